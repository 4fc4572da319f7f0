"""Hand and base motions at the kitchen counter and table that several experts share (the basic
tasks' :mod:`stages.demos.experts` and the household skills' ``stages.demos.skill_*``): the base
pose facing a piece of furniture, the side grasp's hand rotation, the approach to the counter and
the side pick of the mug.

Frame: world, Z up, metres, radians.
"""

from __future__ import annotations

import math

import numpy as np

from stages.demos.driver import APPROACH_TOL, Driver, stow
from stages.demos.record import base_pose

COUNTER_STAGE = 0.35  # the base raises or tucks the hand this far back from its pose at the counter [m]
SIDE_PITCH = 15.0  # side grasps: hand pitched down [deg] so the wrist clears the counter's edge
SIDE_HEIGHT = 0.45  # side grasps: TCP at this fraction of the mug's height


def _pose(p, rot) -> np.ndarray:
    from stages.simulate.control import pose

    return pose(np.asarray(p, float), rot)


def facing_north_goal(front_y: float, x: float, gap: float = 0.08) -> tuple[float, float, float]:
    """Base pose facing +Y with the chassis front ``gap`` [m] before the obstacle face at ``front_y``."""
    return (x, front_y - gap - 0.30, math.pi / 2)


def side_rot(pitch_deg: float = 0.0) -> np.ndarray:
    """Hand pointing along world +Y (tool Z), pitched down ``pitch_deg``, fingers closing along world X."""
    p = math.radians(pitch_deg)
    z = np.array([0.0, math.cos(p), -math.sin(p)])
    y = np.array([1.0, 0.0, 0.0])
    return np.stack([np.cross(y, z), y, z], axis=1)


def _mug(inst) -> tuple[str, float, float]:
    w = inst.world
    return w.placed["mug"].body(), w.mug_radius, w.mug_height


def approach_counter(inst, d: Driver, x: float, *, rot: np.ndarray | None = None,
                     lift: float = 0.12, reach: float = 0.35, grid=None) -> None:
    """Bring the base in front of the counter at ``x`` facing +Y: A* to a pose COUNTER_STAGE back, raise
    the hand to ``lift`` [m] above the counter top, ``reach`` [m] ahead of the base (the tucked arm
    would hit the counter's front), then drive the last COUNTER_STAGE straight in. ``grid``: the
    planning grid (default: the world's)."""
    w = inst.world
    goal = facing_north_goal(w.placed["counter"].footprint()[1], x)
    stage = (goal[0], goal[1] - COUNTER_STAGE, goal[2])
    tuck = stow(d, on_the_way=True)
    d.drive_to(stage, inst.world.grid() if grid is None else grid, approach=0.0, tuck=tuck)
    bx, by, th = base_pose(d.sim)
    ready = np.array([bx + reach * math.cos(th), by + reach * math.sin(th), w.counter_z + lift])
    d.move(_pose(ready, side_rot(0.0) if rot is None else rot), 1.5, segments=3, tol=APPROACH_TOL)
    d.drive_straight(goal)


def leave_counter(inst, d: Driver) -> None:
    """Raise the hand to the approach pose (clear of the counter), back the base COUNTER_STAGE away
    (the tucked hand then hangs 0.2 m clear of the counter's front), tuck."""
    w = inst.world
    bx, by, th = base_pose(d.sim)
    ready = np.array([bx + 0.35 * math.cos(th), by + 0.35 * math.sin(th), w.counter_z + 0.12])
    d.move(_pose(ready, side_rot(0.0)), 1.2, segments=3, tol=APPROACH_TOL)
    d.drive_straight((bx - COUNTER_STAGE * math.cos(th), by - COUNTER_STAGE * math.sin(th), th))
    d.home(1.0)


def _side_pick(d: Driver, at: np.ndarray, rot: np.ndarray, lift: float, pre: float = 0.14) -> np.ndarray:
    """Side grasp of the mug whose grasp point is ``at`` (3,): in front, in, close, lift ``lift`` [m];
    returns the lifted TCP position."""
    approach = rot[:, 2]
    d.grip(0.0, 0.1)
    d.move(_pose(at - pre * approach, rot), 1.6, segments=3, settle=0.1, tol=APPROACH_TOL)
    d.move(_pose(at, rot), 1.0, segments=2, settle=0.2)
    d.grip(1.0, 0.8)
    up = at + [0, 0, lift]
    d.move(_pose(up, rot), 0.6, segments=1, carry=True)
    return up
