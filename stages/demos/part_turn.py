"""Turning a vertically hinged leaf (door) with the base: the hand holds the handle (or presses
the front face) with the arm held, and the base moves as if rigidly attached to the leaf, on a
circle about the hinge axis while yawing at the leaf's rate. Robot and leaf then turn together, so
the hand stays on its grip and the leaf cannot sweep into the robot; one such turn replaces
several regrasp stages of the arm carrying the handle along its arc
(:func:`stages.demos.articulated._swing` uses it for the part of the arc over which the base's
footprint stays free on the room's grid, :func:`turn_limit`). Also the base-side shortcuts of a
stage: going on from where the base stands (:func:`plan_here`) and re-solving a plan from a base
stopped off its pose (:func:`resolve`). Closing, a turn the footprint stops short of closed goes
on as an arm push from where the base stands (:func:`push_on`).

``d`` is a :class:`~stages.demos.driver.Driver`; world frame, metres, radians.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from stages.demos.driver import ROBOT_RADIUS
from stages.demos.part_planning import is_free
from stages.demos.parts import ArticulatedPart, axis_angle

log = logging.getLogger(__name__)

TURN_RATE = 0.6       # leaf (and base) turn rate bound [rad/s]
TURN_ACCEL = 1.0      # its change [rad/s^2]
TURN_BASE_SPEED = 0.75  # base speed bound while turning [m/s]
TURN_HAND_SPEED = 0.45  # handle speed bound [m/s]
# closing (the closed hand pushes the front face): one rate bound over the whole arc [rad/s]. A
# pushed leaf cannot be braked: slowed down, the hand only falls behind while the leaf coasts on at
# its peak rate (catalog doors: hinge friction 0.3 N m, damping 1 N m s/rad) into its stop, off
# which it rebounds (the joint limit gives back ~85 % of the speed). At this rate the hand, braking
# only over the last ~4 deg, is still within ~1.5 deg of closed when the leaf hits its stop, and
# holds the rebound; a step down in the rate (halving it near closed) also outran the base's
# command limits, which stopped the turn as blocked and let the leaf slam free (issue 12).
TURN_CLOSE_RATE = 0.35
TURN_GAIN = 3.0       # base pose feedback gain [1/s]
TURN_LOST = 0.06      # stop when the base falls this far behind its pose [m] (blocked)
TURN_SLIP = 0.15      # ... or the leaf this far [rad] off the turn (grip lost)
TURN_CMD_ACCEL = 1.5  # the base command (vx, vy) changes at most this fast [m/s^2], stops included


def is_vertical(part: ArticulatedPart) -> bool:
    return part.kind == "revolute" and abs(float(np.asarray(part.axis)[2])) > 0.7


def turned(base, part: ArticulatedPart, dq: float) -> tuple[float, float, float]:
    """Base pose (x, y, yaw) ``base`` carried rigidly with the leaf turning by ``dq`` [rad]."""
    o = np.asarray(part.origin, float)
    p = o + axis_angle(np.asarray(part.axis, float), dq) @ (np.array([base[0], base[1], o[2]]) - o)
    yaw = float(base[2]) + dq * math.copysign(1.0, float(part.axis[2]))
    return float(p[0]), float(p[1]), (yaw + math.pi) % (2 * math.pi) - math.pi


def turn_limit(part: ArticulatedPart, d, grid, q_from: float, q_to: float, step: float = math.radians(2.0),
               base=None, blocked=None) -> float:
    """The joint value, from ``q_from`` towards ``q_to``, up to which the base turned with the
    leaf from where it stands (or from ``base`` (x, y, yaw)) keeps its footprint (ROBOT_RADIUS)
    free on ``grid`` (``blocked``: its inflation, where the caller has it)."""
    from stages.demos.record import base_pose

    base = base_pose(d.sim) if base is None else base
    blocked = grid.inflate(ROBOT_RADIUS) if blocked is None else blocked
    sgn = math.copysign(1.0, q_to - q_from)
    last = q_from
    for dq in np.arange(step, abs(q_to - q_from) + step, step):
        q = q_from + sgn * min(float(dq), abs(q_to - q_from))
        x, y, _ = turned(base, part, q - q_from)
        if not is_free(grid, blocked, x, y):
            break
        last = q
    return last


def turn_about_hinge(part: ArticulatedPart, d, q_from: float, q_to: float) -> float:
    """Turn the base (arm held, hand on the leaf) with the leaf from joint value ``q_from`` to
    ``q_to`` about the hinge: the leaf angle follows a trapezoidal profile (TURN_RATE,
    TURN_ACCEL; bounded by the base's and the handle's speed; by TURN_CLOSE_RATE when closing),
    the base tracks the pose it carries by feedforward plus feedback. Stops early when the base is
    blocked or the leaf slips. Returns (the leaf's joint value then, the one the hand carried to)."""
    from stages.demos.record import base_pose

    start = tuple(float(v) for v in base_pose(d.sim))
    o = np.asarray(part.origin, float)
    r_base = math.hypot(start[0] - o[0], start[1] - o[1])
    h = np.asarray(part.handle, float) - o
    r_hand = float(np.linalg.norm(h - np.dot(h, part.axis) * np.asarray(part.axis)))
    closing = q_to < q_from
    w_max = min(TURN_CLOSE_RATE if closing else TURN_RATE, TURN_BASE_SPEED / max(r_base, 1e-3),
                TURN_HAND_SPEED / max(r_hand, 1e-3))
    sgn = math.copysign(1.0, q_to - q_from)
    az = math.copysign(1.0, float(part.axis[2]))
    total = abs(q_to - q_from)
    dt = d.frame_dt
    d.cmd.mode = 1
    done, w = 0.0, 0.0
    cmd = np.zeros(2)  # the last base command (vx, vy) [m/s]
    log.info("%s: turning with the base from %.2f to %.2f (base radius %.2f m, %.2f rad/s)", part.joint_path,
             q_from, q_to, r_base, w_max)
    while done < total - 1e-6:
        w = min(w_max, w + TURN_ACCEL * dt, math.sqrt(2.0 * TURN_ACCEL * max(total - done, 0.0)))
        w = max(w, 0.02)
        done = min(total, done + w * dt)
        tx, ty, tyaw = turned(start, part, sgn * done)
        x, y, yaw = base_pose(d.sim)
        err = math.hypot(tx - x, ty - y)
        q_now = d.sim.joint_q_of_path(part.joint_path)
        log.debug("turn t %.2f plan %.3f leaf %.3f base err %.3f w %.3f", d.sim.time, q_from + sgn * done,
                  q_now, err, w)
        if err > TURN_LOST or abs(q_now - (q_from + sgn * done)) > TURN_SLIP:
            log.info("%s: turn stopped at %.2f (base %.3f m off, leaf at %.2f)", part.joint_path,
                     q_from + sgn * done, err, q_now)
            break
        wz = sgn * w * az  # world yaw rate [rad/s]
        vwx = -wz * (ty - o[1]) + TURN_GAIN * (tx - x)
        vwy = wz * (tx - o[0]) + TURN_GAIN * (ty - y)
        wyaw = wz + TURN_GAIN * ((tyaw - yaw + math.pi) % (2 * math.pi) - math.pi)
        c, s = math.cos(yaw), math.sin(yaw)
        cmd = _limited(cmd, np.array([c * vwx + s * vwy, -s * vwx + c * vwy]), TURN_CMD_ACCEL * dt)
        d.base((float(cmd[0]), float(cmd[1]), wyaw))
        d.step(dt)
    while np.linalg.norm(cmd) > 1e-6:  # brake to a stop (a blocked or slipping turn ends at speed)
        cmd = _limited(cmd, np.zeros(2), TURN_CMD_ACCEL * dt)
        d.base((float(cmd[0]), float(cmd[1]), 0.0))
        d.step(dt)
    d.base((0.0, 0.0, 0.0))
    d.step(0.1)
    return d.sim.joint_q_of_path(part.joint_path), q_from + sgn * done


def push_on(part: ArticulatedPart, d, q_start: float, q_hand: float, goal: float, arc_sols, pitch: float,
            along: float, track, tol: float) -> float:
    """After a closing turn that the footprint stopped short of ``goal`` with the hand at joint
    value ``q_hand`` (the turn began at ``q_start``): the arm pushes on along the arc, base held,
    instead of a new stage. The base turned rigidly with the leaf, the arm held, so relative to the
    base the k-th 6-deg step from here is the k-th planned step from ``q_start``, whose arm solution
    (``arc_sols``) seeds the solve (``track``: :func:`stages.demos.articulated.track`, ``tol`` [m]).
    The hand moves at TURN_CLOSE_RATE. Returns the joint value the hand reached."""
    from stages.demos.part_grasps import gesture

    step = math.copysign(math.radians(6.0), goal - q_hand)
    qs = [float(v) for v in np.arange(q_hand + step, goal, step)] + [goal]
    _, arc = gesture(part, q_hand, qs, pitch, "push", along)
    seeds = [arc_sols[min(k, len(arc_sols) - 1)] for k in range(len(qs))]
    durs = [max(d.pace.min_wait, abs(b - a) / TURN_CLOSE_RATE)
            for a, b in zip([q_hand, *qs[:-1]], qs, strict=True)]
    k = track(d, arc, seeds, durs, tol=tol)
    log.info("%s: pushed on with the arm from %.2f to %.2f (%d/%d steps)", part.joint_path, q_hand,
             qs[k - 1] if k else q_hand, k, len(qs))
    return qs[k - 1] if k else q_hand


def _limited(v: np.ndarray, want: np.ndarray, step: float) -> np.ndarray:
    """``want`` reached from ``v`` by a change of at most ``step`` (norm)."""
    dv = want - v
    n = float(np.linalg.norm(dv))
    return want if n <= step else v + dv * (step / n)


def resolve(d, targets, seeds, tol: float = 0.004) -> list[np.ndarray]:
    """Arm solutions (7,) for the leading ``targets`` (4x4 world poses) that CLIK reaches from the
    base where it stands, each seeded by the planned solution of ``seeds`` (the plan's branch)."""
    from stages.simulate.control import Clik

    out = []
    for t, seed in zip(targets, seeds, strict=False):
        res = d.ik.solve(Clik.world_to_root(d.sim.spawn, t), d.ik.with_arm(d.ik.from_sim(d.sim), seed), max_iters=300)
        if res.position_error > tol or res.rotation_error > math.radians(2.0):
            break
        out.append(d.ik.arm_q(res.q))
    return out


def plan_here(d, part: ArticulatedPart, grid, q0: float, qs: list[float], mode: str, goal: float):
    """(base, pitch, n, arm solutions, along) as :func:`stages.demos.part_planning.plan_stage`
    returns, for the base where it stands, when from there the approach at ``q0`` and every
    waypoint of ``qs`` are reachable (a vertically hinged leaf: the approach, and the turn with the
    base reaches ``goal``); else None (the stage drives to a planned base)."""
    from stages.demos.part_grasps import door_pitch, drawer_pitch, gesture, grips
    from stages.demos.part_planning import reach
    from stages.demos.record import base_pose

    base = tuple(float(v) for v in base_pose(d.sim))
    vertical = is_vertical(part)
    z = float(part.handle_at(q0)[2])
    p0 = door_pitch(z) if vertical else drawer_pitch(z)
    turns = vertical and abs(turn_limit(part, d, grid, q0, goal) - goal) < math.radians(3.0)
    for pitch, along in grips(part, base, p0, vertical, edge=mode == "edge", push=mode == "push"):
        approach, arc = gesture(part, q0, qs, pitch, mode, along)
        sols = reach(d, base, approach + (arc[:1] if turns else arc))
        n = len(sols) - len(approach)
        if n == len(qs) or (turns and n >= 0):
            log.info("%s: going on from the base where it stands (%d/%d arc steps)", part.joint_path,
                     max(n, 0), len(qs))
            return base, pitch, n, sols, along
    return None


def plan_turn(d, part: ArticulatedPart, grid, q0: float, qs: list[float], mode: str, goal: float,
              max_checks: int = 24, min_turn: float = math.radians(10.0)):
    """(base, pitch, n, arm solutions, along) as :func:`stages.demos.part_planning.plan_stage`
    returns, for a vertically hinged leaf at ``q0`` whose arc the arm alone cannot carry (a
    half-open fridge door between its hinge and a counter): the base pose on the handle's rings
    (:func:`~stages.demos.part_planning._swing_bases`, clear of the leaf where it stands, not of the
    arc it sweeps) from which the base turned with the leaf keeps its footprint free on ``grid``
    furthest towards ``goal`` (at least ``min_turn`` [rad]) and the approach onto the handle (or
    face) at ``q0`` is reachable, also with the base stopped 2 cm off; None when there is none (the
    stage's arm plan stands)."""
    from stages.demos.part_grasps import door_pitch, gesture, grips
    from stages.demos.part_planning import _robust, _swing_bases, connected, reach, swept_grid
    from stages.demos.record import base_pose

    here = swept_grid(grid, part, q0, q0)
    blocked = grid.inflate(ROBOT_RADIUS)
    ranked = []
    for k, b in enumerate(_swing_bases(part, here, q0, qs, within=connected(here, base_pose(d.sim)[:2]))):
        lim = turn_limit(part, d, grid, q0, goal, base=b, blocked=blocked)
        if abs(lim - q0) >= min_turn:
            ranked.append((-round(abs(lim - q0) / math.radians(6.0)), k, b))
    ranked.sort()
    p0 = door_pitch(float(part.handle_at(q0)[2]))
    for _, _, b in ranked[:max_checks]:
        for pitch, along in grips(part, b, p0, True, push=mode == "push"):
            approach, arc = gesture(part, q0, qs, pitch, mode, along)
            sols = reach(d, b, approach + arc[:1])
            if len(sols) >= len(approach) and _robust(d, b, part, approach):
                log.info("%s: turn plan from %.2f: base %s turns the leaf to %.2f", part.joint_path, q0,
                         tuple(round(v, 2) for v in b), turn_limit(part, d, grid, q0, goal, base=b, blocked=blocked))
                return b, pitch, len(sols) - len(approach), sols, along
    return None



def plan_stage_or_turn(d, part: ArticulatedPart, plan, grid, q0: float, qs: list[float], mode: str, goal: float,
                       done, stage: int):
    """A stage's plan: :func:`stages.demos.part_planning.plan_stage` on ``plan`` (the room's grid
    with the arc swept), or, where that reaches fewer than 2 arc steps short of ``done`` (a
    predicate on joint values) on a vertically hinged leaf, :func:`plan_turn` on ``grid``, on a
    bottom-hinged one by its handle :func:`~stages.demos.part_planning.plan_short_arc`;
    ExpertFailure("no_base_pose") when none has one."""
    from stages.demos.driver import ExpertFailure
    from stages.demos.part_planning import connected, plan_short_arc, plan_stage, swept_grid
    from stages.demos.record import base_pose

    turns = is_vertical(part) and mode in ("grasp", "push")
    # a bottom-hinged (oven) leaf by its handle: where its full sweep keeps the base out of the
    # arm's reach, a shorter arc from nearer (part_planning.plan_short_arc)
    short = mode == "grasp" and part.kind == "revolute" and not is_vertical(part)
    # only bases the planner reaches from where the base stands (the leaf where it is now)
    within = connected(swept_grid(grid, part, q0, q0), base_pose(d.sim)[:2])
    try:
        best = plan_stage(d, part, plan, q0, qs, mode, within=within)
    except ExpertFailure as e:
        if not (turns or short) or e.reason != "no_base_pose":
            raise
        best, err = None, e
    if best is not None and (best[2] >= 2 or done(qs[max(best[2] - 1, 0)])):
        return best
    nearer = plan_short_arc(d, part, grid, q0, qs, mode, within=within) if short else None
    if nearer is not None:
        return nearer
    turn = plan_turn(d, part, grid, q0, qs, mode, goal) if turns else None
    if turn is not None:
        return turn
    if best is None:
        raise err
    raise ExpertFailure("no_base_pose", f"{part.joint_path}: stage {stage} reaches {best[2]} arc steps from {q0:.2f}")
