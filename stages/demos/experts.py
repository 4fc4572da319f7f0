"""Scripted experts: one per task, driving the mobile Panda in a :class:`~stages.simulate.world.Sim`.

Every expert first raises the hand over the base (:func:`stow`) and drives the base to a task pose
(A* over the world's occupancy grid, then the pure-pursuit follower of :mod:`stages.demos.planner`;
mode 0, locomotion), then manipulates
(mode 1): end-effector motions are straight Cartesian segments solved by CLIK
(``stages.simulate.control.move_ee``). Grasps come from the catalog asset's geometry (its
generated.json parameters: the mug's body radius and height, the pushed object's bounds) and the
world's facts (support heights, the microwave's cavity and button). The mug is grasped top-down
across its body on the table (bowl task) and from the side, hand horizontal, for the microwave
tasks (a top-down hand does not fit under the cavity's ceiling).

An expert acts through a :class:`~stages.demos.driver.Driver` and raises
:class:`~stages.demos.driver.ExpertFailure` with a short reason ("no_path", "ik_unreachable",
"drive_timeout", ...) when it cannot finish; the task's success predicate decides the rest. (Both
are importable from here too.)
"""

from __future__ import annotations

import logging
import math
import time

import numpy as np

from stages.demos.articulated import close_part, open_part
from stages.demos.counter import (
    COUNTER_STAGE,
    SIDE_HEIGHT,
    SIDE_PITCH,
    _mug,
    _pose,
    _side_pick,
    approach_counter,
    facing_north_goal,
    leave_counter,
    side_rot,
)
from stages.demos.driver import APPROACH_TOL, Driver, ExpertFailure, stow
from stages.demos.planner import NavGrid
from stages.demos.record import base_pose
from stages.demos.sampling import TaskInstance
from stages.demos.skill_bed import place_pillow
from stages.demos.skill_books import shelve_book_1, shelve_book_2
from stages.demos.skill_fridge import pick_place_fridge
from stages.demos.pour_place import place_pitcher
from stages.demos.skill_pour import pick_pitcher, pour_drink
from stages.demos.skill_press import press_clock_button, slide_clock_switch
from stages.demos.skill_trash import throw_away
from stages.demos.skill_wardrobe import hang_on_rail
from stages.demos.skill_rack import place_in_rack
from stages.demos.skill_wipe import wipe_plate
from stages.demos.tasks import TASKS

__all__ = ["EXPERTS", "Driver", "ExpertFailure", "approach_counter", "close_articulated", "facing_north_goal",
           "leave_counter", "open_articulated", "pick_from_microwave", "pick_place_bowl", "pick_place_microwave",
           "press_button", "push_object", "side_rot", "timed_clik"]

log = logging.getLogger(__name__)

RIM_CLEARANCE = 0.025  # top-down grasp: fingertip centre below the mug's rim [m]


def timed_clik(desc):
    """A :class:`~stages.simulate.control.Clik` that sums the wall time of its solves in ``seconds``."""
    from stages.simulate.control import Clik

    class TimedClik(Clik):
        seconds = 0.0

        def solve(self, *args, **kwargs):
            t0 = time.perf_counter()
            try:
                return super().solve(*args, **kwargs)
            finally:
                self.seconds += time.perf_counter() - t0

    return TimedClik(desc)


def _grid(inst: TaskInstance) -> NavGrid:
    return inst.world.grid()


def _retreat(d: Driver, back: float = 0.15) -> None:
    """Open the hand, back it off ``back`` [m] along its approach axis, tuck the arm."""
    d.grip(0.0, 0.5)
    q = d.ik.with_arm(d.ik.from_sim(d.sim), d.ctl.arm_targets())
    cur = d.ik.fk(q)
    x, y, yaw = d.sim.spawn
    c, s = math.cos(yaw), math.sin(yaw)
    to_world = np.array([[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    w = to_world @ cur
    d.move(_pose(w[:3, 3] - back * w[:3, 2], w[:3, :3]), 0.8, segments=2, tol=APPROACH_TOL)
    d.home(1.0)


# --------------------------------------------------------------------------------------------
# Experts
# --------------------------------------------------------------------------------------------

def pick_place_bowl(inst: TaskInstance, d: Driver) -> None:
    """Drive to the table, grasp the mug top-down across its body (fingers along world X, the
    handle points away), lift, carry over the bowl, lower, release, retreat."""
    from stages.simulate.control import top_down

    w = inst.world
    body, _, h = _mug(inst)
    mug = np.asarray(inst.objects[body][:2])
    bowl = np.asarray(inst.target)
    tuck = stow(d, on_the_way=True)
    d.drive_to(facing_north_goal(w.table_rect[1], float((mug[0] + bowl[0]) / 2)), _grid(inst), tuck=tuck)
    top = w.table_z
    rot = top_down(math.pi / 2)
    grasp = np.array([mug[0], mug[1], top + 0.002 + h - RIM_CLEARANCE])
    d.move(_pose(grasp + [0, 0, 0.12], rot), 1.5, segments=3, settle=0.1, tol=APPROACH_TOL)
    d.move(_pose(grasp, rot), 1.0, segments=2, settle=0.2)
    d.grip(1.0, 0.8)
    d.move(_pose(grasp + [0, 0, 0.15], rot), 1.0, segments=2, carry=True)
    place = np.array([bowl[0], bowl[1], top + 0.012 + h - RIM_CLEARANCE + 0.008])
    d.move(_pose(place + [0, 0, 0.08], rot), 1.5, segments=3, tol=APPROACH_TOL)
    d.move(_pose(place, rot), 0.8, segments=2, settle=0.2)
    d.grip(0.0, 0.6)
    d.move(_pose(place + [0, 0, 0.12], rot), 0.8, segments=2, tol=APPROACH_TOL)
    stow(d)  # home hangs at table height: swinging there from over the bowl knocks the mug over


def _microwave_front(inst: TaskInstance) -> float:
    """World y of the microwave's front (its bounds, door closed) [m]."""
    return inst.world.placed["microwave"].footprint()[1]


def pick_place_microwave(inst: TaskInstance, d: Driver) -> None:
    """From the counter beside the opened microwave: side-grasp the mug (hand pitched 20 deg down,
    from the front), lift 3 cm, carry it in front of the cavity, slide it in, lower, release, back out."""
    w = inst.world
    body, r, h = _mug(inst)
    start = np.asarray(inst.objects[body][:3], float)
    tgt = np.asarray(inst.target, float)
    approach_counter(inst, d, float((start[0] + tgt[0]) / 2))
    rot = side_rot(SIDE_PITCH)
    gz = SIDE_HEIGHT * h
    _side_pick(d, start + [0.0, -0.003, gz], rot, 0.03)
    front = _microwave_front(inst)
    z = w.cavity_z + gz + 0.025
    d.move(_pose([start[0], front - 0.10, z], rot), 1.0, segments=2, tol=APPROACH_TOL)
    d.move(_pose([tgt[0], front - 0.10, z], rot), 1.5, segments=3, tol=APPROACH_TOL)
    d.move(_pose([tgt[0], tgt[1] - 0.01, z], rot), 1.5, segments=3, carry=True)
    d.move(_pose([tgt[0], tgt[1] - 0.01, z - 0.02], rot), 0.5, segments=1, settle=0.2)
    d.grip(0.0, 0.6)
    d.move(_pose([tgt[0], front - 0.12, z], rot), 1.2, segments=3, tol=APPROACH_TOL)
    leave_counter(inst, d)


def pick_from_microwave(inst: TaskInstance, d: Driver) -> None:
    """Out of the opened microwave onto the counter beside it: reach in (hand pitched 20 deg down),
    grasp the mug from the front, lift 2 cm, pull it out, carry it over the spot, lower, release,
    back off."""
    w = inst.world
    body, r, h = _mug(inst)
    start = np.asarray(inst.objects[body][:3], float)
    tgt = np.asarray(inst.target, float)
    approach_counter(inst, d, float((start[0] + tgt[0]) / 2))
    rot = side_rot(SIDE_PITCH)
    gz = SIDE_HEIGHT * h
    front = _microwave_front(inst)
    d.grip(0.0, 0.1)
    d.move(_pose([start[0], front - 0.10, start[2] + gz], rot), 1.6, segments=3, settle=0.1, tol=APPROACH_TOL)
    up = _side_pick(d, start + [0.0, -0.003, gz], rot, 0.02, pre=0.0)
    d.move(_pose([up[0], front - 0.10, up[2]], rot), 1.5, segments=3, carry=True)
    z = w.counter_z + gz + 0.02
    d.move(_pose([tgt[0], front - 0.10, z], rot), 1.5, segments=3, carry=True)
    d.move(_pose([tgt[0], tgt[1] - 0.01, z], rot), 1.0, segments=2, carry=True)
    d.move(_pose([tgt[0], tgt[1] - 0.01, z - 0.015], rot), 0.5, segments=1, settle=0.2)
    d.grip(0.0, 0.6)
    d.move(_pose([tgt[0], tgt[1] - 0.15, z], rot), 1.0, segments=2, tol=APPROACH_TOL)
    leave_counter(inst, d)


def _half_extent(inst: TaskInstance, role: str, yaw: float, direction) -> float:
    """Half extent [m] of a placed asset's bounds, turned by ``yaw``, along the unit ``direction`` (2,)."""
    a = inst.world.placed[role].asset
    corners = np.array([[x, y] for x in (a.lo[0], a.hi[0]) for y in (a.lo[1], a.hi[1])])
    c, s = math.cos(yaw), math.sin(yaw)
    pts = corners @ np.array([[c, s], [-s, c]])
    return float(np.max(-(pts @ np.asarray(direction))))


PUSH_GRIP = 0.45  # gripper command while pushing: fingers ~4 cm apart cradle the object [0 open .. 1 closed]


def push_object(inst: TaskInstance, d: Driver) -> None:
    """Drive to the table, half-close the hand (the two fingertips ~4 cm apart across the push
    direction cradle a round can: a single contact lets it slip sideways), lower it behind the
    object (on the robot's side, from its bounds), push it 16 cm along +Y at about 2 cm above the
    table, lift away."""
    from stages.simulate.control import top_down

    w = inst.world
    body = w.placed["pusher"].body()
    x, y, _, yaw = inst.objects[body]
    b = np.array([x, y])
    dirn = np.asarray(inst.push_direction, float)
    tuck = stow(d, on_the_way=True)
    d.drive_to(facing_north_goal(w.table_rect[1], float(b[0])), _grid(inst), tuck=tuck)
    rot = top_down(math.pi / 2)  # fingers close along x, across the push direction
    d.grip(PUSH_GRIP, 0.4)
    a = w.placed["pusher"].asset
    z = w.table_z + float(np.clip(0.5 * (a.hi[2] - a.lo[2]), 0.015, 0.022))
    start = np.array([*(b - dirn * (_half_extent(inst, "pusher", yaw, dirn) + 0.03)), z])
    d.move(_pose(start + [0, 0, 0.10], rot), 1.5, segments=3, settle=0.1, tol=APPROACH_TOL)
    d.move(_pose(start, rot), 0.8, segments=2, settle=0.1)
    end = start + np.array([*(dirn * 0.16), 0.0])
    d.move(_pose(end, rot), 1.6, segments=4, settle=0.2)
    d.move(_pose(end + [0, 0, 0.12], rot), 0.8, segments=2, tol=APPROACH_TOL)
    d.grip(0.0, 0.3)
    stow(d)  # (not home: it sweeps the table top)


def press_button(inst: TaskInstance, d: Driver) -> None:
    """Drive in front of the microwave's button, close the hand, point it at the button (pitched
    25 deg down so the hand clears the counter top), push the fingertips in 2 mm steps until the
    button is in by 80% of its travel (at most 25 mm past its face), pull back, leave."""
    w = inst.world
    b = np.asarray(w.button, float)
    push = np.asarray(w.button_push, float)
    joint = w.placed["microwave"].joint("button_joint")
    approach_counter(inst, d, float(b[0]))
    rot = side_rot(25.0)
    d.grip(1.0, 0.4)
    d.move(_pose(b - 0.10 * push, rot), 1.5, segments=3, settle=0.1, tol=APPROACH_TOL)
    d.move(_pose(b - 0.015 * push, rot), 0.6, segments=1)
    depth = -0.015
    while d.sim.joint_q_of_path(joint) < 0.8 * w.button_travel and depth < 0.025:
        depth += 0.002
        d.move(_pose(b + depth * push, rot), 0.08, segments=1)
    d.step(0.2)
    d.move(_pose(b - 0.10 * push, rot), 1.0, segments=2, tol=APPROACH_TOL)
    d.grip(0.0, 0.3)
    leave_counter(inst, d)


def open_articulated(inst: TaskInstance, d: Driver) -> None:
    """Open the instance's part (door or drawer) with :func:`stages.demos.articulated.open_part`."""
    open_part(inst.part, d, _grid(inst))


def close_articulated(inst: TaskInstance, d: Driver) -> None:
    """Close the instance's part from its initial opening (:func:`stages.demos.articulated.close_part`)."""
    close_part(inst.part, d, _grid(inst), start=float(inst.joints[inst.part.joint_path]))


EXPERTS = {"pick_place_bowl": pick_place_bowl, "pick_place_microwave": pick_place_microwave,
           "pick_from_microwave": pick_from_microwave, "push_object": push_object,
           "press_button": press_button, "pick_place_fridge": pick_place_fridge,
           "wipe_plate": wipe_plate, "place_in_rack": place_in_rack, "throw_away": throw_away, "pick_pitcher": pick_pitcher,
           "pour_drink": pour_drink, "place_pitcher": place_pitcher, "press_clock_button": press_clock_button,
           "slide_clock_switch": slide_clock_switch, "place_pillow": place_pillow,
           "shelve_book_1": shelve_book_1, "shelve_book_2": shelve_book_2, "hang_on_rail": hang_on_rail}
for _name in TASKS:
    if _name.startswith("open_"):
        EXPERTS[_name] = open_articulated
    elif _name.startswith("close_"):
        EXPERTS[_name] = close_articulated
