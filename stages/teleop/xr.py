"""WebXR poses -> an end-effector target and a gripper command (pure numpy).

Frames. The page sends poses in the XR ``local-floor`` reference space (y up, -z ahead of the
user's start, metres). The robot's base frame has x ahead, y left, z up (metres). The operator's
head at *calibration* (the first XR message of an episode) stands for the robot's viewpoint
``origin`` in the base frame (:data:`XR_ORIGIN`, near the head camera): a wrist pose ``W`` becomes

    T_base = [R  origin] . Yaw(head_calib)^-1 . W . [R_hand_ee  0]
             [0    1   ]                            [0          1]

where ``Yaw(head_calib)`` is the calibration head pose reduced to its position and its heading
(rotation about y), ``R`` maps XR axes to robot axes (robot x = -XR z, robot y = -XR x, robot z =
XR y) and ``R_hand_ee`` maps the wrist joint's frame (WebXR: -z along the fingers, +y out of the
back of the hand) to the gripper's (z the approach along the fingers, y the fingers' closing
direction across the palm). So moving the hand 10 cm forward moves the gripper 10 cm forward of
where the base's frame is, and pointing the fingers down points the gripper down.

Gripper: the distance between the thumb tip (joint 4) and the index finger tip (joint 9) closes
it below :data:`PINCH_CLOSE` and opens it above :data:`PINCH_OPEN` [m] (hysteresis in between).
"""

from __future__ import annotations

import math

import numpy as np

XR_ORIGIN = np.array([0.10, 0.0, 1.20])
"""Where the operator's calibrated head sits in the robot's base frame [m] (about the head camera)."""

R_XR_TO_ROBOT = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
R_HAND_TO_EE = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])

WRIST, THUMB_TIP, INDEX_TIP = 0, 4, 9  # XRHand joint indices
PINCH_CLOSE, PINCH_OPEN = 0.025, 0.045  # thumb-index tip distance [m]


def heading_frame(head: np.ndarray) -> np.ndarray:
    """The head pose (4, 4) reduced to its position and its heading about the XR y axis."""
    fwd = -np.asarray(head, float)[:3, 2]  # the view direction (-z)
    yaw = math.atan2(-fwd[0], -fwd[2])  # rotation about +y that takes -z to fwd's horizontal part
    c, s = math.cos(yaw), math.sin(yaw)
    m = np.eye(4)
    m[:3, :3] = [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]
    m[:3, 3] = np.asarray(head, float)[:3, 3]
    return m


def wrist_to_ee_target(wrist: np.ndarray, head_calib: np.ndarray, origin=XR_ORIGIN) -> np.ndarray:
    """End-effector target (4, 4) in the robot's base frame for an XR wrist pose (4, 4), given the
    calibration head pose (4, 4) (see the module docstring)."""
    rel = np.linalg.inv(heading_frame(head_calib)) @ np.asarray(wrist, float)
    t = np.eye(4)
    t[:3, :3] = R_XR_TO_ROBOT @ rel[:3, :3] @ R_HAND_TO_EE
    t[:3, 3] = np.asarray(origin, float) + R_XR_TO_ROBOT @ rel[:3, 3]
    return t


def ee_target_to_wrist(ee_base: np.ndarray, head_calib: np.ndarray, origin=XR_ORIGIN) -> np.ndarray:
    """The XR wrist pose (4, 4) that :func:`wrist_to_ee_target` maps to ``ee_base`` (its inverse)."""
    ee = np.asarray(ee_base, float)
    rel = np.eye(4)
    rel[:3, :3] = R_XR_TO_ROBOT.T @ ee[:3, :3] @ R_HAND_TO_EE.T
    rel[:3, 3] = R_XR_TO_ROBOT.T @ (ee[:3, 3] - np.asarray(origin, float))
    return heading_frame(head_calib) @ rel


def pinch_gripper(joints: np.ndarray, previous: int) -> int:
    """Gripper command (0 open, 1 closed) from a hand's joint poses (25, 4, 4), with hysteresis."""
    d = float(np.linalg.norm(joints[THUMB_TIP][:3, 3] - joints[INDEX_TIP][:3, 3]))
    if d < PINCH_CLOSE:
        return 1
    if d > PINCH_OPEN:
        return 0
    return int(previous)


def base_to_root(q_base: tuple[float, float, float]) -> np.ndarray:
    """The base frame in the robot root (spawn) frame (4, 4) from the base joints (x, y [m], yaw [rad])."""
    x, y, yaw = q_base
    c, s = math.cos(yaw), math.sin(yaw)
    m = np.eye(4)
    m[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    m[:3, 3] = (x, y, 0.0)
    return m
