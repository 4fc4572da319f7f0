"""Scripted experts: one per task, driving the mobile Panda in a :class:`~stages.simulate.world.Sim`.

Every expert first drives the base to a task pose (A* over the room's occupancy grid, then the
pure-pursuit follower of :mod:`stages.demos.planner`; mode 0, locomotion), then manipulates
(mode 1): end-effector motions are straight Cartesian segments solved by CLIK
(``stages.simulate.control.move_ee``), grasps come from the object's geometry (the mug's body
diameter and height, the block's faces) or the furniture's handle (bar position and the joint's
axis: drawers are pulled along the prismatic axis by backing the base away, doors follow their
hinge arc with the gripper turning with the door).

An expert raises :class:`ExpertFailure` with a short reason ("no_path", "ik_unreachable",
"drive_timeout", ...) when it cannot finish; the task's success predicate decides the rest.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass

import numpy as np

from stages.demos.planner import NavGrid, NoPathError, PathFollower, plan_path
from stages.demos.record import Commands, Recorder, base_pose
from stages.demos.sampling import BLOCK_SIZE, TABLE_SIZE, TaskInstance

log = logging.getLogger(__name__)

ROBOT_RADIUS = 0.40  # planning footprint radius of the base with the arm tucked [m]
APPROACH_TOL = 0.015  # CLIK position tolerance of free-space approach and retreat waypoints [m]
# fingertip centre above the mug's base (25 mm below the rim of the 0.8-scaled mug) [m]
MUG_GRASP_HEIGHT = 0.059


class ExpertFailure(RuntimeError):
    """The expert could not complete; ``reason`` is a short category."""

    def __init__(self, reason: str, detail: str = "") -> None:
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason = reason


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


@dataclass
class Driver:
    """What an expert acts through: the sim, its controllers, the current commands and the recorder."""

    sim: object
    ctl: object
    ik: object
    cmd: Commands
    recorder: Recorder
    rng: np.random.Generator
    plan_seconds: float = 0.0

    @property
    def frame_dt(self) -> float:
        return 1.0 / self.recorder.fps

    def step(self, seconds: float) -> None:
        self.sim.step(max(1, int(round(seconds / self.sim.settings.dt))))

    def base(self, v) -> None:
        self.cmd.base_velocity = np.asarray(v, float)
        self.ctl.set_base_velocity(*(float(x) for x in v))

    def grip(self, g: float, seconds: float = 0.6) -> None:
        self.cmd.mode = 1
        self.cmd.gripper = float(g)
        self.ctl.set_gripper(float(g))
        self.step(seconds)

    def move(self, target_world: np.ndarray, duration: float, *, segments: int = 2, settle: float = 0.0,
             tol: float = 0.005) -> None:
        """End-effector to ``target_world`` (4x4) along a straight line in ``duration`` [s]; every
        waypoint must be reached by CLIK within ``tol`` [m] (free-space approach moves use a looser
        tolerance than contact moves)."""
        from stages.simulate.control import move_ee

        self.cmd.mode = 1
        self.base((0.0, 0.0, 0.0))
        try:
            move_ee(self.sim, self.ctl, self.ik, target_world, duration, segments=segments, settle=settle,
                    rng=self.rng, tol=tol)
        except RuntimeError as e:
            if "unreachable" in str(e):
                raise ExpertFailure("ik_unreachable", str(e)) from None
            raise

    def home(self, duration: float = 1.0) -> None:
        """Arm joint targets back to the tucked home configuration (linear in joint space)."""
        q0 = self.ctl.arm_targets()
        q1 = np.asarray(self.sim.desc.arm_home, float)
        n = max(1, int(duration / self.frame_dt))
        for k in range(1, n + 1):
            self.ctl.set_arm_targets(q0 + (q1 - q0) * k / n)
            self.step(self.frame_dt)

    def drive_to(self, goal: tuple[float, float, float], grid: NavGrid, *, approach: float = 0.35,
                 timeout: float = 15.0) -> None:
        """Drive the base to ``goal`` (x, y, yaw): A* to a staging point ``approach`` [m] behind the
        goal (backed away from the furniture along the goal heading), then straight in."""
        t0 = time.perf_counter()
        x, y, th = base_pose(self.sim)
        gx, gy, gyaw = goal
        stage = (gx - approach * math.cos(gyaw), gy - approach * math.sin(gyaw))
        try:
            path = plan_path(grid, (x, y), stage, ROBOT_RADIUS)
        except NoPathError as e:
            raise ExpertFailure("no_path", str(e)) from None
        path = np.vstack([path, [gx, gy]])
        self.plan_seconds += time.perf_counter() - t0
        follower = PathFollower(path, gyaw)
        self.cmd.mode = 0
        t_end = self.sim.time + timeout
        while True:
            t1 = time.perf_counter()
            v, done = follower.command(*base_pose(self.sim))
            self.plan_seconds += time.perf_counter() - t1
            self.base(v)
            if done:
                break
            if self.sim.time > t_end:
                self.base((0.0, 0.0, 0.0))
                raise ExpertFailure("drive_timeout", f"base at {base_pose(self.sim)}, goal {goal}")
            self.step(self.frame_dt)
        self.step(0.1)


def _grid(inst: TaskInstance, door_open: bool = False) -> NavGrid:
    r = inst.room
    return NavGrid.from_boxes((-0.2, -0.2, r.size[0] + 0.2, r.size[1] + 0.2), r.nav_boxes(door_open))


def _pose(p, rot) -> np.ndarray:
    from stages.simulate.control import pose

    return pose(np.asarray(p, float), rot)


def _table_goal(inst: TaskInstance, x: float) -> tuple[float, float, float]:
    """Base pose facing the table (+Y) from its -Y side, 0.10 m between chassis front and table edge."""
    edge = inst.room.table_xy[1] - TABLE_SIZE[1] / 2
    return (x, edge - 0.10 - 0.30, math.pi / 2)


# --------------------------------------------------------------------------------------------
# Experts
# --------------------------------------------------------------------------------------------

def pick_place_bowl(inst: TaskInstance, d: Driver) -> None:
    """Drive to the table, grasp the mug top-down across its body, lift, carry over the bowl,
    lower, release, retreat."""
    from stages.simulate.control import top_down

    bowl = np.asarray(inst.room.bowl_xy)
    mug = np.asarray(inst.mug_xy)
    d.drive_to(_table_goal(inst, float((mug[0] + bowl[0]) / 2)), _grid(inst))
    top = inst.room.table_height
    rot = top_down(0.0)  # fingers close along world y; the handle (+x) stays clear
    grasp = np.array([mug[0], mug[1], top + 0.001 + MUG_GRASP_HEIGHT])
    d.move(_pose(grasp + [0, 0, 0.12], rot), 1.5, segments=3, settle=0.1, tol=APPROACH_TOL)
    d.move(_pose(grasp, rot), 1.0, segments=2, settle=0.2)
    d.grip(1.0, 0.8)
    d.move(_pose(grasp + [0, 0, 0.15], rot), 1.0, segments=2)
    place = np.array([bowl[0], bowl[1], top + 0.006 + MUG_GRASP_HEIGHT + 0.02])
    d.move(_pose(place + [0, 0, 0.08], rot), 1.5, segments=3, tol=APPROACH_TOL)
    d.move(_pose(place, rot), 0.8, segments=2, settle=0.2)
    d.grip(0.0, 0.6)
    d.move(_pose(place + [0, 0, 0.12], rot), 0.8, segments=2, tol=APPROACH_TOL)
    d.home(1.0)


def push_object(inst: TaskInstance, d: Driver) -> None:
    """Drive to the table, close the hand, lower it behind the block (on the side facing the
    robot), push it 16 cm along +Y at table level, lift away."""
    from stages.simulate.control import top_down

    b = np.asarray(inst.block_xy)
    dirn = np.asarray(inst.push_direction, float)
    d.drive_to(_table_goal(inst, float(b[0])), _grid(inst))
    rot = top_down(math.pi / 2)  # fingers close along x: the pads face the push direction
    d.grip(1.0, 0.4)
    z = inst.room.table_height + 0.022
    start = np.array([*(b - dirn * (BLOCK_SIZE / 2 + 0.035)), z])
    d.move(_pose(start + [0, 0, 0.10], rot), 1.5, segments=3, settle=0.1, tol=APPROACH_TOL)
    d.move(_pose(start, rot), 0.8, segments=2, settle=0.1)
    end = start + np.array([*(dirn * 0.16), 0.0])
    d.move(_pose(end, rot), 1.6, segments=4, settle=0.2)
    d.move(_pose(end + [0, 0, 0.12], rot), 0.8, segments=2, tol=APPROACH_TOL)
    d.grip(0.0, 0.3)
    d.home(1.0)


def _drawer_rot(pitch: float = 20.0) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    # gripper pointing at the cabinet (+X), pitched ``pitch`` deg down, fingers closing vertically
    return Rotation.from_euler("y", pitch, degrees=True).as_matrix() @ np.stack(
        [[0, 1, 0], [0, 0, 1], [1, 0, 0]], axis=1).astype(float)


def _grasp_drawer(inst: TaskInstance, d: Driver, opening: float) -> np.ndarray:
    """Drive in front of the drawer (its handle ``opening`` [m] out), grasp the bar; returns the
    handle position."""
    h = np.asarray(inst.room.drawer_handle) - [opening, 0.0, 0.0]
    d.drive_to((float(h[0] - 0.75), float(h[1]), 0.0), _grid(inst))
    rot = _drawer_rot()
    d.move(_pose(h + [-0.12, 0, 0], rot), 1.5, segments=3, settle=0.1, tol=APPROACH_TOL)
    d.move(_pose(h, rot), 1.0, segments=2, settle=0.2)
    d.grip(1.0, 0.6)
    return h


def _slide_base(d: Driver, distance: float, speed: float = 0.12) -> None:
    """Move the base straight along its heading by ``distance`` [m] (negative: backwards), arm held."""
    d.cmd.mode = 1
    d.base((math.copysign(speed, distance), 0.0, 0.0))
    d.step(abs(distance) / speed)
    d.base((0.0, 0.0, 0.0))
    d.step(0.3)


def _release_and_back(d: Driver) -> None:
    """Open the hand, back it off 8 cm along its approach axis, tuck the arm."""
    d.grip(0.0, 0.6)
    from stages.simulate.control import pose

    # back the hand off 8 cm along its approach axis, then tuck the arm
    q = d.ik.with_arm(d.ik.from_sim(d.sim), d.ctl.arm_targets())
    cur = d.ik.fk(q)
    x, y, yaw = d.sim.spawn
    c, s = math.cos(yaw), math.sin(yaw)
    to_world = np.array([[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    w = to_world @ cur
    back = w[:3, 3] - 0.08 * w[:3, 2]
    try:
        d.move(pose(back, w[:3, :3]), 0.6, segments=1, tol=APPROACH_TOL)
    except ExpertFailure as e:
        log.info("no straight back-off from the handle (%s); tucking the arm directly", e)
    d.home(1.0)


def open_drawer(inst: TaskInstance, d: Driver) -> None:
    """Grasp the drawer's bar, back the base away along the drawer's axis by 90% of the travel, release."""
    _grasp_drawer(inst, d, 0.0)
    _slide_base(d, -0.9 * inst.room.drawer_travel)
    _release_and_back(d)


def close_drawer(inst: TaskInstance, d: Driver) -> None:
    """Grasp the bar of the open drawer, drive the base forward by the opening, release."""
    from stages.demos.tasks import DRAWER_JOINT

    opening = -inst.joints[DRAWER_JOINT]
    _grasp_drawer(inst, d, opening)
    _slide_base(d, opening + 0.005)
    _release_and_back(d)


def _door_frames(inst: TaskInstance):
    from scipy.spatial.transform import Rotation

    h, hinge = np.asarray(inst.room.door_handle), np.asarray(inst.room.door_hinge)
    grip = Rotation.from_euler("y", 35, degrees=True).as_matrix() @ np.stack(
        [[0, 0, -1], [0, 1, 0], [1, 0, 0]], axis=1).astype(float)

    def handle_pose(theta: float, back: float = 0.0) -> np.ndarray:
        rz = Rotation.from_euler("z", theta).as_matrix()
        p = hinge + rz @ (h - hinge)
        p[2] = h[2]
        rot = rz @ grip
        return _pose(p - back * rot[:, 2], rot)

    return hinge, handle_pose


def _swing_door(inst: TaskInstance, d: Driver, theta0: float, theta1: float, back: float = 0.12) -> None:
    hinge, handle_pose = _door_frames(inst)
    d.drive_to((float(hinge[0] - 0.655), float(hinge[1] - 0.58), 0.3), _grid(inst, door_open=theta0 != 0.0))
    d.move(handle_pose(theta0, back), 1.5, segments=3, settle=0.1, tol=APPROACH_TOL)
    d.move(handle_pose(theta0), 1.0, segments=2, settle=0.2)
    d.grip(1.0, 0.6)
    step = math.copysign(math.radians(6.0), theta1 - theta0)
    for th in np.arange(theta0 + step, theta1 + 0.5 * step, step):
        d.move(handle_pose(float(th)), 0.4, segments=1)
    if theta1 != 0.0:
        # the arm ends wrapped around the open door's free edge at its joint limits: no straight
        # retreat is reachable and tucking would sweep the door shut, so the episode ends released
        d.grip(0.0, 0.6)
        return
    _release_and_back(d)


def open_door(inst: TaskInstance, d: Driver) -> None:
    """Grasp the door's vertical bar, carry it along the hinge arc to 86 deg in 6 deg steps, release."""
    _swing_door(inst, d, 0.0, -math.radians(86.0))


def close_door(inst: TaskInstance, d: Driver) -> None:
    """Grasp the bar of the open door, carry it back along the hinge arc to closed, release."""
    from stages.demos.tasks import DOOR_JOINT

    _swing_door(inst, d, float(inst.joints[DOOR_JOINT]), 0.0, back=0.06)


def press_button(inst: TaskInstance, d: Driver) -> None:
    """Drive in front of the control panel, close the hand, point it at the button (tool axis +X,
    fingers vertical), push the fingertips 12 mm past the button's rest face, pull back, tuck."""
    b = np.asarray(inst.room.button)
    d.drive_to((float(b[0] - 0.72), float(b[1]), 0.0), _grid(inst))
    rot = _drawer_rot(pitch=10.0)
    d.grip(1.0, 0.4)
    d.move(_pose(b + [-0.10, 0, 0], rot), 1.5, segments=3, settle=0.1, tol=APPROACH_TOL)
    d.move(_pose(b + [-0.01, 0, 0], rot), 0.6, segments=1)
    d.move(_pose(b + [inst.room.button_travel + 0.002, 0, 0], rot), 0.8, segments=2, settle=0.3)
    d.move(_pose(b + [-0.10, 0, 0], rot), 0.8, segments=2, tol=APPROACH_TOL)
    d.grip(0.0, 0.3)
    d.home(1.0)


EXPERTS = {"pick_place_bowl": pick_place_bowl, "push_object": push_object, "open_drawer": open_drawer,
           "close_drawer": close_drawer, "open_door": open_door, "close_door": close_door,
           "press_button": press_button}

