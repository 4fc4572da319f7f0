"""Batched end-effector FK (the engine's recorder): equal to Pinocchio's one-at-a-time FK."""

from __future__ import annotations

import numpy as np


def test_batched_arm_fk_and_pose7_equal_pinocchio_per_configuration(tmp_path):
    from stages.demos.experts import timed_clik
    from stages.demos.record import pose7
    from stages.simulate.batch_fk import ArmFK, pose7_batch
    from stages.simulate.robot import find_panda_description, write_robot_urdf

    desc = write_robot_urdf(tmp_path / "robot", panda_root=find_panda_description(None))
    ik = timed_clik(desc)
    fk = ArmFK(ik)
    idx = ik.v_idx[: len(desc.arm_joints)]
    q = np.random.default_rng(0).uniform(ik.lower[idx], ik.upper[idx], size=(64, len(desc.arm_joints)))
    q[0] = desc.arm_home
    ref = np.array([pose7(ik.fk(ik.with_arm(ik.neutral(), a))) for a in q])
    got = pose7_batch(fk(q))
    assert got.shape == (64, 7)
    np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)
    assert np.ptp(got[:, :3], axis=0).min() > 0.1  # the configurations really differ


def test_recorded_orientations_keep_the_home_pose_hemisphere_near_gripper_down(tmp_path):
    """The Panda's home orientation is a 180 deg turn from the identity ((0, 1, 0, 0)), where the
    qw >= 0 rule flips a quaternion's sign with the sign of a tiny qw. With the home orientation as
    the reference hemisphere a path of gripper-down poses, yawing and tilting a little, keeps one
    sign (no jump between neighbours), both in the engine's batched pose7 and in the
    process-per-world recorder's; the default rule (qw >= 0) still flips on that path."""
    from stages.demos.experts import timed_clik
    from stages.demos.record import pose7
    from stages.simulate.batch_fk import ArmFK, pose7_batch
    from stages.simulate.robot import find_panda_description, write_robot_urdf

    desc = write_robot_urdf(tmp_path / "robot", panda_root=find_panda_description(None))
    ik = timed_clik(desc)
    fk = ArmFK(ik)
    np.testing.assert_allclose(np.abs(fk.home_quat), [0.0, 1.0, 0.0, 0.0], atol=0.02)
    home = np.asarray(desc.arm_home, float)
    t = np.linspace(0.0, 1.0, 200)[:, None]
    q = home + np.concatenate([0.03 * np.sin(9 * t), 0.2 * t, 0.02 * np.cos(7 * t), -0.2 * t, 0.03 * np.sin(5 * t),
                               0.2 * t, 1.2 * t - 0.6], axis=1)  # gripper down, wrist yaw -0.6..0.6 rad
    got = pose7_batch(fk(q), fk.home_quat)
    assert np.abs(np.diff(got[:, 3:], axis=0)).max() < 0.05
    assert (got[:, 3:] @ fk.home_quat).min() > 0.5
    one = np.array([pose7(ik.fk(ik.with_arm(ik.neutral(), a)), fk.home_quat) for a in q])
    np.testing.assert_allclose(got, one, rtol=0, atol=1e-12)
    old = pose7_batch(fk(q))  # qw >= 0
    assert np.abs(np.diff(old[:, 3:], axis=0)).max() > 1.0  # the flips the reference removes
