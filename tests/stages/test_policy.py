"""Issue 17 in CI: lerobot-train trains ACT and Diffusion Policy for a few steps on a tiny dataset of
ours (the engine's recorder, :func:`policy_dataset`), and ``agentworld eval`` runs the ACT checkpoint
for one episode on the CPU in a held-out kitchen (report and rollout video checked).

The models are shrunk (a few lerobot-train arguments) so that a step takes about a second on the
CPU; everything else is lerobot's training as ``agentworld train-policy`` runs it.
"""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("lerobot")
pytest.importorskip("diffusers")
pytest.importorskip("accelerate")

REPO = Path(__file__).resolve().parents[2]
TINY = {
    "act": ("--policy.dim_model=32", "--policy.dim_feedforward=64", "--policy.n_heads=2",
            "--policy.n_encoder_layers=1", "--policy.latent_dim=8"),
    "diffusion": ("--policy.crop_shape=[40,56]", "--policy.down_dims=[16,32]", "--policy.horizon=8",
                  "--policy.n_action_steps=4", "--policy.num_inference_steps=2",
                  "--policy.diffusion_step_embed_dim=16", "--policy.spatial_softmax_num_keypoints=8"),
}
STEPS = 3


def _train(policy: str, dataset: Path, out: Path, **kw):
    from stages.policy.train import TrainConfig, train_policy

    kw.setdefault("num_workers", 0)
    cfg = TrainConfig(policy=policy, dataset=dataset, out=out, steps=STEPS, batch_size=2, chunk_size=10,
                      device="cpu", log_freq=1, extra_args=TINY[policy], **kw)
    return train_policy(cfg, timeout=600)


@pytest.fixture(scope="session")
def eval_work(kitchen_catalog, tmp_path_factory) -> Path:
    """Where the evaluation kitchens are built (shared: built once); their catalog job is the session's
    kitchen catalog (linked: its items come from the runner's cache)."""
    from kitchen_testutil import link_kitchen_catalog

    work = tmp_path_factory.mktemp("eval_work")
    link_kitchen_catalog(kitchen_catalog, work / "kitchens")
    return work


@pytest.fixture(scope="session")
def trained_act(policy_dataset, tmp_path_factory):
    """ACT trained through the frame cache, read by one data loader worker process."""
    tmp = tmp_path_factory.mktemp("act")
    return _train("act", policy_dataset, tmp / "run", num_workers=1, frame_cache=tmp / "frames")


def test_our_dataset_gives_lerobot_policies_rgb_cameras_and_no_depth(policy_dataset):
    from lerobot.configs.types import FeatureType
    from lerobot.utils.feature_utils import dataset_to_policy_features

    from stages.dataset import decode_depth, load_dataset

    ds = load_dataset(policy_dataset)
    feats = dataset_to_policy_features(ds.meta.features)
    visual = {k for k, f in feats.items() if f.type is FeatureType.VISUAL}
    assert visual == {"observation.images.wrist", "observation.images.head"}
    assert all(feats[k].shape == (3, 48, 64) for k in visual)
    assert not any(k.startswith("depth.") for k in feats)  # depth is no policy input
    depth = decode_depth(ds[0]["depth.head"])  # but it is there, lossless
    assert depth.shape == (48, 64) and depth.dtype == np.uint16 and (depth > 0).mean() > 0.9


def _check_run(res, policy: str) -> list[dict]:
    rows = list(csv.DictReader(res.curve_csv.open()))
    assert [int(r["step"]) for r in rows] == list(range(1, STEPS + 1))
    assert all(math.isfinite(float(r["loss"])) and float(r["loss"]) > 0 for r in rows)
    assert res.last_loss == float(rows[-1]["loss"]) and res.wall_seconds > 0
    cfg = json.loads((res.checkpoint / "config.json").read_text())
    assert cfg["type"] == policy
    assert set(cfg["input_features"]) == {"observation.state", "observation.images.wrist", "observation.images.head"}
    summary = json.loads((res.curve_csv.parent / "train.json").read_text())
    assert summary["wall_seconds"] == res.wall_seconds and summary["command"][0] == "lerobot-train"
    from PIL import Image

    assert Image.open(res.curve_png).size[0] == 900
    return rows


def test_lerobot_train_trains_act_on_our_dataset(trained_act):
    rows = _check_run(trained_act, "act")
    assert rows[0]["l1_loss"] and rows[0]["kld_loss"]  # ACT's terms are on the curve
    cfg = json.loads((trained_act.checkpoint / "config.json").read_text())
    assert (cfg["chunk_size"], cfg["n_action_steps"], cfg["temporal_ensemble_coeff"]) == (10, 1, 0.01)
    assert "--policy.pretrained_backbone_weights=null" in trained_act.command
    frames = trained_act.curve_csv.parent.parent / "frames"  # the frame cache: one file per camera video
    assert len(list(frames.glob("*.frames.npy"))) == 2


def test_lerobot_train_trains_diffusion_policy_on_our_dataset(policy_dataset, tmp_path):
    res = _train("diffusion", policy_dataset, tmp_path / "run")
    _check_run(res, "diffusion")


def test_eval_sees_the_recorded_frame_and_batches_worlds(trained_act, eval_work, tmp_path):
    """Two worlds, two held-out episodes of 0.5 s: what the policy was given at frame k is the
    recorded frame k (state and RGB), and the worlds share network calls."""
    import av

    from stages.engine import EngineConfig
    from stages.policy.evaluate import EvalConfig, evaluate

    seen: dict[tuple[int, int], dict] = {}
    acts: dict[tuple[int, int], np.ndarray] = {}
    recorded: dict[int, list] = {0: [], 1: []}
    cfg = EvalConfig(checkpoint=trained_act.checkpoint, tasks=("push_object",), scenes=(6,), seeds=(7, 8),
                     worlds=2, max_seconds=0.5, videos=1)
    res = evaluate(cfg, tmp_path / "eval", work_dir=eval_work,
                   observers=[lambda w, k, obs: seen.__setitem__((w, k), obs)],
                   frame_listeners=[lambda w, frame: recorded[w].append(frame)],
                   action_listeners=[lambda w, k, a: acts.__setitem__((w, k), np.array(a))])
    assert set(acts) == set(seen)  # one action per observation, at the same frame
    assert {a.shape for a in acts.values()} == {(len(EngineConfig().dataset_spec().action_names()),)}
    r = res.report
    assert [(e["task"], e["scene"], e["seed"], e["world"]) for e in sorted(r["episodes"], key=lambda e: e["seed"])] == [
        ("push_object", "kitchen_ws6", 7, 0), ("push_object", "kitchen_ws6", 8, 1)]
    for w in (0, 1):
        assert len(recorded[w]) == 15  # frames 0 .. 14 (0.5 s at 30 fps), one action each
        for k, frame in enumerate(recorded[w]):
            obs = seen[(w, k)]
            np.testing.assert_array_equal(obs["observation.state"], frame.state())
            for cam in ("wrist", "head"):
                np.testing.assert_array_equal(obs[f"observation.images.{cam}"], frame.rgb[cam])
    # one network call per frame step for both worlds, but at frame 0: world 1's episode begins after
    # world 0 asked (its program runs next), so it gets a call of its own there
    assert r["runner"]["chunks"] == 2 * 15 and r["runner"]["model_calls"] == 15 + 1
    assert r["held_out"]["checked"] and r["held_out"]["training_scenes"] == ["kitchen_ws5"]
    (video,) = [e["video"] for e in r["episodes"] if e["video"]]  # one video per task
    with av.open(video) as c:
        frames = [f.to_ndarray(format="rgb24") for f in c.decode(video=0)]
    assert len(frames) == 15 and frames[0].shape == (48, 128, 3)


def test_agentworld_eval_runs_one_episode_on_cpu(trained_act, eval_work, tmp_path):
    """``agentworld eval`` (a subprocess) for one episode: report, failure reason and video are real."""
    import av

    out = tmp_path / "eval"
    cmd = [sys.executable, "-m", "pipeline.cli", "eval", str(trained_act.checkpoint.parents[2].parent),
           "--tasks", "push_object", "--scenes", "6", "--seeds", "9", "--worlds", "1", "--max-seconds", "0.5",
           "--videos", "1", "--out", str(out), "--work", str(eval_work)]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=900, cwd=REPO)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    assert "eval: " in run.stdout and "report" in run.stdout
    r = json.loads((out / "eval.json").read_text())
    (ep,) = r["episodes"]
    assert (ep["task"], ep["scene"], ep["seed"]) == ("push_object", "kitchen_ws6", 9)
    assert ep["frames"] == 15 and ep["sim_seconds"] == pytest.approx(0.5, abs=1e-6)
    row = r["tasks"]["push_object"]
    assert row["episodes"] == 1 and row["successes"] == int(ep["success"])
    if not ep["success"]:  # a 3-step policy in 0.5 s: the push predicate's reason is reported
        assert ep["reason"] and row["failures"] == {ep["reason"]: 1}
    assert r["families"] and r["policy"]["type"] == "act" and r["policy"]["temporal_ensemble_coeff"] == 0.01
    with av.open(ep["video"]) as c:
        n = sum(1 for _ in c.decode(video=0))
    assert n == ep["frames"]


def test_agentworld_eval_refuses_a_kitchen_the_policy_was_trained_in(trained_act, tmp_path):
    from stages.policy.evaluate import EvalConfig, held_out_check

    cfg = EvalConfig(checkpoint=trained_act.checkpoint, tasks=("push_object",), scenes=(5,), seeds=(1,))
    with pytest.raises(ValueError, match=r"not held out: .*kitchen_ws5.*\('push_object', 1\)"):
        held_out_check(cfg)
    assert held_out_check(EvalConfig(checkpoint=trained_act.checkpoint, tasks=("push_object",), scenes=(5,),
                                     seeds=(1,), allow_seen=True))["seen_scenes"] == ["kitchen_ws5"]


def test_train_policy_stops_at_max_seconds_and_saves_the_step_reached(policy_dataset, tmp_path):
    """A run of 100,000 planned steps with a 1 s wall limit: start-up alone takes longer, so the first
    step is the last; its checkpoint is saved and is the evaluable one."""
    from stages.policy.train import TrainConfig, train_policy

    cfg = TrainConfig(policy="act", dataset=policy_dataset, out=tmp_path / "run", steps=100_000, batch_size=2,
                      chunk_size=10, device="cpu", num_workers=0, log_freq=1, extra_args=TINY["act"],
                      max_seconds=1.0)
    res = train_policy(cfg, timeout=600)
    assert (res.steps, res.stopped) == (1, True)
    assert (res.checkpoint / "model.safetensors").is_file() and res.checkpoint.resolve().parent.name == "000001"
    summary = json.loads((tmp_path / "run" / "train.json").read_text())
    assert (summary["steps"], summary["steps_planned"], summary["stopped_at_max_seconds"]) == (1, 100_000, True)
    assert [int(r["step"]) for r in csv.DictReader(res.curve_csv.open())] == [1]


def test_train_policy_starts_from_a_checkpoints_weights(trained_act, policy_dataset, tmp_path):
    """``init``: a run with another seed (so another random initialization) starting from the trained
    ACT ends one step later next to that ACT's weights, not at a fresh model's; a folder that is no
    checkpoint, or one of another policy, fails in one line before any training."""
    from safetensors.numpy import load_file

    from stages.policy.train import TrainConfig, train_policy

    cfg = TrainConfig(policy="act", dataset=policy_dataset, out=tmp_path / "run", steps=1, batch_size=2,
                      chunk_size=10, device="cpu", num_workers=0, log_freq=1, seed=7, init=trained_act.checkpoint,
                      extra_args=(*TINY["act"], "--policy.optimizer_lr=1e-7", "--policy.optimizer_lr_backbone=1e-7"))
    res = train_policy(cfg, timeout=600)
    assert f"--policy.pretrained_path={trained_act.checkpoint.resolve()}" in res.command
    before, after = load_file(trained_act.checkpoint / "model.safetensors"), load_file(res.checkpoint / "model.safetensors")
    assert before.keys() == after.keys()
    moved = max(float(np.abs(after[k] - before[k]).max()) for k in before if before[k].dtype.kind == "f")
    spread = max(float(np.abs(before[k]).max()) for k in before if before[k].dtype.kind == "f")
    assert moved < 1e-3 < spread  # one step of lr 1e-7 from the init, not a fresh draw
    with pytest.raises(ValueError, match="not a checkpoint"):
        TrainConfig(policy="act", dataset=policy_dataset, out=tmp_path / "x", init=tmp_path)
    with pytest.raises(ValueError, match="a act checkpoint, not diffusion"):
        TrainConfig(policy="diffusion", dataset=policy_dataset, out=tmp_path / "x", init=trained_act.checkpoint)
