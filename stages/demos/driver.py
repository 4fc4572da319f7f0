"""What a scripted expert acts through: the :class:`Driver` (the sim, its controllers, the commands
and the recorder; base driving over the occupancy grid, end-effector moves, gripper), the
:class:`ExpertFailure` it raises, the planning footprint and tolerances the experts share, and
:func:`stow` (the hand tucked over the base for driving).

The task experts (:mod:`stages.demos.experts`) and the generic open/close experts of articulated
parts (:mod:`stages.demos.articulated`) both build on it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from stages.demos.planner import NavGrid, NoPathError, PathFollower, plan_path
from stages.demos.record import Commands, Recorder, base_pose

ROBOT_RADIUS = 0.40  # planning footprint radius of the base with the arm tucked [m]
APPROACH_TOL = 0.015  # CLIK position tolerance of free-space approach and retreat waypoints [m]


class ExpertFailure(RuntimeError):
    """The expert could not complete; ``reason`` is a short category."""

    def __init__(self, reason: str, detail: str = "") -> None:
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason = reason


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
        self.cmd.mode = 1
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
        self.follow(path, gyaw, timeout=timeout)

    def drive_straight(self, goal: tuple[float, float, float], *, timeout: float = 10.0) -> None:
        """Drive the base in a straight line to ``goal`` (x, y, yaw), no planning (the last metre
        in front of furniture, where the inflated grid is blocked)."""
        x, y, _ = base_pose(self.sim)
        self.follow(np.array([[x, y], goal[:2]], float), goal[2], timeout=timeout)

    def follow(self, path: np.ndarray, gyaw: float, *, timeout: float = 15.0) -> None:
        """Follow ``path`` (N, 2) [m] to its end, turning to ``gyaw`` [rad]; mode 0 (locomotion)."""
        goal = (*path[-1], gyaw)
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


STOW_REACH, STOW_Z = 0.30, 1.0  # hand while driving: this far ahead of the base centre, this high [m]


def stow(d: Driver) -> None:
    """Raise the hand from home (0.52 m ahead at 0.75 m: table-top height, it sweeps objects off a
    table the base drives past) to 0.30 m ahead, 1.0 m high, inside the planner's footprint disc."""
    from stages.simulate.control import pose, top_down

    bx, by, th = base_pose(d.sim)
    at = np.array([bx + STOW_REACH * math.cos(th), by + STOW_REACH * math.sin(th), STOW_Z])
    d.move(pose(at, top_down(th - math.pi / 2)), 1.0, segments=2, tol=APPROACH_TOL)
