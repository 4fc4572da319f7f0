"""Planning for the articulated-part experts (:mod:`stages.demos.articulated`): base poses from
which CLIK reaches a part's waypoints (:func:`choose_base`, :func:`plan_stage`), the arm solutions
along them (:func:`reach`) and the occupancy grid with the area a part sweeps (:func:`swept_grid`).

``d`` is a :class:`~stages.demos.driver.Driver`; plans are checked by IK only, the simulation does
not step. The candidates of a search have their reaches computed side by side
(:mod:`stages.simulate.clik_lanes`: the same solves, bit for bit, as one after another) and are
judged in order, so the plans are those of the plain sequential search
(``tests/stages/test_expert_fast.py``).
"""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from stages.demos.driver import NEAR_STAGING, ROBOT_RADIUS, ExpertFailure
from stages.demos.part_grasps import door_pitch, drawer_pitch, gesture, grips, heading, lateral, toward_hinge
from stages.demos.parts import ArticulatedPart
from stages.simulate.cooperative import checkpoint

log = logging.getLogger(__name__)

STAGING = 0.35      # Driver.drive_to's staging distance behind a base goal [m]
OVEN_HALF_WIDTH = 0.4  # half width of a bottom-hinged door's leaf for base planning [m]
BASE_SLACK = 0.02    # plans must hold with the base this much further from the handle [m]
LIMIT_MARGIN = 0.05  # planned arm joints keep this far from their limits [rad]
EDGE_SIDE = 0.8  # preferred base offset along the bar from its centre when lifting by the edge [m]
# a bottom-hinged (oven) leaf carried by its handle over at most these arcs [rad] beyond where it
# stands, from bases clear of only that much of its sweep (below ~30 deg its counterbalanced hinge
# holds it where it is let go of: it cannot drop onto a base standing that near)
SHORT_ARCS = (0.45, 0.3)


def _robot_q(d) -> np.ndarray:
    """The Pinocchio configuration of the robot now (arm at its joint targets)."""
    return d.ik.with_arm(d.ik.from_sim(d.sim), d.ctl.arm_targets())


def _place_base(d, q: np.ndarray, base: tuple[float, float, float]) -> np.ndarray:
    """A copy of configuration ``q`` with the base moved to ``base`` (world x, y, yaw)."""
    q = q.copy()
    x0, y0, yaw0 = d.sim.spawn
    c, s = math.cos(yaw0), math.sin(yaw0)
    dx, dy = base[0] - x0, base[1] - y0
    local = (c * dx + s * dy, -s * dx + c * dy, base[2] - yaw0)
    for name, v in zip(d.sim.desc.base_joints, local, strict=True):
        q[d.ik.q_idx[name]] = v
    return q


def reachable(d, base: tuple[float, float, float], targets, *, tol: float = 0.004) -> bool:
    """Whether every world pose of ``targets`` (4x4 each, in order) is reached by CLIK from a
    base at ``base`` (see :func:`reach`)."""
    return len(reach(d, base, targets, tol=tol)) == len(targets)


def is_free(grid, blocked, x: float, y: float) -> bool:
    iy, ix = grid.cell_of(x, y)
    ny, nx = blocked.shape
    return 0 <= iy < ny and 0 <= ix < nx and not blocked[iy, ix]


# How far the drawer expert's first base pose candidate is moved at random (dn, dl) [m]: without
# it every grasp had the handle at the same place in the base frame (0.72 m ahead, 0 m left, std
# 1 mm over 400 episodes), and a policy arriving a few centimetres off reached to that place and
# closed its hand on nothing (issue 17, session 27).
STANCE_JITTER = np.array([0.06, 0.06])
# How far its yaw is turned at random from square to the front [rad]: the grasp is a world pose, so
# the expert's hand stays square to the bar from a turned stance, and the data shows a policy how a
# turned base turns the hand (session 29: a policy that kept the hand's base-frame orientation from
# a stance 0.5 rad off square gripped the bar rolled, and it slipped).
STANCE_YAW_JITTER = 0.5


def choose_base(d, part: ArticulatedPart, grid, candidates,
                targets_of) -> tuple[tuple[float, float, float], float]:
    """The first (base pose, pitch) of ``candidates`` ((dn, dl, dyaw, pitch): metres out from the
    handle along the front, metres along the lateral direction (from the hinge towards the handle),
    yaw offset [rad] from facing the part towards the hinge side, gripper pitch [rad]) whose
    footprint is free on ``grid`` and from which ``targets_of(base, pitch)`` are all reachable;
    raises ExpertFailure("no_base_pose")."""
    n, lat = np.asarray(part.front, float), lateral(part)
    h = np.asarray(part.handle, float)
    face, sgn = heading(-n), toward_hinge(part)
    blocked = grid.inflate(ROBOT_RADIUS)
    free = []
    for dn, dl, dyaw, pitch in candidates:
        p = h + dn * n + dl * lat
        base = (float(p[0]), float(p[1]), face + sgn * dyaw)
        if is_free(grid, blocked, base[0], base[1]):
            free.append((base, pitch, dn, dl, dyaw))
    q = _robot_q(d)
    # the free candidates' reaches run in lockstep (the first that reaches wins, as in order): 2
    # lanes, doubling per candidate judged, up to 8
    jobs = (_reach_job(d, q, c[0], targets_of(c[0], c[1]), 0.004, count=True) for c in free)
    for k, (sols, total) in _lockstep(d, jobs, lambda judged: min(8, 2 << judged)):
        if len(sols) == total:
            base, pitch, dn, dl, dyaw = free[k]
            log.info("%s: base %s (dn %.2f dl %.2f dyaw %.2f pitch %.2f)", part.joint_path, base, dn, dl,
                     dyaw, pitch)
            return base, pitch
    raise ExpertFailure("no_base_pose",
                        f"{part.joint_path}: none of {len(free)} free base poses reaches the handle path")


def swept_grid(grid, part: ArticulatedPart, q_lo: float, q_hi: float, margin: float = 0.06):
    """A copy of ``grid`` with the cells the part's front sweeps between joint values q_lo and
    q_hi marked occupied (the door leaf out to its handle plus ``margin`` [m]; a drawer's front
    slides out by q_hi)."""
    from stages.demos.planner import NavGrid

    checkpoint()  # a sweep of milliseconds: a cooperative scheduler may run another world first
    occ = grid.occupied.copy()
    o = np.asarray(part.origin, float)
    h = np.asarray(part.handle, float)
    lat = lateral(part)
    n = np.asarray(part.front, float)
    if part.kind == "revolute":
        v = h - o
        reach = float(np.linalg.norm(v - np.dot(v, part.axis) * np.asarray(part.axis))) + margin + 0.04
        qs = np.linspace(q_lo, q_hi, max(2, int(abs(q_hi - q_lo) / math.radians(2.0)) + 2))
        a = np.asarray(part.axis, float)
        # a bottom-hinged (oven) door spans its width along the axis
        widths = [0.0] if abs(a[2]) > 0.7 else np.linspace(-OVEN_HALF_WIDTH, OVEN_HALF_WIDTH, 17)
        pts = []
        for q in qs:
            rot = part.rotation_at(q)
            for t in np.linspace(0.0, 1.0, int(reach / (grid.cell / 2)) + 2):
                for off in (0.0, 0.05):
                    for wd in widths:
                        pts.append(o + rot @ (t * reach * lat + off * n) + wd * a)
    else:
        width = 0.3
        pts = [h + s * q_hi * n + b * width * lat for s in np.linspace(0, 1, 20)
               for b in np.linspace(-1, 1, 13)]
    for p in pts:
        iy, ix = grid.cell_of(float(p[0]), float(p[1]))
        if 0 <= iy < occ.shape[0] and 0 <= ix < occ.shape[1]:
            occ[iy, ix] = True
    return NavGrid(grid.origin, grid.cell, occ)


def reach(d, base: tuple[float, float, float], targets, *, tol: float = 0.004) -> list[np.ndarray]:
    """Arm solutions (7,) for the leading ``targets`` (4x4 world poses, in order) that CLIK reaches
    one after the other from a base at ``base`` (the first with random restarts, the others
    warm-started from the previous solution, as the motion runs)."""
    return _run(d, _reach_job(d, _robot_q(d), base, targets, tol))


def _lockstep(d, jobs, width):
    from stages.simulate.clik_lanes import lockstep

    return lockstep(d.ik, jobs, width)


def _run(d, job):
    """The value of one job (see :mod:`stages.simulate.clik_lanes`), its solves timed as
    ``Clik.solve`` calls are where the Clik counts them (``seconds``)."""
    from stages.simulate.clik_lanes import run_job

    t0 = time.perf_counter()
    try:
        return run_job(d.ik, job)
    finally:
        if hasattr(d.ik, "seconds"):
            d.ik.seconds += time.perf_counter() - t0


def _reach_job(d, q_robot: np.ndarray, base, targets, tol: float, count: bool = False):
    """:func:`reach` from configuration ``q_robot`` (base moved to ``base``) as a job of
    :mod:`stages.simulate.clik_lanes` (the same solves: restarts from ``default_rng(k)``);
    ``count``: returns (solutions, len(targets))."""
    from stages.simulate.clik_lanes import solve_job
    from stages.simulate.control import Clik

    q = _place_base(d, q_robot, base)
    out = []
    targets = list(targets)
    root = Clik.root_from_world(d.sim.spawn)  # world_to_root's transform, once
    idx = [d.ik.q_idx[n] for n in d.sim.desc.arm_joints]
    for k, t in enumerate(targets):
        res = yield from solve_job(d.ik, root @ np.asarray(t, float), q, max_iters=300,
                                   restarts=6 if k == 0 else 0, rng=lambda k=k: np.random.default_rng(k))
        if res.position_error > tol or res.rotation_error > math.radians(2.0) or _at_limit(d, res.q, idx=idx):
            break
        q = res.q
        out.append(d.ik.arm_q(q))
    return (out, len(targets)) if count else out


def _at_limit(d, q: np.ndarray, margin: float = LIMIT_MARGIN, idx=None) -> bool:
    """Whether an arm joint of Pinocchio configuration ``q`` is within ``margin`` [rad] of a limit
    (such a plan breaks when the base stops a centimetre off its goal). ``idx``: the arm joints'
    configuration indices, where the caller has them."""
    if idx is None:
        idx = [d.ik.q_idx[n] for n in d.sim.desc.arm_joints]
    return bool(np.any(q[idx] < d.ik.lower[idx] + margin) or np.any(q[idx] > d.ik.upper[idx] - margin))


def connected(grid, start_xy, reach: float = 0.5) -> np.ndarray:
    """(ny, nx) bool: the cells where the base's footprint (ROBOT_RADIUS) is free on ``grid`` and
    which the planner reaches from ``start_xy`` (x, y) [m] (or, where that is blocked, from the
    free cell nearest it within ``reach`` [m], where the experts escape to first)."""
    from scipy import ndimage

    free = ~grid.inflate(ROBOT_RADIUS)
    lab, _ = ndimage.label(free)
    iy, ix = grid.cell_of(float(start_xy[0]), float(start_xy[1]))
    cells = np.argwhere(lab > 0)
    if not len(cells):
        return free
    dist = np.hypot(cells[:, 0] - iy, cells[:, 1] - ix) * grid.cell
    k = int(np.argmin(dist))
    if dist[k] > reach:
        return np.zeros_like(free)
    return lab == lab[tuple(cells[k])]


def _swing_bases(part: ArticulatedPart, grid, q0: float, qs: list[float],
                 spread: float = 100.0, inner: bool = False, within=None,
                 staging: float = STAGING) -> list[tuple[float, float, float]]:
    """Candidate base poses for carrying the handle from q0 along ``qs``: on rings 0.55-1.15 m
    around the handle at q0, in front of the leaf or beyond its free edge (up to ``spread`` [deg]
    round from its front normal; ``inner``: behind the leaf, round from its inner normal), facing
    the middle of the handle's path (+-0.4 rad); free on ``grid`` (and true on ``within``, (ny, nx)
    bool: :func:`connected`, where given), and so is the point ``staging`` [m] behind them where the
    drive's straight leg starts; nearest to the ideal reach first."""
    blocked = grid.inflate(ROBOT_RADIUS)
    if within is not None:
        blocked = blocked | ~within
    h0 = part.handle_at(q0)
    mid = part.handle_at(qs[len(qs) // 2]) if qs else h0
    f = -part.front_at(q0) if inner else part.front_at(q0)
    f = f[:2] / max(np.linalg.norm(f[:2]), 1e-9)
    out = []
    for rho in (0.55, 0.65, 0.75, 0.85, 0.95, 1.05, 1.15):
        for phi in np.radians(np.arange(-spread, spread + 1.0, 20.0)):
            c, s_ = math.cos(phi), math.sin(phi)
            v = np.array([c * f[0] - s_ * f[1], s_ * f[0] + c * f[1]])
            xy = h0[:2] + rho * v
            if not is_free(grid, blocked, float(xy[0]), float(xy[1])):
                continue
            to_mid = heading(mid[:2] - xy)
            reach = float(np.linalg.norm(mid[:2] - xy))
            for dyaw in (0.0, 0.4, -0.4):
                yaw = to_mid + dyaw
                stage = xy - staging * np.array([math.cos(yaw), math.sin(yaw)])
                if not is_free(grid, blocked, float(stage[0]), float(stage[1])):
                    continue
                out.append((abs(reach - 0.7) + 0.1 * abs(dyaw), (float(xy[0]), float(xy[1]), to_mid + dyaw)))
    out.sort(key=lambda t: t[0])
    return [b for _, b in out]


def _robust(d, base, part: ArticulatedPart, targets, q_robot: np.ndarray | None = None) -> bool:
    """Whether ``targets`` stay reachable with the base stopped BASE_SLACK further from the handle
    than planned (the drive ends within a centimetre or two of its goal)."""
    away = np.asarray(base[:2]) - np.asarray(part.handle[:2])
    away = away / max(np.linalg.norm(away), 1e-9) * BASE_SLACK
    shifted = (base[0] + float(away[0]), base[1] + float(away[1]), base[2])
    q = _robot_q(d) if q_robot is None else q_robot
    return len(_run(d, _reach_job(d, q, shifted, targets, 0.006))) == len(targets)


def plan_stage(d, part: ArticulatedPart, grid, q0: float, qs: list[float], mode: str = "grasp",
                max_checks: int = 70, within=None):
    """(base, pitch, n, arm solutions, along): the base pose and grip (pitch, offset along the
    bar) from which the approach at q0 and the first n waypoints of ``qs`` are reachable, n as
    large as found (all of them ends the search), and the arm solutions of approach + those
    waypoints.

    The candidates (base poses by :func:`_swing_bases`, each with its :func:`grips`) are checked
    in order, the first ``max_checks`` (``within``: see :func:`_swing_bases`); their reaches run in lockstep, up to 16 at a time
    (:mod:`stages.simulate.clik_lanes`), and are judged in order as they complete."""
    z = float(part.handle_at(q0)[2])
    vertical = abs(float(np.asarray(part.axis)[2])) > 0.7
    p0 = door_pitch(z) if vertical else drawer_pitch(z)
    best = (None, 0.0, -1, [], 0.0)
    # closing a vertical door, the turned fists (part_grasps.PUSH_YAWS) press its front face from
    # beside the free edge: bases further round it, before the fridge, not beyond the hinge
    push_yaws = mode == "push" and vertical
    bases = _swing_bases(part, grid, q0, qs, spread=80.0 if mode == "inner" else 100.0, inner=mode == "inner",
                         within=within)
    if mode == "edge":
        # a lying leaf is lifted from beside it (from in front, its edge runs out of reach as it
        # rises): bases about EDGE_SIDE off the bar's centre along it first
        bar = np.asarray(part.bar_axis, float)[:2]
        bases.sort(key=lambda b: abs(abs(float(np.dot(np.asarray(b[:2]) - part.handle[:2], bar))) - EDGE_SIDE))
        max_checks = 3 * max_checks
    cands = [(base, pitch, along) for base in bases
             for pitch, along in grips(part, base, p0, vertical, edge=mode == "edge", push=mode == "push")]
    if push_yaws:
        # the square fist first, from the bases it had before the turned ones existed (a tie keeps
        # it: on a room door a turned fist reaching as far left the leaf 0.29 rad open and took 3
        # more stages), then the turned fists (part_grasps.PUSH_YAWS, ``along`` != 0) from bases
        # further round the free edge, twice as many checks
        turned = [(base, pitch, along) for base in _swing_bases(part, grid, q0, qs, spread=140.0, within=within)
                  for pitch, along in grips(part, base, p0, vertical, push=True) if along != 0.0]
        cands = [c for c in cands if c[2] == 0.0][:max_checks] + turned[:2 * max_checks]
        # then, on a tight floor (the open leaf's free edge near a wall), the turned fists from bases
        # whose staging point only NEAR_STAGING behind is free (Driver.drive_to stages there)
        seen = set(bases) | {c[0] for c in turned}
        near = [(base, pitch, along) for base in _swing_bases(part, grid, q0, qs, spread=140.0, within=within,
                                                              staging=NEAR_STAGING) if base not in seen
                for pitch, along in grips(part, base, p0, vertical, push=True) if along != 0.0]
        cands += near[:max_checks]
    else:
        cands = cands[:max_checks]
    gestures: dict = {}  # the approach and arc of a grip do not depend on the base

    def gesture_of(pitch: float, along: float):
        if (pitch, along) not in gestures:
            gestures[pitch, along] = gesture(part, q0, qs, pitch, mode, along)
        return gestures[pitch, along]

    def job(base, pitch: float, along: float):
        approach, arc = gesture_of(pitch, along)
        return _reach_job(d, q_robot, base, approach + arc, 0.004)

    q_robot = _robot_q(d)
    jobs = (job(*c) for c in cands)
    checks = 0
    # the first candidates often suffice (a full reach ends the search): 2 lanes, doubling per
    # candidate judged, up to 16
    for k, sols in _lockstep(d, jobs, lambda judged: min(16, 2 << judged)):
        base, pitch, along = cands[k]
        approach, arc = gesture_of(pitch, along)
        n = len(sols) - len(approach)
        checks += 1
        if n > best[2] and _robust(d, base, part, approach + arc[:max(n, 0)], q_robot):
            best = (base, pitch, n, sols, along)
            if n == len(qs):
                return best
    log.info("%s: %s plan: %d free bases, %d checks, best %s reaches %d of %d", part.joint_path, mode,
             len(bases), checks, best[0], best[2], len(qs))
    if best[0] is None or best[2] < 0:
        raise ExpertFailure("no_base_pose", f"{part.joint_path}: no base pose of {checks} reaches the handle")
    return best


def plan_short_arc(d, part: ArticulatedPart, grid, q0: float, qs: list[float], mode: str = "grasp",
                   within=None, arcs=SHORT_ARCS):
    """A stage over the first steps of ``qs`` only (at most ``arcs`` [rad] from q0, the longest
    first): :func:`plan_stage` with the bases clear of the leaf's sweep over that arc alone, on
    ``grid`` (the room's grid, no sweep). A bottom-hinged leaf's full sweep (0.7 m out, 0.8 m wide,
    plus the base's radius) leaves free only bases 1.05-1.15 m from its handle, at the arm's reach;
    the nearer bases before it carry the first ~25 deg, after which the leaf is opened on from
    further off. Returns plan_stage's tuple (its n counts steps of ``qs``, a prefix of which was
    planned) or None where no arc gets 2 steps."""
    for arc in arcs:
        sub = [q for q in qs if abs(q - q0) <= arc + 1e-9]
        if len(sub) < 2:
            continue
        try:
            best = plan_stage(d, part, swept_grid(grid, part, min(q0, sub[-1]), max(q0, sub[-1])), q0, sub, mode,
                              within=within)
        except ExpertFailure:
            continue
        if best[2] >= 2:
            log.info("%s: short arc of %.2f rad from %.2f: base %s reaches %d of %d", part.joint_path, arc, q0,
                     tuple(round(v, 2) for v in best[0]), best[2], len(sub))
            return best
    return None
