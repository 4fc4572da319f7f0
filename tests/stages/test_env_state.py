"""The optional ``observation.environment_state`` (issue 17, :mod:`stages.engine.env_state`): the
recorder writes the task objects' key points in the base frame at the instant of
``observation.state``, lerobot loads it and ACT trains on it, and the closed-loop evaluator gives a
policy trained with it the same values as the recorder; without the option nothing changes.

The dataset (:func:`env_dataset`) is the first 1.5 s of one scripted push_object episode (seed 1)
in the kitchen of world seed 5, recorded by the batched engine and kept as an episode for the test
(the expert needs ~9 s to finish; the frames are what matters here).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("newton")
pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")
pytest.importorskip("lerobot")

ACT_TINY = ("--policy.dim_model=32", "--policy.dim_feedforward=64", "--policy.n_heads=2",
            "--policy.n_encoder_layers=1", "--policy.latent_dim=8")
PUSH_NAMES = ("object_x", "object_y", "object_z", "goal_x", "goal_y", "goal_z")


def _base_frame(p, x: float, y: float, theta: float) -> np.ndarray:
    """A world point in the base frame of base pose (x, y, theta), written out here on its own."""
    dx, dy = p[0] - x, p[1] - y
    return np.array([math.cos(theta) * dx + math.sin(theta) * dy, -math.sin(theta) * dx + math.cos(theta) * dy,
                     p[2]])


def _probe_frames(engine) -> list:
    """The simulation's own reading (``read_state`` of world 0) at every frame the recorder takes,
    appended to the returned list as the engine runs (wraps the engine's capture ``collect``)."""
    from stages.simulate.state import read_state

    probes = []
    collect = engine.capture.collect

    def probing_collect() -> None:
        step = engine.global_step
        collect()
        pending = engine.capture._pending
        if engine.capture.collected_step == step and pending is not None and pending.sinks[0] is not None:
            probes.append(read_state(engine.side.views[0]))

    engine.capture.collect = probing_collect
    return probes


@pytest.fixture(scope="session")
def env_dataset(kitchen_catalog, tmp_path_factory):
    """(dataset root, probes): the recorded dataset with the option on, and per recorded frame the
    simulation's own reading at that frame step (``read_state`` of the world: base link pose, object
    body poses, end-effector body pose [world frame]) and the episode's instance."""
    from kitchen_testutil import link_kitchen_catalog, shard_begin

    from stages.dataset import merge_shards, open_shard
    from stages.demos.sampling import sample_instance
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.env_state import state_names
    from stages.engine.programs import Listed
    from stages.policy.evaluate import build_kitchen

    d = tmp_path_factory.mktemp("env_dataset")
    world = build_kitchen(link_kitchen_catalog(kitchen_catalog, d / "work"), 5)
    cfg = EngineConfig(worlds=1, width=64, height=48, cameras=("wrist", "head"),
                       environment_state=state_names("push_object"))
    engine = BatchEngine(world, panda_root=None, work_dir=d / "engine", config=cfg, seed=5)
    probes = _probe_frames(engine)
    with open_shard(d / "shards", "s0", cfg.dataset_spec()) as shard:
        def end(w, ticket, res):
            shard.end_episode(success=True)  # a 1.5 s prefix of the expert's episode, kept for the test

        engine.run(Listed(world, {0: [("push_object", 1, 1.5)]}), begin=shard_begin(shard, world), end=end)
    root = merge_shards(d / "shards", d / "dataset").root
    return root, probes, sample_instance("push_object", world, 1)


def test_recorded_environment_state_is_the_simulations_object_in_the_base_frame(env_dataset):
    from stages.dataset import load_dataset

    root, probes, inst = env_dataset
    info = json.loads((root / "meta" / "info.json").read_text())
    feat = info["features"]["observation.environment_state"]
    assert (feat["dtype"], tuple(feat["shape"]), tuple(feat["names"])) == ("float32", (6,), PUSH_NAMES)
    ds = load_dataset(root)
    assert len(ds) == len(probes) == 46  # frames 0 .. 45 of 1.5 s at 30 fps
    body = inst.world.placed["pusher"].body()
    goal = (*inst.target, inst.objects[body][2])
    assert goal[1] == pytest.approx(inst.objects[body][1] + 0.15)  # the push goal: 15 cm along +y
    turned = 0.0
    for k, st in enumerate(probes):
        row = ds[k]
        env = row["observation.environment_state"].numpy()
        b = st.robot.base  # the base link's pose, read from the body (the state's base pose is from joints)
        want = np.concatenate([_base_frame(st.objects[body].position, b.x, b.y, b.theta),
                               _base_frame(goal, b.x, b.y, b.theta)])
        np.testing.assert_allclose(env, want, atol=1e-4, err_msg=f"frame {k}")
        state = row["observation.state"].numpy()
        np.testing.assert_allclose(state[14:17], [b.x, b.y, b.theta], atol=1e-4)
        # the same base frame as the state's end-effector pose (arm FK in the base frame)
        np.testing.assert_allclose(state[7:10], _base_frame(st.robot.ee_pose.position, b.x, b.y, b.theta),
                                   atol=2e-3)
        turned = max(turned, abs(b.theta - probes[0].robot.base.theta))
    assert 0.3 < float(np.linalg.norm(ds[0]["observation.environment_state"].numpy()[:2])) < 5.0
    b0, b1 = probes[0].robot.base, probes[-1].robot.base
    assert math.hypot(b1.x - b0.x, b1.y - b0.y) > 0.01 or turned > 0.01  # the base moved: the transform is exercised


@pytest.fixture(scope="session")
def env_act(env_dataset, tmp_path_factory):
    from stages.policy.train import TrainConfig, train_policy

    cfg = TrainConfig(policy="act", dataset=env_dataset[0], out=tmp_path_factory.mktemp("env_act") / "run", steps=2,
                      batch_size=2, chunk_size=10, device="cpu", num_workers=0, log_freq=1, extra_args=ACT_TINY)
    return train_policy(cfg, timeout=600)


def test_act_trains_on_the_environment_state(env_act, env_dataset):
    import pandas as pd
    import torch
    from safetensors.torch import load_file

    cfg = json.loads((env_act.checkpoint / "config.json").read_text())
    env = cfg["input_features"]["observation.environment_state"]
    assert (env["type"], env["shape"]) == ("ENV", [6])
    weights = load_file(env_act.checkpoint / "model.safetensors")
    assert tuple(weights["model.encoder_env_state_input_proj.weight"].shape) == (32, 6)
    assert env_act.steps == 2 and math.isfinite(env_act.last_loss)
    assert torch.isfinite(weights["model.encoder_env_state_input_proj.weight"]).all()
    # normalized as the state is (train.env_state_normalization: lerobot maps nothing to ENV by default):
    # the checkpoint's preprocessor holds the dataset's statistics of the environment state
    assert cfg["normalization_mapping"]["ENV"] == cfg["normalization_mapping"]["STATE"] == "MEAN_STD"
    stats = load_file(next(env_act.checkpoint.glob("policy_preprocessor_step_*_normalizer_processor.safetensors")))
    frames = pd.concat(pd.read_parquet(f) for f in sorted((Path(env_dataset[0]) / "data").rglob("*.parquet")))
    env_values = np.stack(frames["observation.environment_state"].to_numpy())
    assert np.allclose(stats["observation.environment_state.mean"].numpy(), env_values.mean(0), atol=1e-4)


def test_evaluator_gives_the_policy_the_recorders_environment_state(env_act, kitchen_catalog, tmp_path):
    """One held-out episode of 0.5 s: at every frame the policy's environment state equals the
    frame the evaluation engine records (the recorder's path: the episode's ticket) and the
    simulation's object in the base frame."""
    from kitchen_testutil import link_kitchen_catalog

    from stages.policy.evaluate import EvalConfig, evaluate

    work = link_kitchen_catalog(kitchen_catalog, tmp_path / "work" / "kitchens").parent
    seen, recorded = {}, []
    cfg = EvalConfig(checkpoint=env_act.checkpoint, tasks=("push_object",), scenes=(6,), seeds=(7,), worlds=1,
                     max_seconds=0.5, videos=0)
    res = evaluate(cfg, tmp_path / "eval", work_dir=work, observers=[lambda w, k, obs: seen.__setitem__(k, obs)],
                   frame_listeners=[lambda w, frame: recorded.append(frame)])
    assert res.report["overall"]["episodes"] == 1 and len(recorded) == 15
    assert res.report["policy"]["environment_state"] == 6
    for k, frame in enumerate(recorded):
        obs = seen[k]["observation.environment_state"]
        assert obs.dtype == np.float32 and obs.shape == (6,)
        np.testing.assert_array_equal(obs, frame.environment_state)
        np.testing.assert_array_equal(seen[k]["observation.state"], frame.state())
    assert np.abs(recorded[0].environment_state).max() > 0.1  # real points, not zeros


def test_without_the_option_the_feature_is_absent_and_frames_with_it_are_refused():
    from stages.dataset import CameraSpec, DatasetSpec, FrameError, validate_frame
    from stages.dataset.columns import FrameColumns, pack_columns
    from stages.engine import EngineConfig
    from stages.engine.env_state import state_names

    off = EngineConfig().dataset_spec()
    assert "observation.environment_state" not in off.features() and "environment_state" not in off.to_json()
    on = DatasetSpec(cameras=(CameraSpec("wrist", 8, 8, depth=False),), environment_state=state_names("open_drawer"))
    assert DatasetSpec.from_json(on.to_json()) == on
    assert on.features()["observation.environment_state"]["names"] == ["handle_x", "handle_y", "handle_z", "opening"]
    cols = FrameColumns(dict(arm_joint_pos=np.zeros((1, 7)), ee_pose=np.array([[0, 0, 0, 1, 0, 0, 0.0]]),
                             base_pose=np.zeros((1, 3)), arm_joint_target=np.zeros((1, 7)),
                             ee_target=np.array([[0, 0, 0, 1, 0, 0, 0.0]]), base_velocity=np.zeros((1, 3)),
                             gripper=np.zeros(1), mode=np.zeros(1, np.int64)))
    frame = cols.frame(0, {"wrist": np.zeros((8, 8, 3), np.uint8)}, {})
    validate_frame(DatasetSpec(cameras=on.cameras), frame)  # the plain frame: valid without the option
    with pytest.raises(FrameError, match="environment_state missing"):
        validate_frame(on, frame)
    cols.fields["environment_state"] = np.array([[0.5, 0.1, 0.8, 0.02]])
    with pytest.raises(FrameError, match="spec records none"):
        validate_frame(DatasetSpec(cameras=on.cameras), cols.frame(0, {"wrist": np.zeros((8, 8, 3), np.uint8)}, {}))
    validate_frame(on, cols.frame(0, {"wrist": np.zeros((8, 8, 3), np.uint8)}, {}))
    head, values = pack_columns(cols)
    assert values.shape == (1, 7 + 7 + 3 + 7 + 7 + 3 + 1 + 1 + 1 + 4)  # subtask_index and the env state packed


def test_demos_config_option_is_typed_and_checked():
    from pydantic import ValidationError

    from stages.demos.job import DemosConfig

    assert DemosConfig().environment_state is False
    assert DemosConfig(tasks=("open_drawer",), environment_state=True).environment_state
    with pytest.raises(ValidationError, match="press_button.*has no environment state"):
        DemosConfig(tasks=("press_button",), environment_state=True)
    with pytest.raises(ValidationError, match="layouts differ"):
        DemosConfig(tasks=("push_object", "open_drawer"), environment_state=True)
    with pytest.raises(ValidationError, match="mixed = false"):
        DemosConfig(tasks=("push_object",), mixed=True, environment_state=True)


def test_writer_processes_carry_the_environment_state_to_the_dataset(tmp_path):
    """Frames handed to a shard pool's writer process as columns (the engine's path with
    ``writer_procs``) and one by one: the merged dataset holds each frame's values; a NaN is refused
    by the batch screen's per-frame check."""
    import dataclasses

    from stages.dataset import CameraSpec, DatasetSpec, FrameError, load_dataset, merge_shards
    from stages.dataset.columns import NUMERIC, FrameColumns, suspect_rows
    from stages.dataset.pool import PoolConfig, ShardPool
    from stages.dataset.synthetic import synthetic_episode_info, synthetic_frame

    spec = DatasetSpec(cameras=(CameraSpec("wrist", 24, 32, depth=False),), environment_state=PUSH_NAMES)
    want = {s: [np.array([0.1 * s, 0.01 * i, 0.8, -0.2, 0.5 + i, 0.75]) for i in range(4)] for s in range(2)}
    with ShardPool(tmp_path / "shards", ["s0", "s1"], spec, PoolConfig(workers=1)) as pool:
        for s in range(2):
            pool.begin_episode(s, synthetic_episode_info(s, 0))
        for i in range(4):
            frames = [dataclasses.replace(synthetic_frame(spec, s, 0, i), environment_state=want[s][i])
                      for s in range(2)]
            if i % 2:
                for s, f in enumerate(frames):
                    pool.add_frame(s, f)
                continue
            cols = FrameColumns({n: np.array([getattr(f, n) for f in frames]) for n in NUMERIC
                                 if getattr(frames[0], n) is not None})
            images = {"wrist": (np.stack([f.rgb["wrist"] for f in frames]), None)}
            assert not suspect_rows(spec, cols, images).any()
            pool.add_frames([0, 1], cols, images, [0, 1])
        for s in range(2):
            pool.end_episode(s, success=True)
    ds = load_dataset(merge_shards(tmp_path / "shards", tmp_path / "dataset").root)
    got = {(int(ds[k]["episode_index"]), int(ds[k]["frame_index"])): ds[k]["observation.environment_state"].numpy()
           for k in range(len(ds))}
    assert len(got) == 8
    eps = sorted({e for e, _ in got})
    for s, e in enumerate(eps):  # shards merge in order
        for i in range(4):
            np.testing.assert_allclose(got[(e, i)], want[s][i], rtol=1e-6)
    bad = np.array([np.nan, 0, 0, 0, 0, 0.0])
    frames = [dataclasses.replace(synthetic_frame(spec, 0, 0, 0), environment_state=bad)]
    cols = FrameColumns({n: np.array([getattr(f, n) for f in frames]) for n in NUMERIC
                         if getattr(frames[0], n) is not None})
    images = {"wrist": (np.stack([f.rgb["wrist"] for f in frames]), None)}
    assert suspect_rows(spec, cols, images).all()
    with pytest.raises(FrameError, match="s0 frame 0: 1 problem.*environment_state: contains NaN"):
        with ShardPool(tmp_path / "bad", ["s0"], spec, PoolConfig(workers=1)) as pool:
            pool.begin_episode(0, synthetic_episode_info(0, 0))
            pool.add_frames([0], cols, images, [0])


@pytest.mark.parametrize("policy_type, overrides", [
    ("act", dict(chunk_size=6, n_action_steps=1, temporal_ensemble_coeff=0.01, dim_model=32,
                 dim_feedforward=64, n_heads=2, n_encoder_layers=1, latent_dim=8)),
    ("diffusion", dict(horizon=8, n_obs_steps=2, n_action_steps=3, crop_shape=(32, 40), down_dims=(16, 32),
                       diffusion_step_embed_dim=16, num_inference_steps=2, spatial_softmax_num_keypoints=8)),
], ids=["act", "diffusion"])
def test_batched_runner_feeds_the_environment_state_as_lerobot_does(tmp_path, policy_type, overrides):
    """Untrained tiny policies built from a synthetic dataset with the feature: the runner's actions
    per world equal lerobot's select_action fed that world alone (the Diffusion history holds the
    environment state too), and they depend on the environment state."""
    pytest.importorskip("diffusers")
    import torch
    from lerobot.policies.factory import make_policy, make_policy_config, make_pre_post_processors

    from stages.dataset import CameraSpec, DatasetSpec, load_dataset
    from stages.dataset.synthetic import write_synthetic_shard
    from stages.policy.runner import BatchedRunner, LoadedPolicy, to_policy_batch

    spec = DatasetSpec(cameras=(CameraSpec("wrist", 32, 40, depth=False),), environment_state=PUSH_NAMES)
    write_synthetic_shard(tmp_path, "s0", spec, shard_index=0, episodes=1, frames=12)
    meta = load_dataset(tmp_path / "s0").meta
    torch.manual_seed(0)
    cfg = make_policy_config(policy_type, device="cpu", push_to_hub=False, pretrained_backbone_weights=None,
                             **overrides)
    policy = make_policy(cfg, ds_meta=meta)
    policy.eval()
    assert policy.config.env_state_feature.shape == (6,)
    pre, post = make_pre_post_processors(policy.config, dataset_stats=meta.stats)
    lp = LoadedPolicy(policy=policy, preprocessor=pre, postprocessor=post, type=policy_type, device="cpu",
                      image_shapes={"observation.images.wrist": (3, 32, 40)}, state_dim=spec.state_dim,
                      action_dim=spec.action_dim, env_state_dim=6)
    rng = np.random.default_rng(3)
    obs = {w: [{"observation.state": rng.normal(size=spec.state_dim).astype(np.float32),
                "observation.environment_state": rng.normal(size=6).astype(np.float32),
                "observation.images.wrist": rng.integers(0, 256, (32, 40, 3), dtype=np.uint8)} for _ in range(6)]
           for w in (0, 1)}
    runner = BatchedRunner(lp)
    got = {0: [], 1: []}
    for w in (0, 1):
        runner.reset(w, 20 + w)
    for t in range(6):
        for w, a in runner.act({w: obs[w][t] for w in (0, 1)}).items():
            got[w].append(a)

    def reference(world_obs, seed):
        policy.reset()
        gen = torch.Generator().manual_seed(seed)
        out = []
        for k, o in enumerate(world_obs):
            with torch.inference_mode():
                batch = pre(to_policy_batch([o], lp.image_shapes))
                noise = None
                if policy_type == "diffusion" and k % policy.config.n_action_steps == 0:
                    noise = torch.randn((policy.config.horizon, spec.action_dim), generator=gen)[None]
                    torch.random.set_rng_state(gen.get_state())
                kw = {"noise": noise} if policy_type == "diffusion" else {}
                a = policy.select_action(batch, **kw)
                if noise is not None:
                    gen.set_state(torch.random.get_rng_state())
                out.append(post(a)[0].numpy())
        return np.stack(out)

    for w in (0, 1):
        np.testing.assert_allclose(np.stack(got[w]), reference(obs[w], 20 + w), rtol=1e-4, atol=1e-5)
    moved = [dict(o, **{"observation.environment_state": o["observation.environment_state"] + 1.0}) for o in obs[0]]
    assert not np.allclose(reference(moved, 20), reference(obs[0], 20), atol=1e-4)  # the input is used


def test_both_writer_backends_write_the_same_environment_state(tmp_path):
    """The direct writer (the recorder's) and lerobot's own add_frame/save_episode write the same
    values, names and stats of the feature (synthetic frames: 0.5 + 0.01 i + 0.1 j)."""
    from stages.dataset import CameraSpec, DatasetSpec, load_dataset
    from stages.dataset.synthetic import write_synthetic_shard

    spec = DatasetSpec(cameras=(CameraSpec("wrist", 24, 32, depth=False),), environment_state=PUSH_NAMES)
    got = {}
    for backend in ("direct", "lerobot"):
        write_synthetic_shard(tmp_path / backend, "s0", spec, shard_index=0, episodes=1, frames=5, backend=backend)
        ds = load_dataset(tmp_path / backend / "s0")
        assert ds.meta.features["observation.environment_state"]["names"] == list(PUSH_NAMES)
        got[backend] = (np.stack([ds[i]["observation.environment_state"].numpy() for i in range(len(ds))]),
                        ds.meta.stats["observation.environment_state"])
    want = 0.5 + 0.01 * np.arange(5)[:, None] + 0.1 * np.arange(6)[None, :]
    for backend, (values, stats) in got.items():
        np.testing.assert_allclose(values, want, rtol=1e-6, err_msg=backend)
        np.testing.assert_allclose(stats["mean"], want.mean(axis=0), rtol=1e-5, err_msg=backend)


def test_open_drawer_state_is_the_simulated_handle_and_opening(kitchen_catalog, tmp_path):
    """The handle point and opening recorded at every frame of a whole scripted open_drawer episode
    (no cameras: ~10 s on 2 cores): the opening is the simulated joint's value from closed, the
    handle moves as the drawer link's body does in the simulation, and both are in the base frame
    of that frame."""
    from kitchen_testutil import link_kitchen_catalog

    from stages.demos.sampling import world_part
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.env_state import state_names
    from stages.engine.programs import Listed
    from stages.policy.evaluate import build_kitchen

    world = build_kitchen(link_kitchen_catalog(kitchen_catalog, tmp_path / "work"), 5)
    cfg = EngineConfig(worlds=1, record_images=False, environment_state=state_names("open_drawer"))
    engine = BatchEngine(world, panda_root=None, work_dir=tmp_path / "engine", config=cfg, seed=5)
    frames, results = [], []
    probes = _probe_frames(engine)
    engine.run(Listed(world, {0: [("open_drawer", 3, None)]}), begin=lambda w, t: frames.append,
               end=lambda w, t, res: results.append(res))
    assert [r.success for r in results] == [True], results
    part = world_part(world, "drawer")
    prim = world.placed["counter"].prim
    (link,) = [p for p in probes[0].objects if p.startswith(prim + "/") and p.endswith("/" + part.link)]
    assert len(frames) == len(probes) > 100
    for k, (frame, st) in enumerate(zip(frames, probes, strict=True)):
        b = st.robot.base
        q = st.scene_joints[part.joint_path]
        moved = np.asarray(st.objects[link].position) - np.asarray(probes[0].objects[link].position)
        handle = np.asarray(part.handle_at(probes[0].scene_joints[part.joint_path])) + moved  # rides on the link
        want = [*_base_frame(handle, b.x, b.y, b.theta), q - part.closed]
        np.testing.assert_allclose(frame.environment_state, want, atol=1e-4, err_msg=f"frame {k}")
    assert frames[-1].environment_state[3] > 0.75 * part.travel  # opened, as the predicate says


def test_a_policy_of_no_camera_trains_on_the_states_and_evaluates_without_renders(env_dataset, kitchen_catalog,
                                                                                  tmp_path):
    """``cameras=()``: the checkpoint's inputs are the robot state and the environment state only, the
    data loader decodes no video (the frame cache stays empty) and the evaluator renders nothing."""
    from kitchen_testutil import link_kitchen_catalog

    from stages.policy.evaluate import EvalConfig, evaluate
    from stages.policy.train import TrainConfig, train_policy

    cache = tmp_path / "frames"
    res = train_policy(TrainConfig(policy="act", dataset=env_dataset[0], out=tmp_path / "run", steps=2, batch_size=2,
                                   chunk_size=10, device="cpu", num_workers=1, log_freq=1, extra_args=ACT_TINY,
                                   frame_cache=cache, cameras=()), timeout=600)
    cfg = json.loads((res.checkpoint / "config.json").read_text())
    assert set(cfg["input_features"]) == {"observation.state", "observation.environment_state"}
    assert res.steps == 2 and math.isfinite(res.last_loss)
    assert not cache.exists() or not any(cache.iterdir())
    work = link_kitchen_catalog(kitchen_catalog, tmp_path / "work" / "kitchens").parent
    frames = []
    rep = evaluate(EvalConfig(checkpoint=res.checkpoint, tasks=("push_object",), scenes=(6,), seeds=(7,), worlds=1,
                              max_seconds=0.5, videos=0), tmp_path / "eval", work_dir=work,
                   frame_listeners=[lambda w, frame: frames.append(frame)]).report
    assert rep["overall"]["episodes"] == 1 and rep["policy"]["cameras"] == []
    assert len(frames) == 15 and not any(f.rgb for f in frames)  # no image rendered for any frame
    assert frames[-1].environment_state.shape == (6,) and not (tmp_path / "eval" / "videos").exists()
    # with a video asked for, the episode is filmed by the third-person camera (the policy still sees none)
    seen = []
    rep = evaluate(EvalConfig(checkpoint=res.checkpoint, tasks=("push_object",), scenes=(6,), seeds=(7,), worlds=1,
                              max_seconds=0.5, videos=1), tmp_path / "eval_video", work_dir=work,
                   observers=[lambda w, k, obs: seen.append(sorted(obs))]).report
    video = Path(rep["episodes"][0]["video"])
    assert video.is_file() and video.stat().st_size > 0
    assert seen and all(keys == ["observation.environment_state", "observation.state"] for keys in seen)


def test_train_policy_refuses_unknown_cameras_and_a_camera_less_policy_without_environment_state(env_dataset,
                                                                                                 tmp_path):
    from stages.policy.train import TrainConfig, train_policy

    def cfg(dataset, cameras):
        return TrainConfig(policy="act", dataset=dataset, out=tmp_path / "never", device="cpu", cameras=cameras)

    with pytest.raises(ValueError, match=r"no cameras \['nose'\]"):
        train_policy(cfg(env_dataset[0], ("wrist", "nose")))
    plain = tmp_path / "plain"
    (plain / "meta").mkdir(parents=True)
    info = json.loads((Path(env_dataset[0]) / "meta" / "info.json").read_text())
    del info["features"]["observation.environment_state"]
    (plain / "meta" / "info.json").write_text(json.dumps(info))
    with pytest.raises(ValueError, match="no camera and no observation.environment_state"):
        train_policy(cfg(plain, ()))
    assert not (tmp_path / "never").exists()


BASE_POSE = ("base_x", "base_y", "base_theta")


def test_state_view_keeps_the_episodes_and_cuts_the_state(env_dataset, tmp_path):
    """:func:`stages.dataset.view.write_state_view`: lerobot loads the view; its state is the source's
    kept columns (values, names, statistics), every other column is the source's; bad names are refused
    with nothing written."""
    import pandas as pd
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from stages.dataset.view import state_names, write_state_view

    src = Path(env_dataset[0])
    names = state_names(src)
    kept = write_state_view(src, tmp_path / "view", BASE_POSE)
    assert kept == [n for n in names if n not in BASE_POSE] and len(kept) == len(names) - 3
    cols = [names.index(n) for n in kept]
    ds = LeRobotDataset("agentworld/view", root=tmp_path / "view")
    a = pd.concat(pd.read_parquet(f) for f in sorted((src / "data").rglob("*.parquet")))
    assert len(ds) == len(a) and tuple(ds[3]["observation.state"].shape) == (len(kept),)
    np.testing.assert_allclose(ds[3]["observation.state"].numpy(), np.asarray(a["observation.state"].iloc[3])[cols])
    np.testing.assert_array_equal(ds[3]["action"].numpy(), np.asarray(a["action"].iloc[3], np.float32))
    src_stats = json.loads((src / "meta" / "stats.json").read_text())["observation.state"]
    assert np.allclose(ds.meta.stats["observation.state"]["mean"], np.asarray(src_stats["mean"])[cols])
    meta = json.loads((tmp_path / "view" / "meta" / "agentworld.json").read_text())["state_view"]
    assert meta["source_state"] == names and meta["state"] == kept
    with pytest.raises(ValueError, match="no state entries \\['base_z'\\]"):
        write_state_view(src, tmp_path / "bad", ("base_z",))
    with pytest.raises(FileExistsError):
        write_state_view(src, tmp_path / "view", BASE_POSE)
    assert not (tmp_path / "bad").exists() and not list(tmp_path.glob(".*partial"))


def test_a_policy_of_a_state_view_is_fed_its_entries_in_closed_loop(env_dataset, kitchen_catalog, tmp_path):
    """train-policy ``state_drop``: the checkpoint takes the kept entries and names them
    (agentworld_policy.json); the evaluator gives it exactly those entries of the recorded state."""
    from kitchen_testutil import link_kitchen_catalog

    from stages.policy.evaluate import EvalConfig, evaluate
    from stages.policy.runner import POLICY_INFO
    from stages.policy.train import TrainConfig, train_policy

    res = train_policy(TrainConfig(policy="act", dataset=env_dataset[0], out=tmp_path / "run", steps=2, batch_size=2,
                                   chunk_size=10, device="cpu", num_workers=0, log_freq=1, extra_args=ACT_TINY,
                                   cameras=(), state_drop=BASE_POSE), timeout=600)
    cfg = json.loads((res.checkpoint / "config.json").read_text())
    info = json.loads((res.checkpoint / POLICY_INFO).read_text())
    assert cfg["input_features"]["observation.state"]["shape"] == [14] and len(info["state"]) == 14
    assert not set(BASE_POSE) & set(info["state"]) and info["environment_state"] == list(PUSH_NAMES)
    work = link_kitchen_catalog(kitchen_catalog, tmp_path / "work" / "kitchens").parent
    seen, recorded = {}, []
    rep = evaluate(EvalConfig(checkpoint=res.checkpoint, tasks=("push_object",), scenes=(6,), seeds=(7,), worlds=1,
                              max_seconds=0.5, videos=0), tmp_path / "eval", work_dir=work,
                   observers=[lambda w, k, obs: seen.__setitem__(k, obs)],
                   frame_listeners=[lambda w, frame: recorded.append(frame)]).report
    assert rep["overall"]["episodes"] == 1 and len(recorded) == 15
    for k, frame in enumerate(recorded):
        np.testing.assert_array_equal(seen[k]["observation.state"], frame.state()[:14])  # the base pose is last
    with pytest.raises(ValueError, match="cannot drop state entries"):
        train_policy(TrainConfig(policy="act", dataset=env_dataset[0], out=tmp_path / "run2", steps=2,
                                 device="cpu", cameras=(), state_drop=("base_z",)))
    assert not (tmp_path / "run2").exists()


def test_eval_refuses_a_policy_state_it_cannot_build():
    from types import SimpleNamespace

    from stages.policy.evaluate import state_selection

    rec = ["arm_q0", "ee_x", "base_x"]
    assert state_selection(rec, SimpleNamespace(state_names=None, state_dim=3), "ck") is None
    assert state_selection(rec, SimpleNamespace(state_names=("ee_x", "arm_q0"), state_dim=2), "ck") == [1, 0]
    with pytest.raises(ValueError, match="ck: the policy takes a state of 2 entries"):
        state_selection(rec, SimpleNamespace(state_names=None, state_dim=2), "ck")
    with pytest.raises(ValueError, match="state entries \\['hand_q0'\\] are not in the state"):
        state_selection(rec, SimpleNamespace(state_names=("hand_q0",), state_dim=1), "ck")


def test_memory_frames_give_lerobots_items(env_dataset):
    """:mod:`stages.policy.memory_frames`: every item (ACT's action window with its padding at the
    episode's end, a state history, the videos) equals lerobot's own read, dtype and shape too."""
    import torch
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from stages.policy import memory_frames

    delta = {"action": [i / 30 for i in range(20)], "observation.state": [-1 / 30, 0.0]}
    ds = LeRobotDataset("agentworld/env", root=env_dataset[0], delta_timestamps=delta)
    reader = ds._ensure_reader()
    lerobot_get = getattr(type(reader).get_item, "lerobot_get_item", type(reader).get_item)
    memory_frames.install()
    memory_frames.install()  # idempotent
    assert getattr(type(reader).get_item, "agentworld_memory_frames", False)
    for i in [0, 1, len(ds) // 2, len(ds) - 3, len(ds) - 1]:
        ref, new = lerobot_get(reader, i), ds[i]
        assert ref.keys() == new.keys()
        for k, v in ref.items():
            if isinstance(v, torch.Tensor):
                assert v.dtype == new[k].dtype and v.shape == new[k].shape and torch.equal(v, new[k]), k
            else:
                assert v == new[k], k
    last = ds[len(ds) - 1]
    assert last["action_is_pad"][1:].all() and not last["action_is_pad"][0] and not last["observation.state_is_pad"].any()


def test_eval_drives_the_arm_by_the_actions_end_effector_target(env_act, kitchen_catalog, tmp_path, monkeypatch):
    """``arm_command="ee"``: every action's end-effector target (base frame) becomes arm joint targets
    whose forward kinematics (the recorder's ``ee_*_target``) is that pose."""
    from kitchen_testutil import link_kitchen_catalog

    from stages.policy import evaluate as ev

    calls = []
    solve = ev.ee_arm_targets

    def spy(drv, arm_fk, ee7):
        q = solve(drv, arm_fk, ee7)
        calls.append((np.asarray(ee7, float), arm_fk.pose7(q[None])[0]))
        return q

    monkeypatch.setattr(ev, "ee_arm_targets", spy)
    work = link_kitchen_catalog(kitchen_catalog, tmp_path / "work" / "kitchens").parent
    cfg = ev.EvalConfig(checkpoint=env_act.checkpoint, tasks=("push_object",), scenes=(6,), seeds=(7,), worlds=1,
                        max_seconds=0.5, videos=0, arm_command="ee")
    recorded = []
    rep = ev.evaluate(cfg, tmp_path / "eval", work_dir=work,
                      frame_listeners=[lambda w, frame: recorded.append(frame)]).report
    assert rep["overall"]["episodes"] == 1 and len(calls) == 15
    pos = [np.linalg.norm(want[:3] - got[:3]) for want, got in calls]
    rot = [1 - abs(float(np.dot(want[3:] / np.linalg.norm(want[3:]), got[3:]))) for want, got in calls]
    assert np.median(pos) < 2e-3 and np.median(rot) < 1e-3, (pos, rot)
    with pytest.raises(ValueError, match="arm_command must be"):
        ev.EvalConfig(checkpoint=env_act.checkpoint, tasks=("push_object",), arm_command="cartesian")


def scripted_episode(kitchen_catalog, tmp_path: Path, task: str, names) -> tuple[list, list]:
    """One scripted episode of ``task`` (seed 2, kitchen 5, no cameras) recording the environment
    state ``names``: its frames and the simulation's own reading at each (:func:`_probe_frames`);
    asserts it succeeded over more than 100 frames."""
    from kitchen_testutil import link_kitchen_catalog

    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed
    from stages.policy.evaluate import build_kitchen

    world = build_kitchen(link_kitchen_catalog(kitchen_catalog, tmp_path / "work"), 5)
    cfg = EngineConfig(worlds=1, record_images=False, environment_state=tuple(names))
    assert cfg.dataset_spec().features()["observation.environment_state"]["names"] == list(names)
    engine = BatchEngine(world, panda_root=None, work_dir=tmp_path / "engine", config=cfg, seed=5)
    frames, results = [], []
    probes = _probe_frames(engine)
    engine.run(Listed(world, {0: [(task, 2, None)]}), begin=lambda w, t: frames.append,
               end=lambda w, t, res: results.append(res))
    assert [r.success for r in results] == [True], results
    assert len(frames) == len(probes) > 100
    return frames, probes


def scripted_env(kitchen_catalog, tmp_path: Path, task: str, names) -> tuple[np.ndarray, list, list]:
    """:func:`scripted_episode`, with its recorded environment state (frames, len(names)) float64
    first (its shape checked)."""
    frames, probes = scripted_episode(kitchen_catalog, tmp_path, task, names)
    env = np.array([f.environment_state for f in frames], np.float64)
    assert env.shape == (len(frames), len(names))
    return env, frames, probes


def test_gripper_opening_ends_the_state_and_follows_the_fingers(kitchen_catalog, tmp_path):
    """With the gripper entry (``environment_gripper``) a whole scripted pick_place_bowl episode (no
    cameras) records 7 numbers a frame: the mug and bowl as without it, then the fingers' opening, the
    sum of the finger joints' simulated positions [m]: open before the grasp, closed on the mug while
    it is carried, and it moves as the distance between the finger bodies does."""
    from stages.engine.env_state import GRIPPER, state_names

    names = state_names("pick_place_bowl", gripper=True)
    assert names[-1] == GRIPPER and names[:-1] == state_names("pick_place_bowl")
    frames, probes = scripted_episode(kitchen_catalog, tmp_path, "pick_place_bowl", names)
    fingers = [i for i, n in enumerate(probes[0].robot.joint_names) if "finger" in n]
    assert len(fingers) == 2
    env = np.array([f.environment_state for f in frames])
    assert env.shape == (len(frames), 7)
    want = np.array([sum(st.robot.q[i] for i in fingers) for st in probes])
    np.testing.assert_allclose(env[:, -1], want, atol=1e-5)
    dist = np.array([st.robot.gripper_opening for st in probes])  # finger bodies' distance: the same motion
    np.testing.assert_allclose(env[:, -1] - env[0, -1], dist - dist[0], atol=2e-3)
    assert env[0, -1] > 0.07  # open at the start (the Panda's fingers: 0.08 m)
    closed = np.array([f.gripper for f in frames]) > 0.5
    shut = env[0, -1] - 0.005  # the fingers stop on the mug (its width), not at 0
    assert closed.any() and env[closed, -1].min() < shut
    lifted = env[:, 2] > env[0, 2] + 0.05  # while the mug is up, the hand holds it
    assert lifted.any() and env[lifted, -1].max() < shut


def test_gripper_entry_options_are_checked():
    from pydantic import ValidationError

    from stages.demos.job import DemosConfig
    from stages.engine.env_state import GRIPPER, check_names, common_layout, state_names

    assert DemosConfig(tasks=("open_drawer",), environment_state=True, environment_gripper=True).environment_gripper
    with pytest.raises(ValidationError, match="environment_gripper needs environment_state"):
        DemosConfig(tasks=("open_drawer",), environment_gripper=True)
    assert common_layout(("open_drawer",), gripper=True) == ("handle_x", "handle_y", "handle_z", "opening", GRIPPER)
    check_names(state_names("push_object", gripper=True), "push_object", "test")  # either layout is one
    with pytest.raises(ValueError, match="has environment state"):
        check_names(state_names("push_object", gripper=True), "pick_place_bowl", "test")


def test_eval_takes_the_gripper_layout_for_a_policy_one_entry_larger():
    from types import SimpleNamespace

    from stages.engine.env_state import GRIPPER, state_names
    from stages.policy.evaluate import EvalConfig, env_layout

    cfg = EvalConfig(checkpoint=Path("ck"), tasks=("pick_place_bowl",), scenes=(101,), seeds=(1,))
    assert env_layout(cfg, SimpleNamespace(env_state_dim=6, env_state_names=None)) == state_names("pick_place_bowl")
    assert env_layout(cfg, SimpleNamespace(env_state_dim=7, env_state_names=None))[-1] == GRIPPER
    with pytest.raises(ValueError, match="environment state of 8 entries"):
        env_layout(cfg, SimpleNamespace(env_state_dim=8, env_state_names=None))
