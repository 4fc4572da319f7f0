"""Press and slide skills (issue 16, set the alarm clock): a fingertip push along a part's joint axis.

The alarm clock (``asset_catalog.generators.appliances.alarm_clock``, placed role ``"clock"``) has a
push button on top (role ``button``, pressed along -Z) and an on/off slide switch on its back face
(role ``switch``, +Y of the clock: 0 = off). :func:`clock_parts` reads both from the package: the
joints' axes and limits from its UsdPhysics joints, the button's top face and the switch knob's box
from the links' bounds (asset frame, zero joint positions); :func:`parts_at` puts them where the
clock stands now (it may have been nudged by an earlier stage).

- :func:`press_clock_button` (task ``press_clock_button``): the base before the counter at the
  button, the closed hand pointing down (fingers closing across the clock, so the 17.5 mm wide
  fingertips fit between a twin-bell clock's bells) over the button, down onto it, then 1 mm steps
  along the joint axis until the button is in by :data:`PRESS_GOAL` of its travel (at most
  :data:`PRESS_OVER` past its full travel), up, away;
- :func:`slide_clock_switch` (task ``slide_clock_switch``): the closed hand pointing at the clock's
  back (pitched :data:`SLIDE_PITCH` down), the fingertips beside the knob on its off side, inside
  the knob's protrusion, then 1 mm steps along the joint axis until the switch is at
  :data:`SLIDE_GOAL` of its travel, a step back, out, away;
- predicates: :func:`press_clock_button_success` (the button's deepest position during the episode
  past :data:`PRESS_FRACTION` of its travel), :func:`slide_clock_switch_success` (the switch at the
  end past :data:`SLIDE_FRACTION` of its travel: moved to its other end and left there); both fail
  with ``clock_tipped`` when the clock no longer stands upright.

Frame: world, Z up, metres, radians.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stages.demos.driver import APPROACH_TOL, ExpertFailure

PRESS_FRACTION = 0.7   # the predicate: the button went in past this fraction of its travel
SLIDE_FRACTION = 0.8   # the predicate: the switch ends past this fraction of its travel
PRESS_GOAL = 0.9       # the expert pushes until the button is in this far (fraction of travel)
SLIDE_GOAL = 0.97      # the expert pushes until the switch is this far (fraction of travel)
PRESS_OVER = 0.012     # the fingertips go at most this far [m] past the button's full travel
SLIDE_OVER = 0.006     # the fingertips go at most this far [m] past the knob's full travel
SLIDE_PITCH = 20.0     # slide: the hand points at the clock's back pitched down [deg]
STEP = 0.001           # push step along the joint axis [m]
# the Panda hand's closed rubber fingertips (example-robot-data panda.urdf): the tip's end lies
# TIP_AHEAD beyond the TCP; together the two tips span +-TIP_HALF_CLOSED along the closing axis and
# +-TIP_HALF_WIDTH across it [m]
TIP_AHEAD = 0.0093
TIP_HALF_CLOSED = 0.0152
TIP_HALF_WIDTH = 0.00875
GAP = 0.003            # the fingertips start this far [m] from the face they push
BACK_CLEAR = 0.005     # slide: the fingertips' end stops this far [m] short of the clock's back face (2 mm
                       # let them touch it at a generated nightstand: the clock tipped; the knobs stand
                       # out 13.5 mm: asset_catalog.generators.appliances.CLOCK_KNOB)


@dataclass(frozen=True)
class ClockParts:
    """The clock's button and switch in its asset frame (+X front, zero joint positions).
    button_joint / switch_joint: joint prim names; button_top (3,): centre of the button's top
    face [m]; button_axis (3,) unit: pressing direction; button_travel [m]; knob_lo / knob_hi (3,):
    the switch knob's box [m] (the link's bounds; its outer face at knob_lo[0]); switch_axis (3,)
    unit: the off -> on direction; switch_travel [m]; back_x: the back face the knob stands out
    of (the switch joint's origin) [m]."""

    button_joint: str
    button_top: tuple[float, float, float]
    button_axis: tuple[float, float, float]
    button_travel: float
    switch_joint: str
    knob_lo: tuple[float, float, float]
    knob_hi: tuple[float, float, float]
    switch_axis: tuple[float, float, float]
    switch_travel: float
    back_x: float


@functools.lru_cache(maxsize=32)
def _parts_of_package(usd: str, joints: tuple[tuple[str, str], ...]) -> ClockParts:
    from pipeline.types import ItemError
    from stages.demos.packages import link_bounds
    from stages.demos.parts import package_joint_frames

    by_role = {role: name for name, role in joints}
    frames = package_joint_frames(Path(usd))
    missing = [r for r in ("button", "switch") if by_role.get(r) not in frames]
    if missing:
        raise ItemError(f"{usd}: alarm clock without a {' or '.join(missing)} joint (has {sorted(frames)})")
    b, s = frames[by_role["button"]], frames[by_role["switch"]]
    blo, bhi = link_bounds(Path(usd), b.link)
    klo, khi = link_bounds(Path(usd), s.link)
    top = ((blo[0] + bhi[0]) / 2, (blo[1] + bhi[1]) / 2, bhi[2])
    return ClockParts(button_joint=b.name, button_top=tuple(float(v) for v in top), button_axis=b.axis,
                      button_travel=b.upper - b.lower, switch_joint=s.name,
                      knob_lo=tuple(float(v) for v in klo), knob_hi=tuple(float(v) for v in khi),
                      switch_axis=s.axis, switch_travel=s.upper - s.lower, back_x=float(s.origin[0]))


def clock_parts(placed) -> ClockParts:
    """:class:`ClockParts` of a placed alarm clock package (cached per package)."""
    joints = tuple(sorted(dict(placed.info.get("joints", {})).items()))
    return _parts_of_package(str(placed.asset.usd), joints)


def _quat_rot(q) -> np.ndarray:
    w, x, y, z = (float(v) for v in q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


@dataclass(frozen=True)
class PartsAt:
    """The clock's parts in the world at its current pose: button_top (3,), press (3,) unit;
    knob_face (3,): centre of the knob's outer face; knob_half (3,): the knob's half extents along
    (out of the back, slide, up) [m]; knob_out: how far its face stands out of the back face [m]; slide (3,) unit: off -> on; out (3,) unit: the back face's
    outward normal; yaw: the clock's heading (its +X) [rad]."""

    button_top: np.ndarray
    press: np.ndarray
    knob_face: np.ndarray
    knob_half: np.ndarray
    knob_out: float
    slide: np.ndarray
    out: np.ndarray
    yaw: float


def parts_at(parts: ClockParts, position, orientation) -> PartsAt:
    """Where ``parts`` are with the clock's root at ``position`` (3,) [m], ``orientation`` (w, x, y, z)."""
    r, t = _quat_rot(orientation), np.asarray(position, float)
    lo, hi = np.asarray(parts.knob_lo), np.asarray(parts.knob_hi)
    face = np.array([lo[0], (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2])
    return PartsAt(button_top=r @ np.asarray(parts.button_top) + t, press=r @ np.asarray(parts.button_axis),
                   knob_face=r @ face + t, knob_half=0.5 * (hi - lo), knob_out=parts.back_x - float(lo[0]),
                   slide=r @ np.asarray(parts.switch_axis),
                   out=r @ np.array([-1.0, 0.0, 0.0]), yaw=math.atan2(r[1, 0], r[0, 0]))


def _clock_now(inst, d) -> tuple[object, ClockParts, PartsAt]:
    from stages.simulate.state import read_state

    pl = inst.world.placed.get("clock")
    if pl is None:
        raise ExpertFailure("no_clock", f"{inst.world.usd}: no alarm clock in this world")
    parts = clock_parts(pl)
    st = read_state(d.sim).objects[pl.body()]
    return pl, parts, parts_at(parts, st.position, st.orientation)


def _approach(inst, d, x: float, rot: np.ndarray, lift: float, over: np.ndarray) -> None:
    """Bring the base before the surface at ``x`` [m] and the hand (orientation ``rot``) to ``over``
    (3,) [m]. A counter (the task kitchen's): :func:`~stages.demos.counter.approach_counter` (the hand
    raised ``lift`` over the top before the base drives in: the tucked arm would hit the counter's
    front). A low surface whose world names the base's x (``base_x``: a bedroom's nightstand,
    :mod:`stages.demos.house_bedside`, where the bed beside it leaves no room for the base right
    before the clock; ``base_gap``: its chassis's front [m] off the surface): the base drives there with the arm tucked over the top (it clears a 0.5-0.65 m
    nightstand; the counter's ready pose, 0.35 m before the base, is out of the arm's reach that low)."""
    from stages.demos.counter import _pose, approach_counter, facing_north_goal
    from stages.demos.driver import stow

    w = inst.world
    bx = getattr(w, "base_x", None)
    if bx is None:
        approach_counter(inst, d, x, rot=rot, lift=lift)
        return
    goal = facing_north_goal(w.placed["counter"].footprint()[1], float(bx), float(w.base_gap))
    d.drive_to(goal, w.grid(), tuck=stow(d, on_the_way=True))
    d.move(_pose(over, rot), 1.5, segments=3, settle=0.1, tol=APPROACH_TOL)


def _leave(inst, d, away: np.ndarray, rot: np.ndarray) -> None:
    """Back off the clock: the hand to ``away`` (3,) [m], then away from the surface
    (:func:`~stages.demos.counter.leave_counter`; before a nightstand: the arm tucked, the base
    backed COUNTER_STAGE straight out, where the next stage's planner finds it on free floor)."""
    from stages.demos.counter import COUNTER_STAGE, _pose, leave_counter
    from stages.demos.driver import stow
    from stages.demos.record import base_pose

    d.move(_pose(away, rot), 0.8, segments=2, tol=APPROACH_TOL)
    if getattr(inst.world, "base_x", None) is None:
        leave_counter(inst, d)
        return
    stow(d)
    bx, by, th = base_pose(d.sim)
    d.drive_straight((bx - COUNTER_STAGE * math.cos(th), by - COUNTER_STAGE * math.sin(th), th))


def _upright(state, pl) -> bool:
    from stages.demos.predicates import _upright as upright

    return upright(state.objects[pl.body()].orientation)


# --------------------------------------------------------------------------------------------
# experts
# --------------------------------------------------------------------------------------------

def _push(d, start: np.ndarray, direction: np.ndarray, rot: np.ndarray, joint: str, goal: float,
          limit: float) -> float:
    """Move the TCP from ``start`` (3,) along ``direction`` (3,) in STEP steps until scene joint
    ``joint`` reaches ``goal`` [m] or the TCP has gone ``limit`` [m]; returns the distance gone."""
    from stages.demos.counter import _pose

    gone = 0.0
    while d.sim.joint_q_of_path(joint) < goal and gone < limit:
        gone += STEP
        d.move(_pose(start + gone * direction, rot), 0.06, segments=1)
    return gone


def press_clock_button(inst, d) -> None:
    """The expert of ``press_clock_button`` (see the module doc)."""
    from stages.demos.counter import _pose
    from stages.simulate.control import top_down

    w = inst.world
    pl, parts, at = _clock_now(inst, d)
    rot = top_down(at.yaw - math.pi / 2)  # fingers close along the clock's depth, between the bells
    top, press = at.button_top, at.press
    _approach(inst, d, float(top[0]), rot, float(top[2] - w.counter_z) + 0.05, top - 0.10 * press)
    _, _, at = _clock_now(inst, d)  # (the base may have brushed the counter)
    top = at.button_top
    d.grip(1.0, 0.4)
    tcp = top - (TIP_AHEAD + GAP) * press  # the fingertips GAP over the button's top
    d.move(_pose(tcp - 0.04 * press, rot), 1.2, segments=2, settle=0.1, tol=APPROACH_TOL)
    d.move(_pose(tcp, rot), 0.6, segments=1, settle=0.1)
    joint = pl.joint(parts.button_joint)
    _push(d, tcp, press, rot, joint, PRESS_GOAL * parts.button_travel, GAP + parts.button_travel + PRESS_OVER)
    d.step(0.2)
    _leave(inst, d, tcp - 0.04 * press, rot)


def slide_clock_switch(inst, d) -> None:
    """The expert of ``slide_clock_switch`` (see the module doc)."""
    from stages.demos.counter import _pose, side_rot

    w = inst.world
    pl, parts, at = _clock_now(inst, d)
    if at.out[1] > -0.7:
        raise ExpertFailure("switch_out_of_reach", "the clock's back does not face the counter's front")
    rot = side_rot(SLIDE_PITCH)
    q0 = float(d.sim.joint_q_of_path(pl.joint(parts.switch_joint)))
    _approach(inst, d, float(at.knob_face[0]), rot, float(at.knob_face[2] - w.counter_z) + 0.06,
              at.knob_face + 0.06 * at.out + [0.0, 0.0, 0.06])
    _, _, at = _clock_now(inst, d)
    # the fingertips' pushing side GAP off the knob's off side; their end BACK_CLEAR short of the
    # back face (inside the knob's protrusion); the TCP at the knob's height
    p = math.radians(SLIDE_PITCH)
    reach = TIP_AHEAD * math.cos(p) + TIP_HALF_WIDTH * math.sin(p)  # the tips' foremost point before the TCP
    depth = at.knob_out - BACK_CLEAR - reach  # how far in from the knob's face the TCP goes
    side = at.knob_half[1] + TIP_HALF_CLOSED + GAP
    tcp = at.knob_face + (q0 - side) * at.slide - depth * at.out  # (the knob's face is at q = 0)
    d.grip(1.0, 0.4)
    d.move(_pose(tcp + 0.06 * at.out, rot), 1.2, segments=2, settle=0.1, tol=APPROACH_TOL)
    d.move(_pose(tcp, rot), 0.6, segments=1, settle=0.1)
    joint = pl.joint(parts.switch_joint)
    gone = _push(d, tcp, at.slide, rot, joint, SLIDE_GOAL * parts.switch_travel,
                 GAP + parts.switch_travel - q0 + SLIDE_OVER)
    d.step(0.2)
    d.move(_pose(tcp + (gone - 0.004) * at.slide, rot), 0.3, segments=1)
    _leave(inst, d, tcp + (gone - 0.004) * at.slide + 0.08 * at.out, rot)


# --------------------------------------------------------------------------------------------
# predicates
# --------------------------------------------------------------------------------------------

def press_clock_button_success(inst, state, peaks=None) -> tuple[bool, str]:
    """The clock upright; its button in past PRESS_FRACTION of its travel at some point (``peaks``:
    the watched joints' deepest positions; without them, the final position)."""
    pl = inst.world.placed["clock"]
    if not _upright(state, pl):
        return False, "clock_tipped"
    parts = clock_parts(pl)
    path = pl.joint(parts.button_joint)
    pressed = float((peaks or {}).get(path, state.scene_joints[path]))
    return (True, "") if pressed >= PRESS_FRACTION * parts.button_travel else (False, "button_not_pressed")


def slide_clock_switch_success(inst, state, peaks=None) -> tuple[bool, str]:
    """The clock upright; its switch, at the end, past SLIDE_FRACTION of its travel (moved to its
    other end and left there)."""
    pl = inst.world.placed["clock"]
    if not _upright(state, pl):
        return False, "clock_tipped"
    parts = clock_parts(pl)
    q = float(state.scene_joints[pl.joint(parts.switch_joint)])
    return (True, "") if q >= SLIDE_FRACTION * parts.switch_travel else (False, "switch_not_on")


def clock_setup(world) -> tuple[dict, dict]:
    """The episode's clock: its parked pose (body -> (x, y, z, yaw)) and its joints at rest (joint
    path -> 0: the button out, the switch off). ItemError when the world has no clock
    (:func:`stages.demos.kitchen.write_kitchen` parks one when asked)."""
    from pipeline.types import ItemError

    pl = world.placed.get("clock")
    if pl is None:
        raise ItemError(f"{world.usd}: no alarm clock in this kitchen")
    parts = clock_parts(pl)
    return ({pl.body(): (*pl.position, pl.yaw)},
            {pl.joint(parts.button_joint): 0.0, pl.joint(parts.switch_joint): 0.0})
