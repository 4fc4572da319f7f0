"""PPO on the G1 velocity environment (CPU, tiny): an iteration runs, checkpoints resume, export reloads."""

from __future__ import annotations

import csv
import json

import pytest

pytest.importorskip("newton")
pytest.importorskip("rsl_rl")
torch = pytest.importorskip("torch")

from stages.locomotion.config import EnvConfig, PPOConfig, TrainConfig  # noqa: E402


def _cfg(directory, iterations):
    return TrainConfig(env=EnvConfig(num_worlds=2, device="cpu", seed=5),
                       ppo=PPOConfig(num_steps_per_env=3, hidden_dims=(16, 16), num_mini_batches=1,
                                     num_learning_epochs=1),
                       iterations=iterations, save_every=1, checkpoint_dir=str(directory))


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    from stages.locomotion.train import train

    directory = tmp_path_factory.mktemp("loco")
    first = train(_cfg(directory, 2))
    second = train(_cfg(directory, 1))
    return directory, first, second


def test_ppo_iterations_run_and_resume_from_the_latest_checkpoint(trained):
    directory, first, second = trained
    assert first["iteration"] == 2 and first["iterations_done"] == 2
    assert second["iteration"] == 3 and second["iterations_done"] == 1
    assert (directory / "model_3.pt").is_file()
    rows = list(csv.DictReader((directory / "curve.csv").open()))
    assert [int(r["iteration"]) for r in rows] == [1, 2, 3]
    walls = [float(r["wall_s"]) for r in rows]
    assert walls == sorted(walls)  # the resumed run continues the wall clock
    for r in rows:
        assert torch.isfinite(torch.tensor(float(r["reward_per_step"])))
    saved = torch.load(directory / "model_3.pt", weights_only=False)
    assert saved["iter"] == 3 and saved["infos"]["config"]["env"]["seed"] == 5


def test_exported_torchscript_gives_the_actor_s_actions(trained, tmp_path):
    from stages.locomotion.policy import PolicyRuntime, actor_from_state_dict, export_from_checkpoint_dir

    directory, _, _ = trained
    written = {p.name for p in export_from_checkpoint_dir(directory, tmp_path)}
    assert {"policy.pt", "policy.json", "curve.csv", "curve.png", "train_config.json", "checkpoint.pt"} <= written
    meta = json.loads((tmp_path / "policy.json").read_text())
    assert meta["num_obs"] == 85 and meta["num_actions"] == 15 and meta["iteration"] == 3
    runtime = PolicyRuntime.load(tmp_path)
    saved = torch.load(directory / "model_3.pt", weights_only=False)
    actor = actor_from_state_dict(saved["actor_state_dict"], 85, 15, (16, 16))
    obs = torch.randn(6, 85, generator=torch.Generator().manual_seed(1))
    from tensordict import TensorDict

    with torch.inference_mode():
        expected = actor(TensorDict({"policy": obs}, batch_size=[6]))
    got = runtime.act(obs)
    assert got.shape == (6, 15)
    assert torch.equal(got, expected)
    targets = runtime.joint_targets(got)
    assert targets.shape == (6, 15) and torch.isfinite(targets).all()


@pytest.mark.slow
def test_evaluation_reports_errors_and_falls(trained, tmp_path):
    from stages.locomotion.evaluate import EvalConfig, evaluate
    from stages.locomotion.policy import export_from_checkpoint_dir

    directory, _, _ = trained
    export_from_checkpoint_dir(directory, tmp_path)
    result = evaluate(EvalConfig(env=EnvConfig(num_worlds=2, device="cpu"), policy=str(tmp_path), seconds=0.4,
                                 settle_s=0.1))
    assert result["rollouts"] == 2 and 0 <= result["falls"] <= 2
    assert result["lin_vel_error_mps"] >= 0.0 and result["yaw_rate_error_radps"] >= 0.0


def test_committed_policy_loads_and_acts_on_the_cpu():
    from pathlib import Path

    from stages.locomotion.policy import PolicyRuntime

    folder = Path(__file__).resolve().parents[2] / "stages/locomotion/policies/g1_velocity"
    runtime = PolicyRuntime.load(folder)
    meta = runtime.meta
    assert meta["num_obs"] == 85 and meta["num_actions"] == 15 and meta["iteration"] > 0
    obs = torch.zeros(4, 85)
    obs[:, 8] = -1.0  # upright: gravity along -z in the base frame
    actions = runtime.act(obs)
    assert actions.shape == (4, 15) and torch.isfinite(actions).all()
    assert torch.equal(actions[0], actions[3])  # deterministic, batched
    rows = (folder / "curve.csv").read_text().splitlines()
    assert len(rows) == meta["iteration"] + 1
