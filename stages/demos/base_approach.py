"""Driving the mobile base up to furniture with an open leaf (the fridge's, the wardrobe's) or along
a narrow way in (the bookshelf): the leaf's footprint, the grid with the leaf on it, the staging
point of the planned drive and the drive there (the caller drives the last straight stretch); with
something held out ahead of the base (a hanger), the drive turns where its sweep clears the open leaf
(:func:`drive_clear`).

Used by the store-food, organize-books and organize-wardrobe skills. Frame: world, Z up, metres,
radians.
"""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from stages.demos.driver import ExpertFailure

log = logging.getLogger(__name__)

HALF_WIDTH = 0.25 + 0.06  # the chassis half width and a margin to the open leaf [m]
CHASSIS = 0.60           # chassis length [m]


def leaf_points(part, q: float) -> np.ndarray:
    """Points (N, 2) [m] covering the door leaf (and its handle) at joint value ``q``."""
    from stages.demos.part_grasps import lateral

    o = np.asarray(part.origin, float)
    a = np.asarray(part.axis, float)
    v = np.asarray(part.handle, float) - o
    reach = float(np.linalg.norm(v - np.dot(v, a) * a)) + 0.08
    lat, n, rot = lateral(part), np.asarray(part.front, float), part.rotation_at(q)
    return np.array([(o + rot @ (t * reach * lat + off * n))[:2]
                     for t in np.linspace(0.0, 1.0, 40) for off in (-0.03, 0.04, 0.11)])


def grid_with_leaf(world, part, q: float):
    """The world's occupancy grid with the hinged ``part``'s leaf at joint value ``q`` marked."""
    from stages.demos.part_planning import swept_grid

    return swept_grid(world.grid(), part, q, q)


def staging(grid, goal, leaf: np.ndarray, *, approach: float = 0.35, more: float = 1.5,
            side: float = 0.6) -> tuple[tuple[float, float], tuple[float, float]]:
    """Where the planned drive to ``goal`` (x, y, yaw) ends: ``(point, behind)``: the point
    ``approach`` [m] behind the goal on its way in, or where that is blocked for the planner (its
    0.4 m disc near a wall or the open leaf: a fridge in a corner), the free point nearest it up to
    ``more`` further back and ``side`` [m] aside whose sideways drive onto the way in keeps the
    chassis clear of the ``leaf`` (points (N, 2), world) [m]; ``behind`` (x, y): the point on the way
    in level with it, from where the base drives straight in (the chassis, narrower than the disc,
    fits). ExpertFailure("no_path") when there is none."""
    from stages.demos.driver import ROBOT_RADIUS

    blocked = grid.inflate(ROBOT_RADIUS)
    gx, gy, th = goal
    u, v = np.array([math.cos(th), math.sin(th)]), np.array([-math.sin(th), math.cos(th)])
    cands = [(abs(o) + 0.5 * (a - approach), a, o) for a in np.arange(approach, approach + more + 1e-9, 0.05)
             for o in np.arange(-side, side + 1e-9, 0.05)]
    for _, a, o in sorted(cands):
        behind = np.array([gx, gy]) - a * u
        p = behind + o * v
        iy, ix = grid.cell_of(float(p[0]), float(p[1]))
        if not (0 <= iy < blocked.shape[0] and 0 <= ix < blocked.shape[1]) or blocked[iy, ix]:
            continue
        # the chassis (its half length ahead and behind) along the sideways leg, and on the way in
        rel = leaf - behind
        along, across = rel @ u, rel @ v
        lo, hi = min(0.0, o), max(0.0, o)
        near = (np.abs(along) < CHASSIS / 2 + 0.06) & (across > lo - HALF_WIDTH) & (across < hi + HALF_WIDTH)
        if not near.any():
            return (float(p[0]), float(p[1])), (float(behind[0]), float(behind[1]))
    raise ExpertFailure("no_path", f"no free point behind the base pose {goal} before the fridge")


def drive_in(d, grid, goal, leaf: np.ndarray, *, held: np.ndarray | None = None,
             **kw) -> tuple[tuple[float, float], tuple[float, float]]:
    """Drive the base to the ``staging`` point of ``goal`` (x, y, yaw) (``leaf``, ``kw``: as there) and,
    where that point lies aside, sideways onto the way in; the caller drives the last straight stretch.
    ``held``: points (M, 2) [m] in the base frame (x ahead, y left) of what the arm holds out (a hanger):
    the drive there turns where the base and those points sweep clear of the ``leaf``
    (:func:`drive_clear`). Returns staging's ``(point, behind)`` (the way back out)."""
    point, behind = staging(grid, goal, leaf, **kw)
    if held is None:
        d.drive_to((*point, goal[2]), grid, approach=0.0)
    else:
        drive_clear(d, grid, (*point, goal[2]), leaf, held)
    if math.dist(point, behind) > 0.02:
        d.drive_straight((*behind, goal[2]))  # sideways onto the way in
    return point, behind


def held_points(d, placed) -> np.ndarray:
    """What the hand holds out, in the base frame (x ahead, y left): the corners of the held ``placed``
    object's bounding box (its asset's lo/hi, posed as simulated now) and the hand's tool point, (9, 2) [m]."""
    from stages.demos.record import base_pose
    from stages.simulate.state import read_state

    st = read_state(d.sim)
    o = st.objects[placed.body()]
    lo, hi = placed.asset.lo, placed.asset.hi
    box = np.array([[a, b, c] for a in (lo[0], hi[0]) for b in (lo[1], hi[1]) for c in (lo[2], hi[2])], float)
    world = np.asarray(o.position, float) + box @ o.matrix()[:3, :3].T
    return in_base_frame(base_pose(d.sim), np.vstack([world, np.asarray(st.robot.ee_pose.position, float)]))


TURN_MARGIN = 0.05         # the swept chassis and held points keep this far [m] from the open leaf's points
TURN_STEP = math.radians(60.0)  # a turn on the spot is driven in steps of at most this [rad] (the follower
                                # turns the short way: a 180 deg turn is driven the way that was chosen)
PATH_STEP = 0.05           # the drive's path is searched for a place to turn every this far [m]


def chassis_outline(step: float = 0.05) -> np.ndarray:
    """Points (N, 2) [m] on the chassis' outline in the base frame (x ahead, y left)."""
    hx, hy = CHASSIS / 2, HALF_WIDTH - 0.06
    xs, ys = np.arange(-hx, hx + 1e-9, step), np.arange(-hy, hy + 1e-9, step)
    return np.vstack([np.column_stack([xs, np.full_like(xs, s * hy)]) for s in (-1, 1)]
                     + [np.column_stack([np.full_like(ys, s * hx), ys]) for s in (-1, 1)])


def in_base_frame(pose, pts) -> np.ndarray:
    """World points (M, >=2) [m] in the frame of the base at ``pose`` (x, y, yaw): (M, 2) [m]."""
    x, y, th = pose
    rel = np.asarray(pts, float)[:, :2] - [x, y]
    c, s = math.cos(th), math.sin(th)
    return np.column_stack([c * rel[:, 0] + s * rel[:, 1], -s * rel[:, 0] + c * rel[:, 1]])


def clearance(poses: np.ndarray, body: np.ndarray, leaf: np.ndarray) -> float:
    """The least distance [m] between the ``leaf`` points (N, 2) and the ``body`` points (M, 2, base frame)
    carried by the base through ``poses`` (K, 3: x, y, yaw) [m, rad]; inf without leaf points."""
    if len(leaf) == 0 or len(poses) == 0:
        return math.inf
    th = np.asarray(poses, float)[:, 2]
    c, s = np.cos(th)[:, None], np.sin(th)[:, None]
    wx = poses[:, :1] + c * body[None, :, 0] - s * body[None, :, 1]
    wy = poses[:, 1:2] + s * body[None, :, 0] + c * body[None, :, 1]
    pts = np.column_stack([wx.ravel(), wy.ravel()])
    best = math.inf
    for k in range(0, len(pts), 4096):
        dd = np.linalg.norm(pts[k:k + 4096, None, :] - np.asarray(leaf)[None, :, :2], axis=2)
        best = min(best, float(dd.min()))
    return best


def rollout(path: np.ndarray, yaw: float, pose, dt: float, timeout: float = 15.0) -> np.ndarray:
    """The base poses (K, 3) [m, rad] the path follower's commands give from ``pose`` along ``path`` (N, 2)
    [m], turning to ``yaw`` [rad] (kinematic: the base taken to follow its commands at once, every ``dt`` [s])."""
    from stages.demos.planner import PathFollower

    f = PathFollower(np.asarray(path, float), float(yaw), dt=dt)
    x, y, th = (float(v) for v in pose)
    out = [(x, y, th)]
    for _ in range(int(timeout / dt)):
        (vx, vy, w), done = f.command(x, y, th)
        if done:
            break
        c, s = math.cos(th), math.sin(th)
        x, y, th = x + (c * vx - s * vy) * dt, y + (s * vx + c * vy) * dt, th + w * dt
        out.append((x, y, th))
    return np.asarray(out, float)


def spin(xy, yaw0: float, turn: float) -> np.ndarray:
    """The poses (K, 3) of a turn on the spot at ``xy`` from ``yaw0`` by ``turn`` [rad] (signed), 2 deg apart."""
    n = max(2, int(math.ceil(abs(turn) / math.radians(2.0))) + 1)
    return np.array([(xy[0], xy[1], yaw0 + a) for a in np.linspace(0.0, turn, n)])


def _along(path: np.ndarray, step: float) -> list[tuple[int, np.ndarray]]:
    """Points ``step`` [m] apart along the polyline ``path`` (N, 2), each with the index of its segment."""
    out = [(0, path[0])]
    for i in range(len(path) - 1):
        a, b = path[i], path[i + 1]
        n = int(math.floor(float(np.linalg.norm(b - a)) / step))
        out += [(i, a + (b - a) * k * step / float(np.linalg.norm(b - a))) for k in range(1, n + 1)]
    out.append((len(path) - 2, path[-1]))
    return out


def plan_turn(path: np.ndarray, pose, yaw: float, body: np.ndarray, leaf: np.ndarray, dt: float,
              margin: float = TURN_MARGIN):
    """Where to turn on the way: None where the follower's own drive along ``path`` (N, 2) [m] from ``pose``
    (x, y, yaw), turning to ``yaw`` [rad] on the way, keeps the chassis and the ``body`` points (M, 2, base
    frame) ``margin`` [m] from the ``leaf`` (N, 2); else ``(i, point, turn)``: drive along the path (its
    segments up to ``i``) to ``point`` holding the present yaw, turn there on the spot by ``turn`` [rad]
    (signed: the short way, else the long way), then drive on: the first point whose three legs keep that
    clearance. The margin is eased to the clearance at the drive's end (the goal is the caller's). Raises
    ExpertFailure("no_path") where no point along the path has a clear turn."""
    from stages.demos.planner import wrap

    body = np.vstack([chassis_outline(), np.asarray(body, float).reshape(-1, 2)])
    end = np.array([[*path[-1], yaw]])
    m = min(margin, clearance(end, body, leaf) - 0.01)
    if clearance(rollout(path, yaw, pose, dt), body, leaf) >= m:
        return None
    th = float(pose[2])
    short = wrap(yaw - th)
    turns = (short, short - math.copysign(2 * math.pi, short)) if abs(short) > 1e-3 else (short,)
    for i, p in _along(np.asarray(path, float), PATH_STEP):
        head = np.vstack([path[: i + 1], p])
        if clearance(rollout(head, th, pose, dt), body, leaf) < m:
            break  # held so, the body meets the leaf on the way: no later point either
        for turn in turns:
            if clearance(spin(p, th, turn), body, leaf) < m:
                continue
            tail = np.vstack([p, path[i + 1:]])
            if clearance(rollout(tail, yaw, (*p, yaw), dt), body, leaf) >= m:
                return i, p, turn
    raise ExpertFailure("no_path", f"no place on the way to {tuple(path[-1])} to turn clear of the open leaf")


def drive_clear(d, grid, goal, leaf: np.ndarray, held: np.ndarray) -> None:
    """Drive the base to ``goal`` (x, y, yaw) planned on ``grid`` (``Driver.plan_drive``, approach 0), turning
    where the chassis and the ``held`` points (M, 2) [m, base frame] sweep clear of the ``leaf`` (N, 2)
    (:func:`plan_turn`): turned on the way while 0.55 m from an open leaf's free edge, a hanger held out ahead
    swept the wardrobe's door half shut (flat_018: 1.36 -> 0.36-0.71 rad). Where no place is clear, the
    follower's own drive (logged). ExpertFailure("no_path") where the planner finds no way."""
    from stages.demos.record import base_pose

    path = d.plan_drive(goal, grid, approach=0.0)
    t0 = time.perf_counter()
    pose = base_pose(d.sim)
    try:
        plan = plan_turn(path, pose, goal[2], held, leaf, d.frame_dt)
    except ExpertFailure as e:
        log.info("drive_clear: %s: turning on the way", e)
        plan = None
    d.plan_seconds += time.perf_counter() - t0
    if plan is None:
        d.follow(path, goal[2])
        return
    i, p, turn = plan
    log.info("drive_clear: turning %.0f deg at (%.2f, %.2f) on the way to %s", math.degrees(turn), p[0], p[1],
             np.round(goal, 2))
    th = float(pose[2])
    if float(np.linalg.norm(p - path[0])) > 0.01:
        d.follow(np.vstack([path[: i + 1], p]), th)
    n = max(1, int(math.ceil(abs(turn) / TURN_STEP)))
    for k in range(1, n + 1):
        d.follow(np.array([p, p]), th + turn * k / n)
    d.follow(np.vstack([p, path[i + 1:]]), goal[2])
