"""Pieces of the tasks' success predicates that the basic tasks (:mod:`stages.demos.tasks`) and the
household skills (``stages.demos.skill_*``) share: upright, released, inside a rectangle, placed.
They read a :class:`~stages.simulate.state.StepState` (world frame, metres, radians)."""

from __future__ import annotations

import numpy as np


def _upright(q) -> bool:
    """Tilt of the body's +Z from world +Z below 30 deg (q: w, x, y, z)."""
    w, x, y, z = q
    return 1 - 2 * (x * x + y * y) >= np.cos(np.deg2rad(30.0))


def _released(state, body: str, min_gap: float = 0.03) -> bool:
    """The gripper is open and its TCP away from the body's origin (the object is not held)."""
    ee = np.asarray(state.robot.ee_pose.position)
    gap = np.linalg.norm(ee - np.asarray(state.objects[body].position))
    return state.robot.gripper_opening > 0.06 and gap > min_gap


def _inside(xy, rect, margin: float = 0.0) -> bool:
    x0, y0, x1, y1 = rect
    return x0 + margin <= xy[0] <= x1 - margin and y0 + margin <= xy[1] <= y1 - margin


def _placed_check(inst, state, body: str, z_min: float) -> str:
    """'' when ``body`` is upright, at or above ``z_min`` [m] and released; else the reason."""
    o = state.objects[body]
    if o.position[2] < z_min:
        return "object_fell"
    if not _upright(o.orientation):
        return "object_tipped"
    if not _released(state, body):
        return "object_still_held"
    return ""
