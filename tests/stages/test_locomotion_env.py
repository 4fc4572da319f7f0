"""The batched G1 velocity environment on the CPU: shapes, rewards, per-world reset, config."""

from __future__ import annotations

import math

import pytest

pytest.importorskip("newton")
torch = pytest.importorskip("torch")

from stages.locomotion.config import (EnvConfig, PPOConfig, TrainConfig, to_dict,  # noqa: E402
                                      train_config_from_dict)
from stages.locomotion.robot import ARM_JOINTS, LEG_JOINTS, WAIST_JOINTS, joint_gains  # noqa: E402

WORLDS = 3


@pytest.fixture(scope="module")
def env():
    from stages.locomotion.env import G1VelocityEnv

    return G1VelocityEnv(EnvConfig(num_worlds=WORLDS, device="cpu", seed=3))


def test_gains_follow_mjlab_constants():
    # mjlab g1_constants: stiffness = armature * (2 pi 10 Hz)^2; knee 7520-22, hip pitch 7520-14, ankle 2 x 5020
    knee, hip, ankle = joint_gains("left_knee_joint"), joint_gains("right_hip_pitch_joint"), joint_gains(
        "left_ankle_roll_joint")
    assert knee.stiffness == pytest.approx(99.10, rel=1e-3)
    assert hip.stiffness == pytest.approx(40.18, rel=1e-3)
    assert ankle.stiffness == pytest.approx(28.50, rel=1e-3)
    assert knee.damping == pytest.approx(2 * 2.0 * knee.armature * 20 * math.pi)
    assert knee.action_scale == pytest.approx(0.25 * 139.0 / knee.stiffness)
    for name in LEG_JOINTS + WAIST_JOINTS + ARM_JOINTS:
        assert joint_gains(name).effort_limit > 0


def test_observation_and_action_shapes(env):
    assert env.num_actions == 15
    assert env.num_obs == 12 + 2 * 29 + 15
    assert env.obs.shape == (WORLDS, env.num_obs)
    assert env.critic_obs.shape == (WORLDS, env.num_obs)
    assert env.layout.joint_names[:12] == LEG_JOINTS
    obs, critic, reward, fell, timed_out = env.step(torch.zeros(WORLDS, env.num_actions))
    assert obs.shape == (WORLDS, env.num_obs) and reward.shape == (WORLDS,)
    assert fell.dtype == torch.bool and timed_out.shape == (WORLDS,)
    # the critic sees the command and the clean gravity vector (about -z at the start)
    assert torch.allclose(critic[:, 9:12], env.commands)
    assert (critic[:, 8] < -0.9).all()


def test_reward_terms_finite_under_random_actions(env):
    from stages.locomotion.rewards import TERMS

    gen = torch.Generator().manual_seed(0)
    for _ in range(5):
        _, _, reward, _, _ = env.step(torch.randn(WORLDS, env.num_actions, generator=gen))
        assert torch.isfinite(reward).all()
    metrics = env.metrics.pop()
    for name in TERMS:
        assert math.isfinite(metrics[f"term_{name}"])
    assert 0.0 < metrics["term_track_lin_vel"] <= 1.0
    assert 0.0 < metrics["term_posture"] <= 1.0
    assert metrics["term_action_rate"] > 0.0


def test_standing_policy_stays_up_and_tracks_nothing(env):
    # zero actions hold the default pose through PD: 0.5 s later the base is still up
    env.reset_worlds(torch.arange(WORLDS))
    for _ in range(25):
        _, _, _, fell, _ = env.step(torch.zeros(WORLDS, env.num_actions))
        assert not fell.any()
    assert (env.q[:, 2] > 0.6).all()


def test_reset_of_one_world_leaves_the_others_untouched(env):
    for _ in range(3):
        env.step(0.3 * torch.ones(WORLDS, env.num_actions))
    q_before, qd_before = env.q.clone(), env.qd.clone()
    cmd_before = env.commands.clone()
    env.reset_worlds(torch.tensor([1]))
    for w in (0, 2):
        assert torch.equal(env.q[w], q_before[w])
        assert torch.equal(env.qd[w], qd_before[w])
        assert torch.equal(env.commands[w], cmd_before[w])
    assert torch.allclose(env.q[1, 7:], env.default_q)
    assert env.q[1, 2] == pytest.approx(0.76)
    assert torch.count_nonzero(env.qd[1]) == 0
    assert env.episode_length_buf[1] == 0


def test_arm_targets_are_held_within_soft_limits(env):
    env.reset_worlds(torch.arange(WORLDS))
    arms = env.arm_idx
    assert (env.arm_targets <= env.soft_hi[arms] + 1e-6).all() and (env.arm_targets >= env.soft_lo[arms] - 1e-6).all()
    assert torch.equal(env.target_q[:, 7 + arms], env.arm_targets)
    # worlds draw different targets
    assert not torch.allclose(env.arm_targets[0], env.arm_targets[1])


def test_commands_within_ranges(env):
    env.reset_worlds(torch.arange(WORLDS))
    c = env.cfg.commands
    for k, (lo, hi) in enumerate((c.vx, c.vy, c.yaw_rate)):
        assert (env.commands[:, k] >= lo).all() and (env.commands[:, k] <= hi).all()


def test_train_config_round_trips_through_json_dict():
    cfg = TrainConfig(env=EnvConfig(num_worlds=7, device="cpu", seed=11), ppo=PPOConfig(hidden_dims=(8, 4)),
                      iterations=3)
    assert train_config_from_dict(to_dict(cfg)) == cfg
    with pytest.raises(ValueError, match="decimation"):
        EnvConfig(decimation=3)
