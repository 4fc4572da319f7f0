"""The humanoid runtime on the CPU: the committed G1 policy walks two batched worlds on their own
commands, and in manipulation mode the legs hold posture while CLIK brings a hand to a target.
Real Newton simulation (SolverMuJoCo, 200 Hz physics, 50 Hz control), real trained policy."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("newton")
pytest.importorskip("pinocchio")
torch = pytest.importorskip("torch")

from stages.locomotion.robot import ARM_JOINTS, LEG_JOINTS, WAIST_JOINTS  # noqa: E402
from stages.locomotion.runtime import (DEFAULT_POLICY, HumanoidWorlds, HumanoidWorldsConfig,  # noqa: E402
                                       LeggedRuntimeConfig, Mode, index_worlds, quat_rotate_inverse)


def _yaw(quat: torch.Tensor) -> np.ndarray:
    x, y, z, w = (quat[:, k].double().numpy() for k in range(4))
    return np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


@pytest.fixture(scope="module")
def worlds():
    return HumanoidWorlds(HumanoidWorldsConfig(num_worlds=2, device="cpu"))


def test_observations_match_the_training_environment(worlds):
    """The runtime's observations are the training env's (same state, no noise), world by world."""
    from stages.locomotion.config import EnvConfig, Randomization
    from stages.locomotion.env import G1VelocityEnv

    env = G1VelocityEnv(EnvConfig(num_worlds=2, device="cpu", seed=1, cuda_graph=False,
                                  randomization=Randomization(obs_noise=False, push_velocity=0.0)))
    rt = worlds.runtime
    assert rt.joint_names == env.joint_names
    gen = torch.Generator().manual_seed(0)
    env.step(0.5 * torch.randn(2, env.num_actions, generator=gen))   # a state away from the default
    env.commands[:] = torch.tensor([[0.4, -0.1, 0.3], [0.0, 0.2, -0.5]])
    obs, _ = env._observations()
    rt.set_command(env.commands.numpy())
    rt.actions.copy_(env.actions)
    got = rt.observations(env.state_0)
    torch.testing.assert_close(got, obs)
    rt.set_mode([Mode.MANIPULATION, Mode.LOCOMOTION])               # manipulation: zero command
    got = rt.observations(env.state_0)
    assert torch.count_nonzero(got[0, 9:12]) == 0 and torch.equal(got[1, 9:12], obs[1, 9:12])
    rt.reset()


def test_index_finds_each_worlds_joints(worlds):
    ix = index_worlds(worlds.model, worlds.runtime.joint_names)
    assert ix.joint_q.shape == (2, 29) and ix.root_q.tolist() == [0, 36]
    assert (ix.joint_q[1] - ix.joint_q[0] == 36).all() and (ix.joint_qd[1] - ix.joint_qd[0] == 35).all()
    with pytest.raises(ValueError, match="missing"):
        index_worlds(worlds.model, ("no_such_joint",))
    meta = json.loads((DEFAULT_POLICY / "policy.json").read_text())
    assert tuple(meta["default_pos"]) == LEG_JOINTS + WAIST_JOINTS + ARM_JOINTS
    assert (ix.joint_q[0, 1:] > ix.joint_q[0, :-1]).all()             # observation order = model order


def test_two_worlds_walk_on_their_own_commands(worlds):
    """World 0: vx 0.5 m/s; world 1: turn in place at 0.5 rad/s; 4 s of simulated time.

    Measured (CPU; the runtime draws no random numbers): world 0 moves 1.83 m forward, 0.02 m
    sideways and turns 0.02 rad, forward velocity 0.483 m/s over the last 2 s; world 1 turns
    1.74 rad (0.505 rad/s over the last 2 s) and drifts 0.05 m; the pelvis stays above 0.757 m
    (standing 0.76 m, a fall is below 0.3 m). About 20 s of wall time on 2 cores."""
    rt = worlds.runtime
    worlds.reset()
    rt.set_command([[0.5, 0.0, 0.0], [0.0, 0.0, 0.5]])
    pos0, quat0, _, _ = (t.clone() for t in rt.base_state(worlds.state))
    heights, vx, wz = [], [], []
    steps = int(round(4.0 / rt.control_dt))
    for k in range(steps):
        worlds.step()
        pos, quat, lin, ang = rt.base_state(worlds.state)
        heights.append(pos[:, 2].clone())
        if k >= steps // 2:
            vx.append(quat_rotate_inverse(quat, lin)[:, 0].clone())
            wz.append(quat_rotate_inverse(quat, ang)[:, 2].clone())
    pos, quat, _, _ = rt.base_state(worlds.state)
    d = (pos - pos0).numpy()
    turned = _yaw(quat) - _yaw(quat0)
    assert torch.stack(heights).min() > 0.6                           # nobody fell
    assert 1.5 < d[0, 0] < 2.2 and abs(d[0, 1]) < 0.25 and abs(turned[0]) < 0.3
    assert float(torch.stack(vx)[:, 0].mean()) == pytest.approx(0.5, abs=0.1)
    assert math.hypot(*d[1, :2]) < 0.3 and 1.5 < turned[1] < 2.3       # world 1 turned in place
    assert float(torch.stack(wz)[:, 1].mean()) == pytest.approx(0.5, abs=0.15)


def test_manipulation_mode_stands_while_clik_reaches(worlds):
    """Manipulation mode (zero velocity even though vx 0.5 m/s is commanded): the right hand of
    world 0 goes 10 cm forward and 10 cm up, world 1's 5 cm forward, 8 cm inward, 5 cm up, world
    frame; 3 s.

    Measured (CPU): in the last 1.5 s the hands are 4.0 / 9.8 mm from their targets on average,
    at most 5.9 / 15.3 mm (no bias: the policy's in-place sway moves the shoulder by about a
    centimetre and the arms' PD lags the re-solved targets; before the CLIK goal's rate limit,
    without the 0.08 s look-ahead: 8.8 / 12.3 mm mean, 15.6 / 21.7 mm at most); without the arms'
    gravity feed-forward the hands sag 55-70 mm short. The base moves 5-13 mm; the pelvis stays at
    0.76 m. About 17 s of wall time."""
    rt = worlds.runtime
    worlds.reset()
    rt.set_command([0.5, 0.0, 0.0])
    rt.set_mode(Mode.MANIPULATION)
    worlds.run(0.5)
    start = rt.ee_pose_world(worlds.state, "right")
    goal = start.copy()
    goal[0, :3, 3] += [0.10, 0.0, 0.10]
    goal[1, :3, 3] += [0.05, -0.08, 0.05]
    rt.set_ee_target("right", goal)
    left0 = rt.ee_pose_world(worlds.state, "left")
    base0 = rt.base_state(worlds.state)[0].clone()
    errors, heights = [], []
    steps = int(round(3.0 / rt.control_dt))
    for k in range(steps):
        worlds.step()
        heights.append(rt.base_state(worlds.state)[0][:, 2].clone())
        if k >= steps // 2:
            got = rt.ee_pose_world(worlds.state, "right")
            errors.append(np.linalg.norm(got[:, :3, 3] - goal[:, :3, 3], axis=1))
    errors = np.array(errors)
    base = rt.base_state(worlds.state)[0]
    assert errors.mean(axis=0).max() < 0.015 and errors.max() < 0.025
    assert float(torch.linalg.norm((base - base0)[:, :2], dim=1).max()) < 0.05   # stood still
    assert torch.stack(heights).min() > 0.7
    assert (rt.last_clik["right"].position_error < 2e-3).all()     # the IK itself converged
    left = rt.ee_pose_world(worlds.state, "left")                   # the other arm held its pose
    assert np.linalg.norm(left[:, :3, 3] - left0[:, :3, 3], axis=1).max() < 0.03


def test_runtime_evaluation_walks_with_moving_hands(worlds):
    """``agentworld loco-runtime``'s evaluation on the two worlds: random commands, both hands to
    random base-frame targets, 3 s. Measured (seed 0): no falls, planar speed error 0.087 m/s,
    yaw-rate error 0.11 rad/s, hand error 16 mm mean (30 mm p95, targets redrawn while walking);
    a second run on the same worlds gives the same figures."""
    from stages.locomotion.runtime_eval import RuntimeEvalConfig, _hand_targets, evaluate_runtime

    result = evaluate_runtime(RuntimeEvalConfig(num_worlds=2, seconds=3.0, seed=0, worlds=worlds))
    assert result["rollouts"] == 2 and result["falls"] == 0
    assert 0.0 < result["lin_vel_error_mps"] < 0.2 and 0.0 < result["yaw_rate_error_radps"] < 0.3
    assert 0.0 < result["hand_error_mean_m"] < 0.03
    rt = worlds.runtime
    assert rt.ee_in_base["left"].all() and rt.ee_active["right"].all()
    a = _hand_targets(rt, "left", 3, np.random.default_rng(5), 0.6)
    b = _hand_targets(rt, "left", 3, np.random.default_rng(5), 0.6)
    np.testing.assert_array_equal(a, b)                              # targets come from the seed
    assert not np.allclose(a[0], a[1])


def test_spec_names_the_policy_and_frames_follow_the_dataset_layout(worlds):
    """The g1_29dof spec's legged base names the shipped policy; a world's frame (state, action)
    has the spec's layout and the simulation's values."""
    from stages.embodiment import EmbodimentError, load_spec
    from stages.embodiment.layout import action_names, state_names
    from stages.locomotion.embodiment import frame_vectors, runtime_config_for

    spec = load_spec("g1_29dof")
    cfg = runtime_config_for(spec, device="cpu")
    assert cfg.policy == str(DEFAULT_POLICY) and cfg.spec == "g1_29dof" and cfg.root_body == "pelvis"
    h1 = load_spec("h1")
    h1_cfg = runtime_config_for(h1, device="cpu")
    assert Path(h1_cfg.policy).name == "h1_velocity" and h1_cfg.spec == "h1"
    unshipped = h1.model_copy(update={"base": h1.base.model_copy(update={"policy": ""})})
    for other, why in ((unshipped, "no locomotion policy is shipped"), (load_spec("mobile_panda"), "has no locomotion policy")):
        with pytest.raises(EmbodimentError, match=why):
            runtime_config_for(other)

    rt = worlds.runtime
    worlds.reset()
    rt.set_command([[0.3, 0.0, 0.2], [0.5, 0.1, 0.0]])
    rt.set_mode([Mode.LOCOMOTION, Mode.MANIPULATION])
    worlds.run(0.2)
    state, action = frame_vectors(rt, worlds.state)
    s_names, a_names = state_names(spec), action_names(spec)
    assert state.shape == (2, len(s_names)) and action.shape == (2, len(a_names))
    s, a = dict(zip(s_names, state.T, strict=True)), dict(zip(a_names, action.T, strict=True))
    pos, quat, _, _ = rt.base_state(worlds.state)
    np.testing.assert_allclose(s["base_x"], pos[:, 0].numpy(), atol=1e-6)
    np.testing.assert_allclose(s["base_theta"], _yaw(quat), atol=1e-5)
    jq, _ = rt.joint_state(worlds.state)
    left = [rt.joint_names.index(j) for j in spec.arm("left").joints]
    np.testing.assert_allclose(np.stack([s[f"left_q{i}"] for i in range(7)], 1), jq[:, left].numpy(), atol=1e-6)
    quat_norm = np.linalg.norm(np.stack([s[f"right_ee_{c}"] for c in ("qw", "qx", "qy", "qz")], 1), axis=1)
    np.testing.assert_allclose(quat_norm, 1.0, atol=1e-9)
    assert a["mode"].tolist() == [0.0, 1.0]
    np.testing.assert_allclose(np.stack([a["base_vx"], a["base_vy"], a["base_vtheta"]], 1),
                               [[0.3, 0.0, 0.2], [0.0, 0.0, 0.0]], atol=1e-6)  # manipulation: zero
    # arms at rest: the commanded joints are the default pose, the measured ones within 0.05 rad
    default = rt.default_q.numpy()[left]
    np.testing.assert_allclose(np.stack([a[f"left_q{i}_target"] for i in range(7)], 1), [default] * 2, atol=1e-6)
    assert np.abs(jq[:, left].numpy() - default).max() < 0.05


def test_index_finds_the_g1_behind_other_bodies_of_a_world():
    """A world whose model arrays start with another free body (a box, as scene objects come
    first in a kitchen): the runtime still reads the G1's base and joints."""
    import newton
    import warp as wp

    from stages.locomotion.robot import DEFAULT_POSE, g1_builder

    world = newton.ModelBuilder()
    newton.solvers.SolverMuJoCo.register_custom_attributes(world)
    box = world.add_body(xform=wp.transform((2.0, 0.0, 0.5), wp.quat_identity()), label="box")
    world.add_shape_box(box, hx=0.1, hy=0.1, hz=0.1)
    robot, _ = g1_builder(base_pose=(1.0, -0.5, 0.3))
    world.add_builder(robot)
    main = newton.ModelBuilder()
    main.replicate(world, 2)
    model = main.finalize(device="cpu")
    ix = index_worlds(model, LEG_JOINTS + WAIST_JOINTS + ARM_JOINTS)
    assert ix.root_q.tolist() == [7, 7 + 43] and ix.joint_q[0, 0] == 14
    worlds = HumanoidWorlds(HumanoidWorldsConfig(num_worlds=2), model=model)
    pos, quat, _, _ = worlds.runtime.base_state(worlds.state)
    np.testing.assert_allclose(pos[:, :2].numpy(), [[1.0, -0.5]] * 2, atol=1e-6)
    np.testing.assert_allclose(_yaw(quat), [0.3, 0.3], atol=1e-6)
    jq, _ = worlds.runtime.joint_state(worlds.state)
    assert jq[:, LEG_JOINTS.index("left_knee_joint")].tolist() == pytest.approx([DEFAULT_POSE["left_knee_joint"]] * 2)
