"""The arm's postures for the hang-on-rail skill (:mod:`stages.demos.skill_wardrobe`): the carry posture's
candidates and IK seeds, postures found by IK from several seeds (:func:`posture`, with the arm kept narrow
before the wardrobe: :func:`arm_width`), the held hanger's moves (:func:`joint_move`: CLIK without restarts,
else a ramp in joint space), and the hand's rotation in the hanger's frame with the hanger's roll in the
pinch partly taken up by the hanger (:func:`roll_limited`).

Frame: world, Z up, metres, radians; the Panda arm's 7 joints.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from stages.demos.driver import APPROACH_TOL, ExpertFailure

log = logging.getLogger(__name__)

LIFT_MARGIN = 0.08      # the lift's postures may come this near [rad] their joints' limits (the pinch on a 0.42 m
                        # bed stands with joint 4 at -150 deg)
ROLL_LIMIT = math.radians(10.0)  # the hand turns at most this far [rad] off square to set a hanger that rolled in
                                 # the pinch square before the wardrobe; the hanger keeps the rest of its roll


#: the carry pose's candidates: (hand ahead of the base centre, height) [m], the first with a posture wins
CARRY = ((0.40, 1.0), (0.45, 0.95), (0.35, 1.05), (0.50, 0.95))
#: seeds of the carry posture's IK (the wrist rolled ~90 deg, its last joint ~140 deg) [rad]
WRIST_SEEDS = tuple((j1, -0.3, 0.0, -2.0, 1.6, 0.7, 2.4) for j1 in (-0.5, 0.0, 0.5))
#: the posture before the wardrobe reaches at most this far [m] sideways, or a narrower one of more seeds is sought
#: (flat_038: the one solution, 0.22 m wide, met the wardrobe on the way in: the base stopped 10 cm short)
NARROW_MAX = 0.2
#: ... and its forearm at least this far [m] on the open side of the wardrobe's middle (:func:`posture`'s ``beside``)
BESIDE_CLEAR = 0.08
#: more seeds for the posture before the wardrobe (:func:`posture`'s ``narrow``) [rad]
NARROW_SEEDS = tuple((j1, j2, j3, -1.8, j5, 1.2, j7) for j1 in (-0.3, 0.3) for j2 in (-0.5, 0.2)
                     for j3 in (-0.6, 0.6) for j5 in (-1.5, 1.5) for j7 in (-0.8, 2.4))


def arm_width(d, q: np.ndarray) -> float:
    """How far [m] the arm of robot configuration ``q`` reaches sideways: the largest |y| of the elbow's and
    the wrist's links in the arm's mount frame."""
    mount = np.linalg.inv(d.ik.fk(q, "panda_link0"))
    return max(abs(float((mount @ d.ik.fk(q, f))[1, 3])) for f in ("panda_link4", "panda_link6"))


def posture(d, target: np.ndarray, margin: float = 0.25, narrow: bool = False, beside=None):
    """Arm joint targets (7,) [rad] for the hand at ``target`` (4x4, world) from the current targets and
    :data:`WRIST_SEEDS`: of the solutions within 3 mm and 2 deg whose joints all keep ``margin`` [rad]
    from their limits, the nearest the current targets (``narrow``: the one whose elbow and wrist stay
    nearest the base's centre line, :func:`arm_width`: with the elbow out sideways, the arm met the wardrobe's
    carcass on the way in and the base stopped 8-10 cm short, flat_026/038; ``beside``: (point (2,), normal (2,)
    unit) [m] (world): with ``narrow``, a posture whose forearm (:func:`forearm_off`) lies less than
    :data:`BESIDE_CLEAR` on the normal's side of the line through the point counts as not narrow: the forearm
    of a mirrored wrist branch, 2 cm from the wardrobe's middle, met the closed door: flat_018 s5); None if none."""
    from stages.simulate.control import Clik

    goal = Clik.world_to_root(d.sim.spawn, target)
    now = d.ctl.arm_targets()
    base_q = d.ik.from_sim(d.sim)
    idx = d.ik.v_idx[: len(now)]
    lo, hi = d.ik.lower[idx], d.ik.upper[idx]
    sols = []  # (joint distance from now, width, q)
    for k, seed in enumerate((now, *WRIST_SEEDS, *(NARROW_SEEDS if narrow else ()))):
        if narrow and k == 1 + len(WRIST_SEEDS) and sols and _fits(min(sols, key=lambda t: t[0])):
            break  # the nearest of the first seeds' solutions is narrow enough
        r = d.ik.solve(goal, d.ik.with_arm(base_q, np.asarray(seed, float)), max_iters=600)
        q = d.ik.arm_q(r.q)
        if r.position_error > 0.003 or r.rotation_error > math.radians(2.0):
            continue
        if float(np.min(np.minimum(q - lo, hi - q))) < margin:
            continue
        wide = arm_width(d, r.q) if narrow else 0.0
        if narrow and beside is not None and (off := forearm_off(d, r.q, *beside)) < BESIDE_CLEAR:
            wide = max(wide, NARROW_MAX + 1e-3 + BESIDE_CLEAR - off)
        sols.append((float(np.abs(q - now).max()), wide, q))
    if not sols:
        return None
    near = min(sols, key=lambda t: t[0])
    if not narrow or _fits(near):
        return near[2]
    ok = [t for t in sols if t[1] <= NARROW_MAX]
    log.debug("posture: nearest %.2f rad away, %.3f m wide; %d of %d narrow", near[0], near[1], len(ok), len(sols))
    return (min(ok, key=lambda t: t[0]) if ok else min(sols, key=lambda t: t[1]))[2]


def forearm_off(d, q: np.ndarray, point, normal) -> float:
    """How far [m] the forearm of robot configuration ``q`` (the links panda_link5 and panda_link6, world) lies
    on the side of the unit ``normal`` (2,) of the vertical plane through ``point`` (2,) [m]: the least of the two."""
    from stages.simulate.control import Clik

    to_world = np.linalg.inv(Clik.root_from_world(d.sim.spawn))
    return min(float(((to_world @ d.ik.fk(q, f))[:2, 3] - np.asarray(point, float)) @ np.asarray(normal, float))
               for f in ("panda_link5", "panda_link6"))


def _fits(sol) -> bool:
    """Whether a posture (joint distance [rad], width [m], q) is narrow enough as it is."""
    return sol[1] <= NARROW_MAX


def joint_move(d, target: np.ndarray, seconds: float, low: bool) -> None:
    """The held hanger's hand to ``target`` (4x4, world): on a ``low`` bed in joint space where
    :func:`posture` finds a posture (a linear ramp of the arm's joints over ``seconds`` [s]), else by
    CLIK: CLIK's waypoints after the pinch on a low bed (0.42 m, flat_037) jumped to another branch
    (joint 6 at 209 deg) and dropped the hanger; on a higher bed CLIK's way holds the hanger as the
    carry wants it (with the ramp, flat_023's hand was out of reach before the wardrobe), without CLIK's restarts:
    where it stalls, the ramp (a restart's branch jump, joint 1 swung 120 deg, rolled the hanger 115 deg about
    its neck in the pinch, its hook's tip then outward, out of reach: flat_014 s3)."""
    if not low:
        try:
            return d.move(target, seconds, segments=2, carry=True, tol=APPROACH_TOL, restarts=False)
        except ExpertFailure as e:
            if e.reason != "ik_unreachable":
                raise
    for margin in (0.25, LIFT_MARGIN):
        if (qa := posture(d, target, margin)) is not None:
            ramp(d, qa, seconds)
            return
    d.move(target, seconds, segments=2, carry=True, tol=APPROACH_TOL)


def ramp(d, q: np.ndarray, seconds: float) -> None:
    """Arm joint targets linearly to ``q`` (7,) [rad] in ``seconds`` [s] or slower (the pace's joint speed)."""
    q0 = d.ctl.arm_targets()
    n = max(len(d._arm_ramp(q)), int(seconds / d.frame_dt))
    for k in range(1, n + 1):
        d.ctl.set_arm_targets(q0 + (q - q0) * k / n)
        d.step(d.frame_dt)


def roll_limited(in_hanger: np.ndarray, limit: float = ROLL_LIMIT) -> np.ndarray:
    """The hand's rotation in the hanger's frame ``in_hanger`` (3, 3) with the hanger's roll about its neck
    (local X) in the pinch taken as at most ``limit`` [rad]: the hanger's roll is the angle of the hand's
    approach (tool Z) about the neck from the hanger's plane's +Y (the pinch's way in, 0 as pinched);
    the hand set by the returned rotation turns at most ``limit`` off the hanger's wanted pose, the hanger
    keeps the rest of its roll. Rolled 24-31 deg (flat_014 s2: in the base's turns on the way), the hand
    turned to set the hanger square met the wardrobe's closed door and pushed the base back 5 cm."""
    z = np.asarray(in_hanger, float)[:, 2]
    roll = math.atan2(-z[2], z[1])
    b = roll - max(-limit, min(limit, roll))
    c, s = math.cos(b), math.sin(b)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]) @ in_hanger
