"""The batched policy runner does per world what lerobot's own select_action does for one world.

Policies here are lerobot's ACT and Diffusion Policy built from a synthetic dataset's features and
stats (untrained, tiny): the runner's chunking, ensembling and observation history do not depend
on the weights. Three worlds start their episodes at different steps; each world's actions must
equal those of ``policy.select_action`` fed that world's observations alone, with ``reset()`` at
its episode start (Diffusion: the same random numbers per chunk, from the world's episode seed).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("lerobot")
pytest.importorskip("diffusers")

from stages.dataset.schema import CameraSpec, DatasetSpec  # noqa: E402
from stages.dataset.synthetic import write_synthetic_shard  # noqa: E402

H, W = 32, 40
SPEC = DatasetSpec(cameras=(CameraSpec("wrist", H, W), CameraSpec("head", H, W, depth=False)))
STEPS = 9
STARTS = {0: 0, 1: 2, 2: 5}  # world -> step at which its episode starts
SEEDS = {0: 11, 1: 12, 2: 13}


@pytest.fixture(scope="module")
def meta(tmp_path_factory):
    from stages.dataset import load_dataset

    root = tmp_path_factory.mktemp("runner_ds")
    write_synthetic_shard(root, "s0", SPEC, shard_index=0, episodes=1, frames=12)
    return load_dataset(root / "s0").meta


def _loaded(meta, policy_type: str, **overrides):
    import torch

    from lerobot.policies.factory import make_policy, make_policy_config, make_pre_post_processors
    from stages.policy.runner import LoadedPolicy

    torch.manual_seed(0)
    cfg = make_policy_config(policy_type, device="cpu", push_to_hub=False, pretrained_backbone_weights=None,
                             **overrides)
    policy = make_policy(cfg, ds_meta=meta)
    policy.eval()
    pre, post = make_pre_post_processors(policy.config, dataset_stats=meta.stats)
    shapes = {k: tuple(ft.shape) for k, ft in policy.config.image_features.items()}
    assert set(shapes) == {"observation.images.wrist", "observation.images.head"}  # no depth input
    return LoadedPolicy(policy=policy, preprocessor=pre, postprocessor=post, type=policy_type, device="cpu",
                        image_shapes=shapes, state_dim=SPEC.state_dim, action_dim=SPEC.action_dim)


def _observations() -> dict[int, list[dict[str, np.ndarray]]]:
    rng = np.random.default_rng(7)
    out = {}
    for w, start in STARTS.items():
        out[w] = [{"observation.state": rng.normal(size=SPEC.state_dim).astype(np.float32),
                   "observation.images.wrist": rng.integers(0, 256, (H, W, 3), dtype=np.uint8),
                   "observation.images.head": rng.integers(0, 256, (H, W, 3), dtype=np.uint8)}
                  for _ in range(STEPS - start)]
    return out


def _reference(lp, obs: list[dict], seed: int) -> np.ndarray:
    """lerobot's own loop for one world: preprocessor -> select_action -> postprocessor."""
    import torch

    from stages.policy.runner import to_policy_batch

    pol = lp.policy
    pol.reset()
    gen = torch.Generator().manual_seed(seed)
    out = []
    for k, o in enumerate(obs):
        with torch.inference_mode():
            batch = lp.preprocessor(to_policy_batch([o], lp.image_shapes))
            if lp.type == "diffusion":
                noise = None
                if k % pol.config.n_action_steps == 0:  # select_action predicts a chunk (queue empty)
                    shape = (pol.config.horizon, pol.config.action_feature.shape[0])
                    noise = torch.randn(shape, generator=gen)[None]
                    torch.random.set_rng_state(gen.get_state())  # the DDPM steps draw the same stream
                a = pol.select_action(batch, noise=noise)
                if noise is not None:
                    gen.set_state(torch.random.get_rng_state())
            else:
                a = pol.select_action(batch)
            out.append(lp.postprocessor(a)[0].numpy())
    return np.stack(out)


def _batched(lp, obs: dict[int, list[dict]]) -> dict[int, np.ndarray]:
    from stages.policy.runner import BatchedRunner

    runner = BatchedRunner(lp)
    got: dict[int, list] = {w: [] for w in obs}
    for t in range(STEPS):
        acting = {}
        for w, start in STARTS.items():
            if t == start:
                runner.reset(w, SEEDS[w])
            if t >= start:
                acting[w] = obs[w][t - start]
        for w, a in runner.act(acting).items():
            got[w].append(a)
    assert runner.model_calls >= 1
    return {w: np.stack(v) for w, v in got.items()}


@pytest.mark.parametrize("policy_type, overrides", [
    ("act", dict(chunk_size=6, n_action_steps=1, temporal_ensemble_coeff=0.01, dim_model=32,
                 dim_feedforward=64, n_heads=2, n_encoder_layers=1, latent_dim=8)),
    ("act", dict(chunk_size=6, n_action_steps=3, dim_model=32, dim_feedforward=64, n_heads=2,
                 n_encoder_layers=1, latent_dim=8)),
    ("diffusion", dict(horizon=8, n_obs_steps=2, n_action_steps=3, crop_shape=(32, 40), down_dims=(16, 32),
                       diffusion_step_embed_dim=16, num_inference_steps=2, spatial_softmax_num_keypoints=8)),
], ids=["act_ensemble", "act_chunks", "diffusion"])
def test_batched_runner_equals_lerobot_select_action_per_world(meta, policy_type, overrides):
    lp = _loaded(meta, policy_type, **overrides)
    obs = _observations()
    got = _batched(lp, obs)
    for w in STARTS:
        want = _reference(lp, obs[w], SEEDS[w])
        assert got[w].shape == want.shape == (STEPS - STARTS[w], SPEC.action_dim)
        np.testing.assert_allclose(got[w], want, rtol=1e-4, atol=1e-5, err_msg=f"world {w}")
    # the worlds' actions differ (different observations): the comparison is not vacuous
    assert not np.allclose(got[0][-2:], got[2][-2:])


def test_runner_refuses_a_world_that_was_not_reset(meta):
    from stages.policy.runner import BatchedRunner

    lp = _loaded(meta, "act", chunk_size=4, n_action_steps=4, dim_model=32, dim_feedforward=64, n_heads=2,
                 n_encoder_layers=1, latent_dim=8)
    with pytest.raises(RuntimeError, match=r"worlds \[3\] act before reset"):
        BatchedRunner(lp).act({3: _observations()[0][0]})


def test_load_policy_names_a_folder_that_is_no_checkpoint(tmp_path: Path):
    from stages.policy.runner import load_policy

    with pytest.raises(FileNotFoundError, match="not a lerobot checkpoint"):
        load_policy(tmp_path)


def test_train_policy_uses_the_papers_settings_and_validates_its_config(tmp_path: Path):
    from stages.policy.train import TrainConfig, lerobot_args

    act = lerobot_args(TrainConfig(policy="act", dataset=tmp_path / "ds", out=tmp_path / "o"))
    for arg in ("--policy.type=act", "--policy.chunk_size=20", "--policy.n_action_steps=1",
                "--policy.temporal_ensemble_coeff=0.01", "--batch_size=16", "--policy.pretrained_backbone_weights=null",
                f"--dataset.root={(tmp_path / 'ds').resolve()}", f"--output_dir={(tmp_path / 'o').resolve() / 'lerobot'}"):
        assert arg in act, arg
    dp = lerobot_args(TrainConfig(policy="diffusion", dataset=tmp_path / "ds", out=tmp_path / "o",
                                  extra_args=("--policy.horizon=32",)))
    assert "--policy.type=diffusion" in dp and dp[-1] == "--policy.horizon=32"
    assert not any(a.startswith(("--policy.chunk_size", "--policy.temporal_ensemble")) for a in dp)
    with pytest.raises(ValueError, match="policy must be one of.*steps must be >= 1.*--key=value"):
        TrainConfig(policy="pi0", dataset=tmp_path, out=tmp_path, steps=0, extra_args=("policy.x=1",))


def test_eval_command_parses_seed_ranges():
    from stages.policy.cli import _ints

    assert _ints("1,2,5-7") == (1, 2, 5, 6, 7) and _ints("1000000-1000002") == (1000000, 1000001, 1000002)
