"""Generic open/close experts for the doors and drawers of :mod:`stages.demos.parts`.

Public surface (signatures are stable; the task world imports them)::

    open_part(part, d, grid, goal_fraction=0.9)      # d: stages.demos.driver.Driver; grid: NavGrid
    close_part(part, d, grid, start=q0)              # q0: the part's joint value at the start

Where the hand goes on a part is :mod:`stages.demos.part_grasps`; where the base stands and which
arm solutions reach is :mod:`stages.demos.part_planning`; this module runs the phases (drive, take
hold, carry, let go, back off) on the simulation.

Experts (the robot drives with ``Driver.drive_to`` over ``grid``, the room with its parts closed;
the experts add the part's swept area themselves):

- drawers: base in front of the bar (pose checked by IK), grasp, the base backs away (or drives
  in) along the drawer axis with the arm held, release, tuck;
- doors (vertical hinge: fridge, microwave, cabinet, room door; bottom hinge: oven): in stages,
  each from the base pose (searched on rings round the handle, checked by CLIK) that reaches the
  longest part of the remaining arc; the arm follows the planned IK branch (no random restarts
  mid-motion); opening holds the handle, closing a vertical door pushes its front face with the
  closed hand. A vertically hinged leaf is turned by the base instead of the arm where the base's
  footprint stays free turning with it about the hinge (:mod:`stages.demos.part_turn`): one
  stage usually does a fridge or room door. After each stage the hand backs off with base
  motions (round the free edge of an opened leaf) and, unless the part is done, tucks; a later
  stage goes on from where the base stands when the rest is reachable from there.
  A bottom-hinged (oven) door opened past 20 deg lies with its handle under the leaf: closing
  first lifts it by pinching its free edge from beside the leaf (the base drives towards the
  front while holding when the arm runs out of reach) to below ~15 deg, where its counterbalanced
  hinge holds it, then presses it shut with the closed hand.

They raise :class:`~stages.demos.driver.ExpertFailure` ("no_base_pose", "ik_unreachable",
"not_reached", "handle_faces_floor", and the Driver's "no_path", "drive_timeout").
"""

from __future__ import annotations

import logging
import math

import numpy as np

from stages.demos.driver import APPROACH_TOL, ROBOT_RADIUS, ExpertFailure, stow
from stages.demos.part_grasps import GRASP_BACK, PUSH_STANDOFF, drawer_pitch, edge_point, gesture, handle_pose
from stages.demos.part_grasps import heading, lateral
from stages.demos.part_checks import _check_grasp
from stages.demos.part_planning import STANCE_JITTER, STANCE_YAW_JITTER, choose_base, is_free, reach, swept_grid
from stages.demos.part_turn import is_vertical, plan_here, plan_stage_or_turn, push_on, resolve, turn_about_hinge
from stages.demos.part_turn import turn_limit
from stages.demos.parts import ArticulatedPart

log = logging.getLogger(__name__)

# --------------------------------------------------------------------------------------------
# Experts
# --------------------------------------------------------------------------------------------

# a push ends this far [rad] past closed (negative: short of it; a heavy leaf pressed onto its stop rebounds)
PUSH_OVERSHOOT = -0.01
DRIVE_SLACK = 0.04   # a base stopped this close to its goal [m] counts as arrived
CARRY_SPEED = 0.3    # hand speed carrying a handle or pushing a leaf along its arc [m/s]
CARRY_TURN = 0.7     # hand (and leaf) turn rate while carrying it [rad/s]
SHIFT_SPEED = 0.5   # base speed of short straight shifts with the arm held [m/s]
SHIFT_ACCEL = 1.2    # base acceleration of those shifts and of drawer slides [m/s^2]
SWING_TOL = 0.008   # CLIK position tolerance of waypoints along a door's arc [m]
EDGE_LIFT_ABOVE = math.radians(22.0)  # close a bottom-hinged door opened further by lifting its edge first
EDGE_LIFT_TO = math.radians(4.5)      # ... towards here (it stays put below ~30 deg), then by the closed hand
EDGE_HOLD = math.radians(20.0)       # the lift ends once the leaf stays below this
EDGE_DONE = math.radians(4.0)        # a lifted bottom-hinged leaf this near closed counts as shut (tasks: 5 deg)
INNER_FROM = 0.3  # a vertically hinged leaf opened this far [fraction of travel] may be pushed on by its inner face
ESCAPE_MARGIN = 0.1  # an escape from a blocked spot goes this far into the free region where it can [m]


def _slide(d, distance: float, speed: float = 0.3, along: float | None = None) -> None:
    """Base straight by ``distance`` [m] (negative: backwards) along the world direction ``along``
    [rad] (None: its heading) without turning, arm held; closed on the measured displacement
    (velocity commands alone fall a few centimetres short)."""
    from stages.demos.record import base_pose

    x0, y0, yaw0 = base_pose(d.sim)
    along = yaw0 if along is None else along
    u = np.array([math.cos(along), math.sin(along)]) * math.copysign(1.0, distance)
    cu, su = math.cos(along - yaw0), math.sin(along - yaw0)  # the direction in the base frame
    d.cmd.mode = 1
    t_end = d.sim.time + abs(distance) / speed * 2.0 + 1.0
    v_prev = 0.0
    while d.sim.time < t_end:
        x, y, _ = base_pose(d.sim)
        left = abs(distance) - float(np.dot([x - x0, y - y0], u))
        if left <= 0.002:
            break
        v = min(speed, max(0.03, 3.0 * left), v_prev + SHIFT_ACCEL * d.frame_dt)
        v_prev = v
        sv = math.copysign(v, distance)
        d.base((sv * cu, sv * su, 0.0))
        d.step(d.frame_dt)
    d.base((0.0, 0.0, 0.0))
    d.step(0.2)


def _drawer(part: ArticulatedPart, d, grid, q0: float, q1: float) -> None:
    """Grasp the drawer's bar at opening q0, move the base along the drawer axis to q1, release, tuck."""
    out = q0 - part.closed

    def targets(base, pitch):
        # the arm holds its pose in the base frame while the base slides: only the grasp matters
        return [handle_pose(part, q0, pitch, GRASP_BACK), handle_pose(part, q0, pitch)]

    p0 = drawer_pitch(float(part.handle[2]))
    jn, jl = d.rng.uniform(-1.0, 1.0, 2) * STANCE_JITTER  # a varied stance first (part_planning)
    jyaw = d.rng.uniform(-1.0, 1.0) * STANCE_YAW_JITTER
    cands = [(0.72 + jn + out, jl, jyaw, p0)] + [
        (dn + out, dl, 0.0, p0 + dp) for dp in (0.0, math.radians(-10), math.radians(15))
        for dn in (0.72, 0.66, 0.78, 0.60, 0.84) for dl in (0.0, 0.05, -0.05, 0.1, -0.1)]
    base, pitch = choose_base(d, part, grid, cands, targets)
    _drive(d, base, grid)
    closing, along = q1 < q0, heading(-np.asarray(part.front, float))  # slides along the drawer axis
    # closing pushes the bar with the closed hand (the approaching fingers would nudge an open
    # drawer in and miss the grasp); opening grasps it
    d.grip(1.0 if closing else 0.0, 0.3)
    d.move(handle_pose(part, q0, pitch, GRASP_BACK), 1.5, segments=3, settle=0.1, tol=APPROACH_TOL)
    if closing:
        d.move(handle_pose(part, q0, pitch, PUSH_STANDOFF), 1.0, segments=2, settle=0.2)
        q_now = d.sim.joint_q_of_path(part.joint_path)
        _slide(d, (q_now - q1) + PUSH_STANDOFF + 0.008, speed=0.25, along=along)
        _slide(d, -0.03, speed=0.05, along=along)  # straight off the bar before the diagonal retreat drags it
    else:
        with d.steady():  # no DART noise from the last approach to the grip: the fingers close on the bar
            d.move(handle_pose(part, q0, pitch, 0.0), 1.0, segments=2, settle=0.5)
            d.grip(1.0, 0.6)
            d.step(0.1)  # the grip held still before the pull
        _check_grasp(part, d)
        _slide(d, q0 - q1, along=along)
    log.debug("%s: slid to %.3f (goal %.3f)", part.joint_path, d.sim.joint_q_of_path(part.joint_path), q1)
    _retreat_from_leaf(part, d, q1, grid, push=closing)
    d.home(1.0)


def _carry_times(d, start: np.ndarray, poses, slow) -> list[float]:
    """Durations [s] of hand steps from 4x4 ``start`` through ``poses`` carrying a part: at most
    CARRY_SPEED [m/s] and CARRY_TURN [rad/s] of hand rotation, half that where ``slow[k]``."""
    out, prev = [], np.asarray(start, float)
    for t, s_ in zip(poses, slow, strict=True):
        dist = float(np.linalg.norm(t[:3, 3] - prev[:3, 3]))
        cos = (np.trace(prev[:3, :3].T @ t[:3, :3]) - 1.0) / 2.0
        turn = float(np.arccos(np.clip(cos, -1.0, 1.0)))
        out.append(max(d.pace.min_wait, dist / CARRY_SPEED, turn / CARRY_TURN) * (2.0 if s_ else 1.0))
        prev = t
    return out


def track(d, targets, seeds, durations, *, tol: float, fallback: bool = False) -> int:
    """Follow world poses ``targets`` with the arm: each is solved by CLIK from the robot's actual
    state with the arm seeded by the planned solution in ``seeds`` (so execution stays on the
    planned branch), and the joint targets move linearly there in ``durations`` [s] (with
    ``fallback``, free-space moves, at most: by the Driver's pace), longer where an arm joint
    would move faster than the pace allows; with
    ``fallback`` a miss is solved again from the arm's state with restarts.
    Returns how many were reached; stops at the first one CLIK misses by more than ``tol`` [m] or
    3 deg."""
    from stages.simulate.control import Clik

    d.cmd.mode = 1
    d.base((0.0, 0.0, 0.0))
    for k, (t, seed, dur) in enumerate(zip(targets, seeds, durations, strict=False)):
        q0 = d.ik.with_arm(d.ik.from_sim(d.sim), seed)
        goal = Clik.world_to_root(d.sim.spawn, t)
        res = d.ik.solve(goal, q0, max_iters=300)
        if fallback and (res.position_error > tol or res.rotation_error > math.radians(3.0)):
            # free-space waypoints may leave the planned branch: solve again from the arm's state
            q1 = d.ik.with_arm(d.ik.from_sim(d.sim), d.ctl.arm_targets())
            res = d.ik.solve(goal, q1, max_iters=300, restarts=8, rng=np.random.default_rng(k))
        if res.position_error > tol or res.rotation_error > math.radians(3.0):
            log.info("track: waypoint %d unreachable (%.4f m, %.3f rad; seed %s, got %s)", k,
                     res.position_error,
                     res.rotation_error, np.round(seed, 2), np.round(d.ik.arm_q(res.q), 2))
            return k
        if fallback:
            dur = d.move_time(t, dur, APPROACH_TOL)
        a0, a1 = d.ctl.arm_targets(), d.ik.arm_q(res.q)
        dur = max(dur, float(np.abs(a1 - a0).max()) / d.pace.max_joint_speed)
        n = max(1, int(round(dur / d.frame_dt)))
        for i in range(1, n + 1):
            d.ctl.set_arm_targets(a0 + (a1 - a0) * i / n)
            d.step(d.frame_dt)
    return len(targets)


def _swing(part: ArticulatedPart, d, grid, q0: float, q1: float, step_deg: float = 6.0, max_stages: int = 5,
           mode: str = "grasp", done_at: float | None = None) -> None:
    """Carry the part from q0 to q1 along its arc in ``step_deg`` steps, holding the handle (or,
    ``mode="push"``, pressing the front face with the closed hand). Each stage drives to the base pose
    that reaches the longest part of the remaining arc, takes hold, swings, lets go and backs
    off; the part stays where it was left (damped joint) and the next stage starts from there.
    ``mode="edge"``: pinch a bottom-hinged door's free edge instead of its handle. ``done_at``:
    the joint value that ends it (default: 80 % of the travel opening, 2.5 deg from closed closing)."""
    opening = q1 > q0
    push, edge = mode == "push", mode == "edge"
    fist = push or mode == "inner"  # the closed hand presses the leaf (inner: its inner face, opening it)
    if done_at is None:
        done_at = (part.closed + 0.8 * part.travel) if opening else (part.closed + math.radians(2.5))

    def done(q):
        return q >= done_at if opening else q <= done_at

    q = d.sim.joint_q_of_path(part.joint_path)  # a free leaf may have moved since q0 was set
    for stage in range(max_stages):
        if done(q) and stage > 0:
            # a leaf knocked since (tucking arm, base) may still move (off its stop): done only at rest
            _settle_part(part, d)
            q = d.sim.joint_q_of_path(part.joint_path)
            log.info("%s: at rest at %.3f before stage %d", part.joint_path, q, stage)
        if done(q):  # a free leaf may have moved on by itself (an oven door past its hold drops open)
            return
        step = math.copysign(math.radians(step_deg), q1 - q)
        qs = arc_steps(q, q1, step, then=part.closed - PUSH_OVERSHOOT if push else None)
        plan = swept_grid(grid, part, min(q, q1), max(q, q1))
        # a later stage (or a chained expert) first tries to go on from where the base stands
        stay = plan_here(d, part, grid, q, qs, mode, goal=part.closed - PUSH_OVERSHOOT if push else q1) \
            if stage > 0 or not _at_home(d) else None
        base, pitch, n, sols, along = stay or plan_stage_or_turn(
            d, part, plan, grid, q, qs, mode, part.closed - PUSH_OVERSHOOT if push else q1, done, stage)
        log.info("%s: stage %d from %.2f, base %s pitch %.2f, %d/%d steps", part.joint_path, stage, q,
                 tuple(round(v, 2) for v in base), pitch, n, len(qs))
        here = swept_grid(grid, part, q, q)
        # at the start the arm tucks while the base sets off, unless it must escape a blocked spot first
        tuck = _stow(d, on_the_way=_free_here(d, here)) if stage == 0 else None
        try:
            if not stay:
                _escape(d, here)
                _drive(d, base, here, tuck=tuck)
        except ExpertFailure as e:
            if e.reason != "drive_timeout" or stage == max_stages - 1:
                raise
            # blocked short of the goal (a chassis corner on the leaf): plan again from here
            log.info("%s: %s; planning again", part.joint_path, e)
            d.base((0.0, 0.0, 0.0))
            q = d.sim.joint_q_of_path(part.joint_path)
            continue
        q_now = d.sim.joint_q_of_path(part.joint_path)
        if abs(q_now - q) > math.radians(2.0) and stage < max_stages - 1:
            log.info("%s: the part moved from %.3f to %.3f during the drive; planning again", part.joint_path,
                     q, q_now)
            q = q_now
            continue
        approach, arc = gesture(part, q, qs, pitch, mode, along)
        na = len(approach)
        from stages.demos.record import base_pose

        actual = tuple(float(v) for v in base_pose(d.sim))
        if math.hypot(actual[0] - base[0], actual[1] - base[1]) > 0.005:
            # the drive stopped off the planned pose: re-solve the plan from where the base stands
            sols2 = reach(d, actual, approach + arc[:max(n, 0)])
            if len(sols2) < na + min(n, 2):  # CLIK seeded by the plan's solutions often still reaches
                sols2 = max(sols2, resolve(d, approach + arc[:max(n, 0)], sols), key=len)
            if len(sols2) < na + min(n, 2) and stage < max_stages - 1:
                log.info("%s: plan lost from the base reached (%d of %d); planning again", part.joint_path,
                         len(sols2), na + n)
                _stow(d)
                q = d.sim.joint_q_of_path(part.joint_path)
                continue
            if len(sols2) >= na:
                sols, n = sols2, len(sols2) - na
        d.grip(1.0 if fist else 0.0, 0.4)
        # free-space approach waypoints by the Driver's pace, the last (onto the part) at CARRY_SPEED
        durs = [1.5] + [0.6] * (na - 2) + _carry_times(d, approach[-2], approach[-1:], [False])
        log.debug("%s: base at %s (planned %s)", part.joint_path, np.round(base_pose(d.sim), 3),
                  np.round(base, 3))
        if track(d, approach[:-1], sols[:na - 1], durs, tol=SWING_TOL, fallback=True) < na - 1 or \
                track(d, approach[-1:], sols[na - 1:na], durs[-1:], tol=SWING_TOL) < 1:
            if stage == max_stages - 1:
                raise ExpertFailure("ik_unreachable", f"{part.joint_path}: approach at {q:.2f}")
            # the base stopped off its planned pose: tuck and plan again from where it stands
            log.info("%s: approach at %.2f unreachable from the base reached; planning again", part.joint_path, q)
            _stow(d)
            q = d.sim.joint_q_of_path(part.joint_path)
            continue
        d.settle(0.2)
        k = 0
        if not fist:
            d.grip(1.0, 0.6)
            try:
                _check_grasp(part, d, along=along,
                             point=edge_point(part, along) if edge else None)
            except ExpertFailure as e:
                # a free leaf nudged by the fingers: let go, back off and plan again from where it is
                if stage == max_stages - 1:
                    raise
                log.info("%s: %s; regrasping", part.joint_path, e)
                n = -1
        turn_to = None
        if n >= 0 and is_vertical(part):
            # turning with the base reaches further than the arm along the arc: do that instead
            goal = part.closed - PUSH_OVERSHOOT if push else q1
            q_turn = turn_limit(part, d, grid, q, goal)
            if abs(q_turn - q) > abs((qs[n - 1] if n > 0 else q) - q) + math.radians(5.0):
                turn_to = q_turn
        if turn_to is not None:
            turned, hand = turn_about_hinge(part, d, q, turn_to)
            if push and n > 0 and not done(hand):  # stopped short by the footprint: the arm pushes on
                push_on(part, d, q, hand, goal, sols[na:na + n], pitch, along, track, SWING_TOL)
        elif n >= 0:
            # slow near closed: a heavy leaf driven into its stop rebounds
            durs = _carry_times(d, approach[-1], arc[:n], [abs(qw - part.closed) < math.radians(20.0)
                                                           and not opening for qw in qs[:n]])
            k = track(d, arc[:n], sols[na:na + n], durs, tol=SWING_TOL)
            # pinching an edge: the leaf slides between the fingers, push again while it is short
            # (closing: on towards q1 even once done, sparing the closed hand's push stage)
            for _ in range(2 if edge else 0):
                q_e = d.sim.joint_q_of_path(part.joint_path)
                if done(q_e) and (opening or q_e - q1 < math.radians(1.0)):
                    break
                _edge_push(part, d, grid, q1 if opening else q1 - math.radians(1.5))
        d.settle(0.4)
        last = turned if turn_to is not None else qs[k - 1] if k else q
        log.debug("%s: swing to %.3f -> %.3f", part.joint_path, last, d.sim.joint_q_of_path(part.joint_path))
        _retreat_from_leaf(part, d, last, grid, push=fist, edge=edge)
        log.debug("%s: retreat -> %.3f", part.joint_path, d.sim.joint_q_of_path(part.joint_path))
        _settle_part(part, d)
        q = d.sim.joint_q_of_path(part.joint_path)
        log.info("%s: stage %d ends at %.3f (goal %.3f)", part.joint_path, stage, q, q1)
        if done(q):
            return  # the hand stays backed off the leaf (a following stage or expert tucks first)
        _stow(d)
    raise ExpertFailure("not_reached",
                        f"{part.joint_path}: at {q:.2f} after {max_stages} stages (goal {q1:.2f})")


def _edge_push(part: ArticulatedPart, d, grid, q1: float, speed: float = 0.08) -> None:
    """Holding a bottom-hinged leaf by its edge with the arm out of reach: carry it on towards q1
    by moving the base (arm held) towards the asset's front by the edge's remaining horizontal
    travel, as far as the room allows (the leaf slides radially between the fingers)."""
    from stages.demos.record import base_pose

    q = d.sim.joint_q_of_path(part.joint_path)
    e = edge_point(part)
    a = np.asarray(part.axis, float)
    v = e - np.asarray(part.origin, float)
    r = float(np.linalg.norm(v - np.dot(v, a) * a))
    n = np.asarray(part.front, float)[:2]
    n = n / max(np.linalg.norm(n), 1e-9)
    want = r * (math.sin(abs(q - part.closed)) - math.sin(abs(q1 - part.closed)))
    blocked = grid.inflate(ROBOT_RADIUS - 0.05)
    x, y, _ = base_pose(d.sim)
    dist = 0.0
    for s_ in np.arange(0.02, want + 1e-9, 0.02):
        if not is_free(grid, blocked, x - s_ * n[0], y - s_ * n[1]):
            break
        dist = float(s_)
    log.info("%s: edge at %.2f out of the arm's reach: base %.2f m of %.2f towards the front", part.joint_path,
             q, dist, want)
    if dist > 0.0:
        _base_shift(d, -dist * np.array([n[0], n[1], 0.0]), speed=speed)


def _stow(d, on_the_way: bool = False) -> np.ndarray | None:
    """Tuck the hand above the base for driving (:func:`stages.demos.driver.stow`; home hangs the
    hand half a metre ahead, where it knocks a leaf the base drives past), home if that fails.
    ``on_the_way``: may return the tucked arm's joint targets for the drive instead."""
    try:
        return stow(d, on_the_way=on_the_way)
    except ExpertFailure as e:
        log.info("stow failed (%s); tucking home", e)
        d.home(1.0)
    return None


def _at_home(d) -> bool:
    """Whether the arm's joint targets are the tucked home configuration (an episode's start)."""
    return float(np.abs(d.ctl.arm_targets() - np.asarray(d.sim.desc.arm_home, float)).max()) < 0.05


def _free_here(d, grid) -> bool:
    """Whether the base stands where the planner counts it free on ``grid``."""
    from stages.demos.record import base_pose

    x, y, _ = base_pose(d.sim)
    return is_free(grid, grid.inflate(ROBOT_RADIUS), x, y)


def _escape(d, grid, reach: float = 0.5) -> None:
    """When the base stands where the planner counts it blocked (the leaf it just moved now lies
    near it), move it straight to the nearest free spot within ``reach`` [m] first."""
    from stages.demos.record import base_pose

    x, y, _ = base_pose(d.sim)
    best = escape_target(grid, x, y, reach)
    if best is None:
        return
    log.info("base at (%.2f, %.2f) is blocked for planning: moving to (%.2f, %.2f)", x, y, *best)
    _base_shift(d, np.array([best[0] - x, best[1] - y, 0.0]))


def escape_target(grid, x: float, y: float, reach: float = 0.5, margin: float = ESCAPE_MARGIN):
    """Where :func:`_escape` moves a base at (x, y) [m] that the planner counts blocked on ``grid``:
    None where it is free (or nothing is within ``reach`` [m]); else the nearest free point (5 cm
    rings, 15 deg apart) carried on up to ``margin`` [m] further the same way while that stays free
    (a base shift ends a few cm short: on the free region's edge it would still be blocked)."""
    blocked = grid.inflate(ROBOT_RADIUS)
    if is_free(grid, blocked, x, y):
        return None
    for r in np.arange(0.05, reach + 1e-9, 0.05):
        for a in np.radians(np.arange(0.0, 360.0, 15.0)):
            c, s_ = math.cos(a), math.sin(a)
            if is_free(grid, blocked, x + r * c, y + r * s_):
                extra = 0.0
                for e in np.arange(0.025, margin + 1e-9, 0.025):
                    if not is_free(grid, blocked, x + (r + e) * c, y + (r + e) * s_):
                        break
                    extra = float(e)
                return float(x + (r + extra) * c), float(y + (r + extra) * s_)
    return None


def _drive(d, base: tuple[float, float, float], grid, tuck=None) -> None:
    """``Driver.drive_to`` ``base`` (``tuck``: see there); a timeout with the base within
    DRIVE_SLACK of the goal (a chassis corner grazing furniture) is accepted: the arm plans are
    re-solved from the actual base pose."""
    from stages.demos.record import base_pose

    try:
        d.drive_to(base, grid, tuck=tuck)
    except ExpertFailure as e:
        x, y, yaw = base_pose(d.sim)
        off = math.hypot(x - base[0], y - base[1])
        dyaw = abs((yaw - base[2] + math.pi) % (2 * math.pi) - math.pi)
        if e.reason != "drive_timeout" or off > DRIVE_SLACK or dyaw > 0.05:
            raise
        d.base((0.0, 0.0, 0.0))
        log.info("base %.3f m / %.3f rad off its goal after the drive timeout; going on", off, dyaw)


def arc_steps(q: float, q1: float, step: float, then: float | None = None) -> list[float]:
    """The joint values [rad or m] a stage swings the part through from ``q`` towards ``q1``, ``step``
    apart (signed), ending within half a step of ``q1``, then ``then`` when given (a push's
    overshoot); never empty: ``[q1]`` where the part is within half a step of ``q1`` but short of
    its ``done_at`` (an empty list made the stage planner raise IndexError)."""
    qs = [float(v) for v in np.arange(q + step, q1 + 0.5 * step, step)]
    if then is not None:
        qs.append(float(then))
    return qs or [float(q1)]


def _settle_part(part: ArticulatedPart, d, max_seconds: float = 2.0, speed: float = 0.03) -> None:
    """Step until the part's joint moves slower than ``speed`` [rad/s or m/s] (a heavy leaf let go
    of keeps swinging), at most ``max_seconds``; at least 0.1 s."""
    d.step(0.1)
    qs_ = int(d.sim.model.joint_qd_start.numpy()[_joint_index(d, part)])
    t_end = d.sim.time + max_seconds
    while d.sim.time < t_end and abs(float(d.sim.state_0.joint_qd.numpy()[qs_])) > speed:
        d.step(0.1)


def _joint_index(d, part: ArticulatedPart) -> int:
    for j, p in d.sim.scene.joint_path.items():
        if p == part.joint_path:
            return int(j)
    raise KeyError(part.joint_path)


def _retreat_from_leaf(part: ArticulatedPart, d, q: float, grid, *, push: bool = False, edge: bool = False) -> None:
    """Release the handle and take the hand clear of the leaf with base motions (arm held): back
    along the approach axis, then, from a door opened past 30 %, out along the leaf past its free
    edge (an arm wrapped round an opened door's edge would sweep it shut when tucked) as far as
    the room allows (up to 0.35 m)."""
    from stages.demos.record import base_pose

    if not push:  # a pushing fist stays closed: opening fingers catch the handle
        d.grip(0.0, 0.5)
    w = _ee_world(d)
    if edge:  # fingers straddle the leaf's edge: draw the hand straight off it first (4 cm clear it)
        for dist in (0.10, 0.07, 0.04):
            off = w.copy()
            off[:3, 3] -= dist * w[:3, 2]
            try:
                _move(d, off, 1.0, segments=2, tol=0.01)
                break
            except ExpertFailure:
                w = _ee_world(d)
        w = _ee_world(d)
    _base_shift(d, -0.08 * w[:3, 2], speed=0.25)
    if part.kind == "revolute" and q - part.closed > 0.3 * part.travel:
        e = part.rotation_at(q) @ lateral(part)
        blocked = grid.inflate(ROBOT_RADIUS - 0.08)
        x, y, _ = base_pose(d.sim)
        dist = 0.0
        for s_ in np.arange(0.05, 0.351, 0.05):
            if not is_free(grid, blocked, x + s_ * e[0], y + s_ * e[1]):
                break
            dist = float(s_)
        _base_shift(d, dist * e)


def _base_shift(d, delta, speed: float = SHIFT_SPEED, accel: float = SHIFT_ACCEL) -> None:
    """Translate the base by the horizontal part of world vector ``delta`` [m] (heading kept):
    a trapezoidal speed profile, up to ``speed`` [m/s] at ``accel`` [m/s^2]."""
    from stages.demos.record import base_pose

    v = np.asarray(delta, float)[:2]
    dist = float(np.linalg.norm(v))
    if dist < 1e-3:
        return
    _, _, yaw = base_pose(d.sim)
    c, s = math.cos(yaw), math.sin(yaw)
    u = np.array([c * v[0] + s * v[1], -s * v[0] + c * v[1]]) / dist  # base frame
    peak = min(speed, math.sqrt(accel * dist))
    ramp = peak / accel
    total = dist / peak + ramp
    h = max(1, int(round(d.frame_dt / d.sim.settings.dt))) * d.sim.settings.dt  # one command's time [s]
    n = max(1, int(math.ceil(total / h)))
    # speeds sampled at the commands' midpoints, scaled so that they cover exactly ``dist``
    t = (np.arange(n) + 0.5) * total / n
    prof = np.minimum.reduce([np.full(n, peak), accel * t, accel * (total - t)])
    prof *= dist / (prof.sum() * h)
    d.cmd.mode = 1
    for vk in prof:  # a command lasts to the next frame step: speed scaled to its actual time
        d.base(tuple(float(vk * h / (d.step_count(h) * d.sim.settings.dt) * c) for c in (u[0], u[1], 0.0)))
        d.step(h)
    d.base((0.0, 0.0, 0.0))
    d.step(0.1)


def _move(d, target: np.ndarray, duration: float, *, segments: int = 1, settle: float = 0.0,
          tol: float = 0.005) -> None:
    """:meth:`Driver.move` without random IK restarts: a contact move must continue from the
    current arm configuration (a restart may flip the elbow and slam the part)."""
    from stages.simulate.control import move_ee

    d.cmd.mode = 1
    d.base((0.0, 0.0, 0.0))
    try:
        move_ee(d.sim, d.ctl, d.ik, target, duration, segments=segments, settle=settle, rng=None, tol=tol,
                max_joint_speed=d.pace.max_joint_speed)
    except RuntimeError as e:
        if "unreachable" in str(e):
            raise ExpertFailure("ik_unreachable", str(e)) from None
        raise


def _ee_world(d) -> np.ndarray:
    """4x4 world pose of the end-effector target (the arm joint targets' forward kinematics)."""
    from stages.simulate.control import Clik

    q = d.ik.with_arm(d.ik.from_sim(d.sim), d.ctl.arm_targets())
    return np.linalg.inv(Clik.world_to_root(d.sim.spawn, np.eye(4))) @ d.ik.fk(q)


def open_part(part: ArticulatedPart, d, grid, goal_fraction: float = 0.9) -> None:
    """Open ``part`` from closed to ``goal_fraction`` of its travel: drawers by backing the base
    away holding the bar, doors by carrying the handle along its arc. ``d``: a
    :class:`~stages.demos.driver.Driver`; ``grid``: the room's NavGrid with the part closed.
    Raises ExpertFailure."""
    q1 = part.closed + goal_fraction * part.travel
    if part.kind == "prismatic":
        _drawer(part, d, grid, part.closed, q1)
        return
    if abs(float(np.asarray(part.axis)[2])) > 0.7:
        try:
            _swing(part, d, grid, part.closed, q1)
        except ExpertFailure as e:  # the handle's arc runs out of floor: push the leaf's inner face on
            q = d.sim.joint_q_of_path(part.joint_path)
            if e.reason not in ("no_base_pose", "not_reached") or q - part.closed < INNER_FROM * part.travel:
                raise
            log.info("%s: by the handle: %s; pushing the inner face on", part.joint_path, e)
            _swing(part, d, grid, q, q1, mode="inner")
        return
    # a bottom-hinged (oven) door: by the handle while it faces the robot, then (a counterbalanced
    # leaf stays where it is let go of below ~30 deg) by its free edge until it drops open
    try:
        _swing(part, d, grid, part.closed, q1, max_stages=2)
    except ExpertFailure as e:
        if e.reason not in ("no_base_pose", "not_reached", "ik_unreachable"):
            raise
        log.info("%s: by the handle: %s; going on by the edge", part.joint_path, e)
    q = d.sim.joint_q_of_path(part.joint_path)
    if q < part.closed + 0.8 * part.travel:
        _swing(part, d, grid, q, q1, mode="edge")


def close_part(part: ArticulatedPart, d, grid, *, start: float) -> None:
    """Close ``part`` from joint value ``start`` (its opening at the episode start)."""
    if part.kind == "prismatic":
        _drawer(part, d, grid, start, part.closed)
        return
    vertical = abs(float(np.asarray(part.axis)[2])) > 0.7
    if vertical:
        _swing(part, d, grid, start, part.closed, mode="push")
        return
    _settle_part(part, d, max_seconds=3.0)  # an opened oven door drops onto its stop
    q = d.sim.joint_q_of_path(part.joint_path)
    if q - part.closed > EDGE_LIFT_ABOVE:
        # its handle hangs under the leaf: lift the leaf by its free edge to where it stays put
        _swing(part, d, grid, q, part.closed + EDGE_LIFT_TO, mode="edge",
               done_at=part.closed + EDGE_HOLD)
        q = d.sim.joint_q_of_path(part.joint_path)
    if part.front_at(q)[2] < -0.5:
        raise ExpertFailure("handle_faces_floor", f"{part.joint_path}: handle under the open leaf at {q:.2f}")
    # the last few degrees (unless the lift left it within EDGE_DONE): press the front face shut with the closed hand
    _swing(part, d, grid, q, part.closed, step_deg=3.0, mode="push", done_at=part.closed + EDGE_DONE)
