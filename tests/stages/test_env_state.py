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


@pytest.fixture(scope="session")
def env_dataset(kitchen_catalog, tmp_path_factory):
    """(dataset root, probes): the recorded dataset with the option on, and per recorded frame the
    simulation's own reading at that frame step (``read_state`` of the world: base link pose, object
    body poses, end-effector body pose [world frame]) and the episode's instance."""
    from kitchen_testutil import link_kitchen_catalog

    from stages.dataset import EpisodeInfo, merge_shards, open_shard
    from stages.demos.sampling import sample_instance
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.env_state import state_names
    from stages.engine.programs import Listed
    from stages.policy.evaluate import build_kitchen
    from stages.simulate.state import read_state

    d = tmp_path_factory.mktemp("env_dataset")
    world = build_kitchen(link_kitchen_catalog(kitchen_catalog, d / "work"), 5)
    cfg = EngineConfig(worlds=1, width=64, height=48, cameras=("wrist", "head"),
                       environment_state=state_names("push_object"))
    engine = BatchEngine(world, panda_root=None, work_dir=d / "engine", config=cfg, seed=5)
    probes = []
    collect = engine.capture.collect

    def probing_collect() -> None:  # the simulation's reading of every frame the recorder takes
        step = engine.global_step
        collect()
        pending = engine.capture._pending
        if engine.capture.collected_step == step and pending is not None and pending.sinks[0] is not None:
            probes.append(read_state(engine.side.views[0]))

    engine.capture.collect = probing_collect
    with open_shard(d / "shards", "s0", cfg.dataset_spec()) as shard:
        def begin(w, ticket):
            shard.begin_episode(EpisodeInfo(task=ticket.instruction, task_kind=ticket.task, scene_id=world.scene_id,
                                            seed=ticket.seed, asset_ids=ticket.asset_ids))
            return shard.add_frame

        def end(w, ticket, res):
            shard.end_episode(success=True)  # a 1.5 s prefix of the expert's episode, kept for the test

        engine.run(Listed(world, {0: [("push_object", 1, 1.5)]}), begin=begin, end=end)
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
    assert float(np.linalg.norm(np.asarray(probes[-1].robot.base.x) - probes[0].robot.base.x)) > 0.01 or turned > 0.01


@pytest.fixture(scope="session")
def env_act(env_dataset, tmp_path_factory):
    from stages.policy.train import TrainConfig, train_policy

    cfg = TrainConfig(policy="act", dataset=env_dataset[0], out=tmp_path_factory.mktemp("env_act") / "run", steps=2,
                      batch_size=2, chunk_size=10, device="cpu", num_workers=0, log_freq=1, extra_args=ACT_TINY)
    return train_policy(cfg, timeout=600)


def test_act_trains_on_the_environment_state(env_act):
    import torch
    from safetensors.torch import load_file

    cfg = json.loads((env_act.checkpoint / "config.json").read_text())
    env = cfg["input_features"]["observation.environment_state"]
    assert (env["type"], env["shape"]) == ("ENV", [6])
    weights = load_file(env_act.checkpoint / "model.safetensors")
    assert tuple(weights["model.encoder_env_state_input_proj.weight"].shape) == (32, 6)
    assert env_act.steps == 2 and math.isfinite(env_act.last_loss)
    assert torch.isfinite(weights["model.encoder_env_state_input_proj.weight"]).all()


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
