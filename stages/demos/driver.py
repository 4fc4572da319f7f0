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
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from stages.demos.planner import NavGrid, NoPathError, PathFollower, plan_path
from stages.demos.record import Commands, Recorder, base_pose

ROBOT_RADIUS = 0.40  # planning footprint radius of the base with the arm tucked [m]
APPROACH_TOL = 0.015  # CLIK position tolerance of free-space approach and retreat waypoints [m]
NEAR_STAGING = 0.15  # drive_to's staging distance where the one asked for is blocked for the planner [m]


@dataclass(frozen=True, kw_only=True)
class Pace:
    """How fast the scripted motions go. A hand move takes the longer of its distance over
    ``free_speed`` (free-space moves: a CLIK tolerance of at least APPROACH_TOL) or
    ``contact_speed`` (moves that end at or in contact) or ``carry_speed`` (a held object carried
    through free space) [m/s] and its rotation over ``turn_rate``
    [rad/s], at least ``min_move`` [s] and at most the duration the expert gives; it is stretched
    where an arm joint target would move faster than ``max_joint_speed`` [rad/s] (65% of the
    Panda's slowest joint limit, 2.175 rad/s). ``joint_speed`` [rad/s]: arm joint speed of
    joint-space moves (home). Waits end on conditions: a gripper once its fingers stop
    (``finger_still`` [m/s]), a settle once every arm joint is slower than ``arm_still``
    [rad/s] and within ``arm_near`` [rad] of its target; ``min_wait`` [s] before either is checked."""

    free_speed: float = 0.6
    contact_speed: float = 0.25
    carry_speed: float = 0.4
    turn_rate: float = 2.5
    min_move: float = 0.25
    joint_speed: float = 1.4
    max_joint_speed: float = 1.4
    finger_still: float = 0.005
    arm_still: float = 0.05
    arm_near: float = 0.01
    min_wait: float = 0.1


PACE = Pace()


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
    pace: Pace = PACE

    @property
    def frame_dt(self) -> float:
        return 1.0 / self.recorder.fps

    def step_count(self, seconds: float) -> int:
        """Physics steps that :meth:`step` runs for ``seconds`` [s] from the current step: to the
        frame step of the episode's frame grid (frame k at step ``ceil(k * S / fps)``, S = steps per
        second: the engine's frame steps when the episode started at a sync point) nearest to
        ``seconds`` on, at least one step on (a tie goes to the later one). Frames are 16 or 17
        steps apart at 500 steps/s and 30 fps: ``step(1 / fps)`` is one frame, and so is a request
        of 17 steps (0.034 s) that ends one step past a 16-step frame (taking the next frame step
        instead doubled it to 33 steps: every other base-shift command of the retreat from an
        oven door lasted two frames, the leaf dropped onto the slowed hand and open_oven missed
        its regrasp). Requests that end on frame steps let a batched engine advance all worlds a
        frame at a time (one round of the programs per frame; a world whose request ends between
        frames splits every frame into several engine steps). ``round(seconds / dt)`` (at least 1)
        when 1/dt is not a whole number of steps per second."""
        dt = self.sim.settings.dt
        S = 1.0 / dt
        if abs(S - round(S)) > 1e-6:
            return max(1, int(round(seconds / dt)))
        S, f, t = int(round(S)), self.recorder.fps, int(self.sim.steps)
        target = round(t + seconds / dt, 6)  # the requested end [steps]

        def at(k: int) -> int:  # frame k's step
            return -(-k * S // f)

        first = t * f // S + 1  # the first frame whose step is after t
        k = max(first, int(target * f // S))
        while k > first and at(k) > target:
            k -= 1
        while at(k + 1) <= target:
            k += 1
        # at(k): the last frame step not past the request (or the first one after t)
        if at(k) < target and at(k + 1) - target <= target - at(k):
            k += 1
        return at(k) - t

    def step(self, seconds: float) -> float:
        """Advance about ``seconds`` [s] (:meth:`step_count`: to the nearest frame step); returns the
        seconds actually stepped."""
        n = self.step_count(seconds)
        self.sim.step(n)
        return n * self.sim.settings.dt

    def base(self, v) -> None:
        self.cmd.base_velocity = np.asarray(v, float)
        self.ctl.set_base_velocity(*(float(x) for x in v))

    def _joint_speed(self, names) -> np.ndarray:
        qd = self.sim.state_0.joint_qd.numpy()
        return np.array([qd[self.sim.world_dof(n)] for n in names])

    def wait_until(self, done, seconds: float) -> None:
        """Step ``pace.min_wait`` [s], then frame by frame until ``done()`` holds, at most
        ``seconds`` [s] in all."""
        t_end = self.sim.time + seconds - 1e-9
        self.step(min(seconds, self.pace.min_wait))
        while self.sim.time < t_end and not done():
            self.step(self.frame_dt)

    @contextmanager
    def steady(self):
        """Within: the expert's commands run without DART noise (:mod:`stages.engine.action_noise`;
        without noise, no effect)."""
        self.cmd.steady = True
        try:
            yield
        finally:
            self.cmd.steady = False

    def grip(self, g: float, seconds: float = 0.6) -> None:
        """Gripper command ``g`` (0 open .. 1 closed); waits until the fingers stop (closed on
        the object or at their limit), at most ``seconds`` [s]."""
        self.cmd.mode = 1
        self.cmd.gripper = float(g)
        self.ctl.set_gripper(float(g))
        fingers = self.sim.desc.gripper.finger_joints
        self.wait_until(lambda: np.abs(self._joint_speed(fingers)).max() < self.pace.finger_still, seconds)

    def settle(self, seconds: float) -> None:
        """Wait until the arm has come to rest at its joint targets, at most ``seconds`` [s]."""
        from stages.demos.record import arm_q

        names = self.sim.desc.arm_joints

        def still() -> bool:
            p = self.pace
            return (np.abs(self._joint_speed(names)).max() < p.arm_still
                    and np.abs(arm_q(self.sim) - self.ctl.arm_targets()).max() < p.arm_near)

        self.wait_until(still, seconds)

    def move_time(self, target_world: np.ndarray, duration: float, tol: float, carry: bool = False) -> float:
        """The duration [s] of a hand move to ``target_world`` (4x4) by the :class:`Pace`, at most
        ``duration`` (``carry``: carrying a held object through free space)."""
        from stages.simulate.control import Clik

        cur = self.ik.fk(self.ik.with_arm(self.ik.from_sim(self.sim), self.ctl.arm_targets()))
        goal = Clik.world_to_root(self.sim.spawn, target_world)
        dist = float(np.linalg.norm(goal[:3, 3] - cur[:3, 3]))
        cos = (np.trace(cur[:3, :3].T @ goal[:3, :3]) - 1.0) / 2.0
        angle = float(np.arccos(np.clip(cos, -1.0, 1.0)))
        p = self.pace
        speed = p.carry_speed if carry else p.free_speed if tol >= APPROACH_TOL else p.contact_speed
        return min(duration, max(p.min_move, dist / speed, angle / p.turn_rate))

    def move(self, target_world: np.ndarray, duration: float, *, segments: int = 2, settle: float = 0.0,
             tol: float = 0.005, carry: bool = False, restarts: bool = True) -> None:
        """End-effector to ``target_world`` (4x4) along a straight line in at most ``duration``
        [s] (:meth:`move_time`), then :meth:`settle` up to ``settle`` [s]; every waypoint must be
        reached by CLIK within ``tol`` [m] (free-space approach moves use a looser tolerance than
        contact moves); ``carry``: a held object carried through free space (:class:`Pace`).
        ``restarts=False``: no CLIK restarts from random arm configurations where the solve from the
        current one stalls (a restart's solution on another branch of the arm is reached by a joint
        sweep, which swings a held object; the move fails ``ik_unreachable`` instead)."""
        from stages.simulate.control import move_ee

        self.cmd.mode = 1
        self.base((0.0, 0.0, 0.0))
        try:
            seconds = self.move_time(target_world, duration, tol, carry)
            move_ee(self.sim, self.ctl, self.ik, target_world, seconds, segments=segments,
                    rng=self.rng if restarts else None,
                    tol=tol, max_joint_speed=self.pace.max_joint_speed)
        except RuntimeError as e:
            if "unreachable" in str(e):
                raise ExpertFailure("ik_unreachable", str(e)) from None
            raise
        if settle > 0:
            self.settle(settle)

    def home(self, duration: float = 1.0) -> None:
        """Arm joint targets back to the tucked home configuration (linear in joint space) at
        ``pace.joint_speed``, in at most ``duration`` [s]."""
        self.cmd.mode = 1
        q0 = self.ctl.arm_targets()
        q1 = np.asarray(self.sim.desc.arm_home, float)
        p = self.pace
        duration = min(duration, max(p.min_move, float(np.abs(q1 - q0).max()) / p.joint_speed))
        n = max(1, int(duration / self.frame_dt))
        for k in range(1, n + 1):
            self.ctl.set_arm_targets(q0 + (q1 - q0) * k / n)
            self.step(self.frame_dt)

    def drive_to(self, goal: tuple[float, float, float], grid: NavGrid, *, approach: float = 0.35,
                 timeout: float = 15.0, tuck: np.ndarray | None = None) -> None:
        """Drive the base to ``goal`` (x, y, yaw): A* to a staging point ``approach`` [m] behind the
        goal (backed away from the furniture along the goal heading), then straight in; where that
        staging point is blocked for the planner (a tight floor: a wall behind the goal), from one
        NEAR_STAGING behind the goal. ``tuck``:
        arm joint targets (7,) [rad] the arm moves to while the base sets off (:func:`stow`)."""
        self.follow(self.plan_drive(goal, grid, approach=approach), goal[2], timeout=timeout, tuck=tuck)

    def plan_drive(self, goal: tuple[float, float, float], grid: NavGrid, *, approach: float = 0.35) -> np.ndarray:
        """The path (N, 2) [m] :meth:`drive_to` follows from the base's pose to ``goal`` (x, y, yaw), ending at
        the goal (planning time added to ``plan_seconds``); ExpertFailure("no_path") where none is found."""
        t0 = time.perf_counter()
        x, y, th = base_pose(self.sim)
        gx, gy, gyaw = goal
        stage = (gx - approach * math.cos(gyaw), gy - approach * math.sin(gyaw))
        try:
            path = plan_path(grid, (x, y), stage, ROBOT_RADIUS)
        except NoPathError as e:
            near = (gx - NEAR_STAGING * math.cos(gyaw), gy - NEAR_STAGING * math.sin(gyaw))
            try:
                if approach <= NEAR_STAGING:
                    raise
                path = plan_path(grid, (x, y), near, ROBOT_RADIUS)
            except NoPathError:
                raise ExpertFailure("no_path", str(e)) from None
        self.plan_seconds += time.perf_counter() - t0
        return np.vstack([path, [gx, gy]])

    def drive_straight(self, goal: tuple[float, float, float], *, timeout: float = 10.0) -> None:
        """Drive the base in a straight line to ``goal`` (x, y, yaw), no planning (the last metre
        in front of furniture, where the inflated grid is blocked)."""
        x, y, _ = base_pose(self.sim)
        self.follow(np.array([[x, y], goal[:2]], float), goal[2], timeout=timeout)

    def follow(self, path: np.ndarray, gyaw: float, *, timeout: float = 15.0, tuck: np.ndarray | None = None) -> None:
        """Follow ``path`` (N, 2) [m] to its end, turning to ``gyaw`` [rad]; mode 0 (locomotion).
        ``tuck``: arm joint targets (7,) [rad] reached linearly at ``pace.joint_speed`` meanwhile
        (from the start; a drive shorter than that waits for the arm). Meanwhile
        ``cmd.stop_distance`` is the base's distance to the path's end [m] (inf after)."""
        goal = (*path[-1], gyaw)
        follower = PathFollower(path, gyaw, dt=self.frame_dt)
        self.cmd.mode = 0
        t_end = self.sim.time + timeout
        arm = self._arm_ramp(tuck)
        try:
            while True:
                if arm:
                    self.ctl.set_arm_targets(arm.pop(0))
                t1 = time.perf_counter()
                pose = base_pose(self.sim)
                v, done = follower.command(*pose)
                self.plan_seconds += time.perf_counter() - t1
                self.cmd.stop_distance = math.hypot(goal[0] - pose[0], goal[1] - pose[1])
                self.base(v)
                if done:
                    break
                if self.sim.time > t_end:
                    self.base((0.0, 0.0, 0.0))
                    raise ExpertFailure("drive_timeout", f"base at {pose}, goal {goal}")
                self.step(self.frame_dt)
        finally:
            self.cmd.stop_distance = math.inf
        for q in arm:
            self.ctl.set_arm_targets(q)
            self.step(self.frame_dt)
        self.step(0.1)

    def _arm_ramp(self, q1: np.ndarray | None) -> list[np.ndarray]:
        """Arm joint targets per frame from the current ones linearly to ``q1`` at ``pace.joint_speed``."""
        if q1 is None:
            return []
        q0 = self.ctl.arm_targets()
        n = max(1, int(math.ceil(float(np.abs(q1 - q0).max()) / self.pace.joint_speed / self.frame_dt)))
        return [q0 + (q1 - q0) * k / n for k in range(1, n + 1)]


STOW_REACH, STOW_Z = 0.30, 1.0  # hand while driving: this far ahead of the base centre, this high [m]


def stow(d: Driver, *, on_the_way: bool = False) -> np.ndarray | None:
    """Raise the hand from home (0.52 m ahead at 0.75 m: table-top height, it sweeps objects off a
    table the base drives past) to 0.30 m ahead, 1.0 m high, inside the planner's footprint disc.
    ``on_the_way`` with the arm at home (an episode's start, in the open): only solve the tucked
    arm's joint targets and return them, for ``Driver.drive_to(tuck=...)`` to tuck while the base
    sets off (it moves under 0.4 m meanwhile); else (or when CLIK misses) tuck here, return None."""
    from stages.simulate.control import Clik, pose, top_down

    bx, by, th = base_pose(d.sim)
    at = np.array([bx + STOW_REACH * math.cos(th), by + STOW_REACH * math.sin(th), STOW_Z])
    target = pose(at, top_down(th - math.pi / 2))
    home = np.asarray(d.sim.desc.arm_home, float)
    if on_the_way and float(np.abs(d.ctl.arm_targets() - home).max()) < 0.05:
        q0 = d.ik.with_arm(d.ik.from_sim(d.sim), d.ctl.arm_targets())
        res = d.ik.solve(Clik.world_to_root(d.sim.spawn, target), q0, max_iters=600)
        if res.position_error <= APPROACH_TOL and res.rotation_error <= math.radians(2.0):
            return d.ik.arm_q(res.q)
    d.move(target, 1.0, segments=2, tol=APPROACH_TOL)
    return None
