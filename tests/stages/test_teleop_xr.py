"""WebXR poses -> end-effector target and gripper (pure numpy; the browser test drives it end to end)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stages.teleop.xr import XR_ORIGIN, ee_target_to_wrist, pinch_gripper, wrist_to_ee_target


def _pose(rot, pos) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = rot, pos
    return m


def _yaw_xr(a: float) -> np.ndarray:
    """Rotation about the XR y (up) axis by ``a`` [rad] (positive: turning left)."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def test_a_hand_ahead_and_below_the_head_puts_the_gripper_ahead_and_below_the_origin():
    head = _pose(np.eye(3), (0.0, 1.6, 0.0))
    wrist = _pose(np.eye(3), (0.1, 1.3, -0.5))  # 0.5 m ahead, 0.3 m down, 0.1 m right; fingers ahead
    t = wrist_to_ee_target(wrist, head)
    np.testing.assert_allclose(t[:3, 3], XR_ORIGIN + [0.5, -0.1, -0.3], atol=1e-12)
    np.testing.assert_allclose(t[:3, 2], [1, 0, 0], atol=1e-12)  # approach axis: forward
    np.testing.assert_allclose(t[:3, 1], [0, -1, 0], atol=1e-12)  # fingers close across the palm


def test_the_calibrated_heading_is_factored_out():
    a = math.radians(70.0)
    head = _pose(_yaw_xr(a), (1.0, 1.7, 2.0))
    wrist = _pose(_yaw_xr(a), (1.0, 1.4, 2.0) + _yaw_xr(a) @ [0.1, 0.0, -0.5])
    t = wrist_to_ee_target(wrist, head)
    np.testing.assert_allclose(t[:3, 3], XR_ORIGIN + [0.5, -0.1, -0.3], atol=1e-12)
    np.testing.assert_allclose(t[:3, 2], [1, 0, 0], atol=1e-12)
    # fingers pointing down (hand pitched 90 degrees about XR x) -> the gripper approaches downward
    down = _pose(np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]]) @ np.eye(3), (0.0, 1.3, -0.5))
    np.testing.assert_allclose(wrist_to_ee_target(down, _pose(np.eye(3), (0, 1.6, 0)))[:3, 2], [0, 0, -1], atol=1e-12)


def test_inverse_mapping_round_trips():
    rng = np.random.default_rng(0)
    from scipy.spatial.transform import Rotation

    for k in range(5):
        head = _pose(_yaw_xr(rng.uniform(-3, 3)) @ Rotation.from_rotvec([0.2, 0, 0.1]).as_matrix(), rng.normal(size=3))
        ee = _pose(Rotation.random(random_state=k).as_matrix(), rng.normal(size=3))
        np.testing.assert_allclose(wrist_to_ee_target(ee_target_to_wrist(ee, head), head), ee, atol=1e-12)


@pytest.mark.parametrize("gap, previous, expected", [(0.01, 0, 1), (0.06, 1, 0), (0.035, 0, 0), (0.035, 1, 1)])
def test_pinch_closes_and_opens_with_hysteresis(gap, previous, expected):
    joints = np.tile(np.eye(4), (25, 1, 1))
    joints[4][:3, 3] = (0.0, 1.2, -0.3)
    joints[9][:3, 3] = (gap, 1.2, -0.3)
    assert pinch_gripper(joints, previous) == expected
