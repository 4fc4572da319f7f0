"""Checks of a hold on an articulated part in the simulation (:mod:`stages.demos.articulated`): the
hand on the handle after closing (:func:`_check_grasp`), the finger opening, the tool centre's world
position. ``d`` is a :class:`~stages.demos.driver.Driver`; world frame, metres."""

from __future__ import annotations

import logging

import numpy as np

from stages.demos.driver import ExpertFailure
from stages.demos.parts import ArticulatedPart

log = logging.getLogger("stages.demos.articulated")

GRASP_TOL = 0.03    # the hand centre within this of the handle centre after closing [m]


def _check_grasp(part: ArticulatedPart, d, tol: float = GRASP_TOL, across_axis: bool = False,
                 along: float = 0.0, point=None) -> None:
    """Raise ExpertFailure("grasp_missed") when the hand is not on the handle (or ``point`` (3,),
    a link point at closed) after closing (``across_axis``: only the offset perpendicular to a
    drawer's axis counts)."""
    hand = _tcp_world(d)
    grip = np.asarray(part.handle, float) + along * np.asarray(part.bar_axis, float) if point is None else point
    handle = part.point_at(grip, d.sim.joint_q_of_path(part.joint_path))
    v = hand - handle
    if across_axis:
        v = v - np.dot(v, part.axis) * np.asarray(part.axis)
    gap = float(np.linalg.norm(v))
    log.debug("%s: grasp: hand %s handle %s (%.3f m), fingers %.3f", part.joint_path, np.round(hand, 3),
              np.round(handle, 3), gap, _finger_gap(d))
    if gap > tol:
        raise ExpertFailure("grasp_missed", f"{part.joint_path}: hand {gap:.3f} m from the handle")


def _finger_gap(d) -> float:
    """Finger opening [m] now (sum of the two finger joints)."""
    jq = d.sim.state_0.joint_q.numpy()
    return float(sum(jq[d.sim.world_coord(n)] for n in d.sim.desc.gripper.finger_joints))


def _tcp_world(d) -> np.ndarray:
    """World position (3,) of the end-effector frame in the simulation now."""
    from stages.simulate.control import Clik

    m = np.linalg.inv(Clik.world_to_root(d.sim.spawn, np.eye(4))) @ d.ik.fk(d.ik.from_sim(d.sim))
    return m[:3, 3]
