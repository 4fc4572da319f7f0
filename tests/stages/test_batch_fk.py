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
