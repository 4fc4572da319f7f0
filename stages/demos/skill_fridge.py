"""The store-food skill (issue 16): the mug from the counter beside the microwave onto a shelf of the
opened fridge (task ``pick_place_fridge``; the multistage task ``store_food`` opens the fridge
first and closes it after).

- :func:`fridge_shelf`: where the mug goes: the shelf behind the door the open/close tasks use
  (:func:`stages.demos.sampling.world_part`) nearest 0.95 m high among those 0.5-1.2 m high with
  room for the mug and the hand above it, a spot :data:`SHELF_BACK` behind its front edge inside
  the door's opening;
- :func:`pick_place_fridge` (the expert): side-grasp the mug on the counter (as the microwave
  tasks), hold it 0.35 m ahead of the base, back away, drive before the fridge (the open leaf is an
  obstacle: the base stands beside it), carry the mug in over the shelf, lower, release, back out;
- :func:`pick_place_fridge_success` (the predicate): the mug's centre over the shelf (1 cm in
  from its edges) on it, upright, released.

The fridge may face any way (a house's kitchen); the counter faces world -Y (the task frame).
Frame: world, Z up, metres, radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stages.demos.base_approach import CHASSIS, HALF_WIDTH, drive_in, grid_with_leaf, leaf_points
from stages.demos.driver import APPROACH_TOL, ExpertFailure
from stages.demos.record import base_pose

SHELF_Z = (0.5, 1.2)     # shelves this high above the floor [m] are reachable with a side grasp
SHELF_PREFER = 0.95      # of those, the one nearest this height [m]
SHELF_BACK = 0.09        # the mug's spot: behind the shelf's front edge [m]
HAND_ROOM = 0.12         # free height above the mug a shelf needs for the hand [m]
BASE_GAP = 0.08          # the base's front before the fridge's (closed) front [m]
HAND_AWAY = 0.15         # a hand this far from the mug [m] does not hold it, open or closed
COUNTER_SHIFT = 0.25     # the base takes the mug up to this far along the counter from its usual spot [m]
MUG_OFF = 0.5            # ... and up to this far beside the mug [m] (the side grasp reaches it)


@dataclass(frozen=True)
class Shelf:
    """Where the mug goes. rect (xmin, ymin, xmax, ymax) [m]: where its centre must end (the
    shelf less 1 cm, world); z: the shelf's top [m]; spot (x, y) [m]: where the expert puts it;
    front (3,) unit: the fridge's outward front normal; edge: the shelf front edge's distance along
    ``front`` from the fridge origin [m]; door_y (lo, hi): the door's opening across the front in
    the fridge frame [m]."""

    rect: tuple[float, float, float, float]
    z: float
    spot: tuple[float, float]
    front: tuple[float, float, float]
    edge: float
    door_y: tuple[float, float]


def fridge_shelf(world, part, mug_radius: float, mug_height: float) -> Shelf:
    """The :class:`Shelf` of ``world``'s fridge behind the door ``part`` for a mug of
    ``mug_radius`` x ``mug_height`` [m]; ItemError when the fridge has none that fits."""
    from pipeline.types import ItemError
    from stages.demos.packages import link_bounds

    fr = world.placed["fridge"]
    lo, hi = link_bounds(fr.asset.usd, part.link)
    z0 = float(fr.position[2])
    ok = [s for s in fr.info.get("surfaces", []) if s["inside"] and s["link"] == "base"
          and SHELF_Z[0] <= z0 + s["z"] <= SHELF_Z[1] and lo[2] - 0.01 <= s["z"]
          and s["z"] + mug_height + HAND_ROOM <= hi[2] and s.get("clear_height", 1.0) >= mug_height + HAND_ROOM]
    if not ok:
        raise ItemError(f"{fr.asset.usd}: no fridge shelf {SHELF_Z[0]}-{SHELF_Z[1]} m high behind "
                        f"{part.link} with room for a {mug_height * 1000:.0f} mm mug")
    s = min(ok, key=lambda s: abs(z0 + s["z"] - SHELF_PREFER))
    y_lo = max(s["lo"][1], float(lo[1])) + mug_radius + 0.05
    y_hi = min(s["hi"][1], float(hi[1])) - mug_radius - 0.05
    if y_hi < y_lo:
        raise ItemError(f"{fr.asset.usd}: the door {part.link} opens too narrow a gap onto the shelf")
    spot = fr.to_world((s["hi"][0] - SHELF_BACK, 0.5 * (y_lo + y_hi), 0.0))
    rect = fr.rect((s["lo"][0] + 0.01, s["lo"][1] + 0.01), (s["hi"][0] - 0.01, s["hi"][1] - 0.01))
    return Shelf(rect=tuple(float(v) for v in rect), z=z0 + float(s["z"]),
                 spot=(float(spot[0]), float(spot[1])),
                 front=tuple(float(v) for v in fr.dir_to_world((1.0, 0.0, 0.0))), edge=float(s["hi"][0]),
                 door_y=(float(lo[1]), float(hi[1])))


def pick_place_fridge_success(inst, state, peaks=None) -> tuple[bool, str]:
    """The mug's centre over the shelf (:class:`Shelf` ``rect``), at most 4 cm above its top,
    upright, released (the hand open and off it, or :data:`HAND_AWAY` from it)."""
    from stages.demos.predicates import _inside, _placed_check

    shelf: Shelf = inst.place
    body = inst.world.placed["mug"].body()
    p = np.asarray(state.objects[body].position)
    if not _inside(p[:2], shelf.rect) or not shelf.z - 0.02 <= p[2] <= shelf.z + 0.04:
        return False, "object_not_in_container"
    reason = _placed_check(inst, state, body, shelf.z - 0.02)
    if reason == "object_still_held" and _hand_away(state, body):
        reason = ""  # (the hand closed again for a later stage: closing the fridge door)
    return (not reason), reason


def _hand_away(state, body: str, gap: float = HAND_AWAY) -> bool:
    """The TCP more than ``gap`` [m] from the body's origin: it cannot hold it, open or closed."""
    ee = np.asarray(state.robot.ee_pose.position)
    return float(np.linalg.norm(ee - np.asarray(state.objects[body].position))) > gap


def facing_rot(u, pitch_deg: float) -> np.ndarray:
    """Hand pointing along the horizontal unit ``u`` (2,) (tool Z), pitched down ``pitch_deg``,
    fingers closing horizontally across it (``side_rot`` for any heading)."""
    p = math.radians(pitch_deg)
    ux, uy = float(u[0]), float(u[1])
    z = np.array([ux * math.cos(p), uy * math.cos(p), -math.sin(p)])
    y = np.array([uy, -ux, 0.0])
    return np.stack([np.cross(y, z), y, z], axis=1)


def fridge_base(world, part, shelf: Shelf, q: float) -> tuple[tuple[float, float, float], float]:
    """The base pose (x, y, yaw) before the fridge with the door at ``q`` and the length [m] of the
    way in that reaches beyond the leaf: the chassis (and that way in) clear of the open leaf by
    6 cm, as near the shelf spot as that allows; ExpertFailure("no_base_pose") when the opening
    leaves no room."""
    fr = world.placed["fridge"]
    c, s = math.cos(fr.yaw), math.sin(fr.yaw)
    to_local = np.array([[c, s], [-s, c]])
    leaf = (leaf_points(part, q) - np.asarray(fr.position[:2])) @ to_local.T
    front = float(fr.asset.hi[0])
    x_base = front + BASE_GAP + CHASSIS / 2
    # the way in starts beyond the leaf's reach, at least 0.35 m back
    approach = max(0.35, float(leaf[:, 0].max()) + 0.45 - (x_base - CHASSIS / 2) + 0.05)
    spot_l = to_local @ (np.asarray(shelf.spot) - np.asarray(fr.position[:2]))
    near = leaf[(leaf[:, 0] > front + BASE_GAP - 0.06) & (leaf[:, 0] < x_base + CHASSIS / 2 + approach)]
    for dy in sorted(np.arange(-0.30, 0.3001, 0.01), key=abs):
        y = float(spot_l[1] + dy)
        if not len(near) or np.abs(near[:, 1] - y).min() >= HALF_WIDTH:
            p = fr.to_world((x_base, y, 0.0))
            return (float(p[0]), float(p[1]), float(math.atan2(-s, -c))), approach
    raise ExpertFailure("no_base_pose", f"{part.joint_path}: the leaf at {q:.2f} rad leaves no room before the fridge")


def counter_x(grid, front_y: float, x: float, mug_x: float, most: float = COUNTER_SHIFT,
              mug_off: float = MUG_OFF) -> float:
    """Where along the counter (its front at ``front_y`` [m], facing -Y) the base takes the mug
    (x [m]): ``x``, or where the open fridge
    leaf (on ``grid``) blocks the planned drive's end COUNTER_STAGE before the counter pose there,
    the nearest x up to ``most`` [m] aside, and at most ``mug_off`` [m] from the mug at ``mug_x``, where it
    does not (the straight drive in from there passes the leaf); ``x`` when there is none (the drive
    reports no_path)."""
    from stages.demos.counter import COUNTER_STAGE, facing_north_goal
    from stages.demos.driver import ROBOT_RADIUS
    from stages.demos.part_planning import is_free

    blocked = grid.inflate(ROBOT_RADIUS)
    for dx in sorted(np.arange(-most, most + 1e-9, 0.01), key=lambda v: (round(abs(v), 6), v)):
        gx, gy, _ = facing_north_goal(front_y, x + float(dx))
        if abs(gx - mug_x) <= max(mug_off, abs(x - mug_x)) and is_free(grid, blocked, gx, gy - COUNTER_STAGE):
            return float(gx)
    return x


def pick_place_fridge(inst, d) -> None:
    """The expert (see the module doc)."""
    from stages.demos.counter import (
        COUNTER_STAGE,
        SIDE_HEIGHT,
        SIDE_PITCH,
        _mug,
        _pose,
        _side_pick,
        approach_counter,
        side_rot,
    )

    w = inst.world
    shelf: Shelf = inst.place
    part = inst.part
    body, _, h = _mug(inst)
    start = np.asarray(inst.objects[body][:3], float)
    cav = w.cavity
    q = float(inst.joints[part.joint_path])
    grid = grid_with_leaf(w, part, q)
    # after open_fridge the base may stand where the planner counts it blocked (by the fridge or its
    # leaf: no_path from there in the test kitchen, world seed 5): move it clear first
    from stages.demos.articulated import _escape

    _escape(d, grid, reach=1.0)
    x = counter_x(grid, w.placed["counter"].footprint()[1], float((start[0] + 0.5 * (cav[0] + cav[2])) / 2),
                  float(start[0]))
    approach_counter(inst, d, x, grid=grid)
    gz = SIDE_HEIGHT * h
    _side_pick(d, start + [0.0, -0.003, gz], side_rot(SIDE_PITCH), 0.03)
    # hold it before the base, clear of the counter, and back away from the counter
    bx, by, th = base_pose(d.sim)
    held = facing_rot((math.cos(th), math.sin(th)), SIDE_PITCH)
    up = np.array([bx + 0.35 * math.cos(th), by + 0.35 * math.sin(th), w.counter_z + gz + 0.08])
    d.move(_pose(up, held), 1.2, segments=3, carry=True, tol=APPROACH_TOL)
    d.drive_straight((bx - COUNTER_STAGE * math.cos(th), by - COUNTER_STAGE * math.sin(th), th))
    goal, _ = fridge_base(w, part, shelf, q)
    drive_in(d, grid, goal, leaf_points(part, q))
    d.drive_straight(goal)
    # in over the shelf: the hand points into the fridge (-front)
    n = np.asarray(shelf.front[:2])
    rot = facing_rot(-n, SIDE_PITCH)
    fr = w.placed["fridge"]
    edge = float(np.dot(np.asarray(fr.position[:2]), n)) + shelf.edge  # the shelf edge along n
    spot = np.asarray(shelf.spot)
    along = float(np.dot(spot, n))
    z = shelf.z + gz + 0.025
    before = spot + (edge + 0.07 - along) * n
    d.move(_pose([*before, z], rot), 1.5, segments=3, carry=True, tol=APPROACH_TOL)
    d.move(_pose([*(spot + 0.01 * n), z], rot), 1.2, segments=3, carry=True)
    d.move(_pose([*(spot + 0.01 * n), z - 0.02], rot), 0.5, segments=1, settle=0.2)
    d.grip(0.0, 0.6)
    out = spot + (edge + 0.10 - along) * n
    d.move(_pose([*out, z], rot), 1.2, segments=3, tol=APPROACH_TOL)
    bx, by, th = base_pose(d.sim)
    d.drive_straight((bx - 0.3 * math.cos(th), by - 0.3 * math.sin(th), th))
    d.home(1.0)
