"""The Unitree H1 in the locomotion stack (CPU): its description matches its MJCF, the G1's still
gives the trained policy's values, the H1 env stands under its default-pose PD, PPO trains and
the export names the robot (skipped where the shared third-party assets are absent)."""

from __future__ import annotations

import json
import re

import pytest

pytest.importorskip("newton")
torch = pytest.importorskip("torch")

from stages.locomotion.config import EnvConfig, PPOConfig, Randomization, TrainConfig  # noqa: E402
from stages.locomotion.humanoids import ROBOTS, humanoid  # noqa: E402
from stages.locomotion.h1 import H1  # noqa: E402

try:
    H1_FILE = H1.source_path()
except FileNotFoundError:
    H1_FILE = None
needs_h1 = pytest.mark.skipif(H1_FILE is None, reason="shared H1 MJCF absent")


def test_g1_description_gives_the_trained_policy_s_values():
    from stages.locomotion import robot as g1

    desc = humanoid("g1")
    assert desc.joints == g1.LEG_JOINTS + g1.WAIST_JOINTS + g1.ARM_JOINTS
    assert desc.base_height == g1.DEFAULT_BASE_HEIGHT
    for j in desc.joints:
        assert desc.gains(j) == g1.joint_gains(j)
        assert desc.joint_posture_std(j) == g1.posture_std(j)
    for j in desc.leg_joints + desc.waist_joints:
        assert desc.joint_action_scale(j) == g1.joint_gains(j).action_scale
    for j in desc.arm_joints:
        assert desc.reach_range(j) == g1.reach_arm_range(j)
    with pytest.raises(ValueError, match="unknown humanoid 'h2'"):
        humanoid("h2")
    with pytest.raises(ValueError, match="robot must be one of g1, h1"):
        EnvConfig(robot="h2")
    assert set(ROBOTS) == {"g1", "h1"}


@needs_h1
def test_h1_description_covers_its_mjcf_joints():
    text = H1_FILE.read_text()
    joints = tuple(re.findall(r'<joint name="([a-z_]+)"', text))
    assert joints == H1.joints and H1.num_joints == 19
    motor = r'<motor class="h1" name="[a-z_]+" joint="([a-z_]+)" ctrlrange="-?[\d.]+ ([\d.]+)"'
    ctrl = dict(re.findall(motor, text))
    for j in H1.joints:
        g = H1.gains(j)
        assert g.effort_limit == float(ctrl[j]) and g.stiffness > 0 and g.damping > 0 and g.armature == 0.1
        assert H1.joint_posture_std(j) > 0
    assert {H1.joint_action_scale(j) for j in H1.leg_joints + H1.waist_joints} == {0.25}
    for j in H1.arm_joints:
        lo, hi = H1.reach_range(j)
        assert lo < hi


@pytest.fixture(scope="module")
def h1_env():
    from stages.locomotion.env import G1VelocityEnv

    cfg = EnvConfig(robot="h1", num_worlds=2, device="cpu", cuda_graph=False, seed=3,
                    randomization=Randomization(push_velocity=0.0, obs_noise=False))
    return G1VelocityEnv(cfg)


@needs_h1
def test_h1_env_stands_one_second_under_its_default_pose_pd(h1_env):
    env = h1_env
    assert env.num_actions == 11 and env.num_obs == 12 + 2 * 19 + 11
    assert env.obs.shape == (2, 61) and env.critic_obs.shape == (2, 61)
    assert env.policy_joints == H1.leg_joints + ("torso_joint",)
    lay = env.layout
    assert lay.joint_names == H1.joints and lay.coords_per_world == 26 and len(lay.foot_shapes) == 8
    # the soles start on the floor: the lowest sphere 0-5 mm above z = 0
    feet = env.body_q[:, env.foot_idx, 2] - H1.sole_below_ankle
    assert float(feet.min()) > -0.002 and float(feet.max()) < 0.006
    zero = torch.zeros(2, env.num_actions)
    heights = []
    for _ in range(50):  # 1 s at 50 Hz, arms moving to their random targets
        obs, critic, reward, fell, timed_out = env.step(zero)
        assert not fell.any() and not timed_out.any()
        heights.append(env.q[:, 2].clone())
    h = torch.stack(heights)
    assert obs.shape == (2, 61) and reward.shape == (2,) and torch.isfinite(reward).all()
    assert float(h.min()) > 0.95 and float(h[-1].min()) > 0.98, h[-1]
    assert int(env.episode_length_buf.min()) == 50


@pytest.fixture(scope="module")
def h1_policy(tmp_path_factory):
    pytest.importorskip("rsl_rl")
    from stages.locomotion.policy import export_from_checkpoint_dir
    from stages.locomotion.train import train

    tmp = tmp_path_factory.mktemp("h1")
    cfg = TrainConfig(env=EnvConfig(robot="h1", num_worlds=2, device="cpu", seed=5),
                      ppo=PPOConfig(num_steps_per_env=3, hidden_dims=(16, 16), num_mini_batches=1,
                                    num_learning_epochs=1),
                      iterations=2, save_every=1, checkpoint_dir=str(tmp / "run"))
    summary = train(cfg)
    export_from_checkpoint_dir(tmp / "run", tmp / "policy")
    return tmp, summary


@needs_h1
def test_h1_ppo_iterations_run_and_export_names_the_robot(h1_policy):
    from stages.locomotion.policy import PolicyRuntime, policy_humanoid

    tmp, summary = h1_policy
    assert summary["iteration"] == 2
    assert policy_humanoid(tmp / "run" / "model_2.pt") == "h1"
    meta = json.loads((tmp / "policy" / "policy.json").read_text())
    assert meta["humanoid"] == "h1" and meta["num_obs"] == 61 and meta["num_actions"] == 11
    assert list(meta["default_pos"]) == list(H1.joints) and meta["action_scale"]["torso_joint"] == 0.25
    assert policy_humanoid(tmp / "policy") == "h1"
    actions = PolicyRuntime.load(tmp / "policy").act(torch.zeros(4, 61))
    assert actions.shape == (4, 11) and torch.isfinite(actions).all()


@needs_h1
def test_humanoid_runtime_builds_the_policy_s_robot(h1_policy):
    import warp as wp

    from stages.locomotion.runtime import HumanoidWorlds, HumanoidWorldsConfig, LeggedRuntimeConfig

    tmp, _ = h1_policy
    worlds = HumanoidWorlds(HumanoidWorldsConfig(num_worlds=2, runtime=LeggedRuntimeConfig(
        policy=str(tmp / "policy"), spec="h1")))
    labels = {lbl.rsplit("/", 1)[-1] for lbl in worlds.model.joint_label}
    assert "torso_joint" in labels and "waist_yaw_joint" not in labels
    for _ in range(5):  # 0.1 s of the (barely trained) policy
        worlds.step()
    q = wp.to_torch(worlds.state.joint_q).view(2, -1)
    assert q.shape[1] == 26 and torch.isfinite(q).all() and float(q[:, 2].min()) > 0.9
