"""Recording an episode at 30 fps while the scripted expert drives the simulation.

:class:`Recorder` is a pre-step callback of the :class:`~stages.simulate.world.Sim`: frame ``k``
is captured at the first physics step whose time is at least ``k / fps`` (physics steps of 2 ms,
so a frame is at most one step late), before that step runs. A frame holds

- observation.state = [arm joint positions (7) [rad], end-effector pose in the base frame
  (7: x, y, z [m], quaternion w, x, y, z with w >= 0), base pose in the world (x, y [m], theta [rad])];
- action = the commands in force at that moment: [arm joint targets (7) [rad], end-effector target
  in the base frame (7; the forward kinematics of the arm targets), base velocity command
  (vx, vy [m/s], vtheta [rad/s]) in the base frame, gripper command (0 open .. 1 closed), mode
  (0 locomotion, 1 manipulation)];
- RGB and depth of the wrist, head and third-person cameras (depth in mm, uint16, lossless).

Frames go to a sink (the dataset's ``add_frame``) as they are captured; the recorder keeps the
per-stage wall times (:class:`Timings`: simulation, rendering, control, encoding, writing).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np

log = logging.getLogger(__name__)


class EpisodeTimeout(RuntimeError):
    """The episode ran past its time limit."""


#: the recording stages :class:`Timings` splits wall time into, in report order
STAGES = ("simulation", "rendering", "control", "encoding", "writing")


@dataclass
class Timings:
    """Wall time [s] per stage of recording: simulation (physics steps), rendering (cameras),
    control (expert: planning, IK, state reads), encoding (frame conversion and the writer's
    add_frame, which feeds the video encoders), writing (end of episode: parquet, video flush)."""

    simulation: float = 0.0
    rendering: float = 0.0
    control: float = 0.0
    encoding: float = 0.0
    writing: float = 0.0
    frames: int = 0

    def add(self, other: Timings) -> None:
        for k in (*STAGES, "frames"):
            setattr(self, k, getattr(self, k) + getattr(other, k))

    def to_json(self) -> dict:
        return {k: round(getattr(self, k), 4) for k in STAGES} | {"frames": self.frames}


@dataclass
class Commands:
    """The commands currently in force (what an action records). base_velocity (3,) base frame;
    gripper in [0, 1]; mode 0 locomotion / 1 manipulation; steady: the expert asks that its
    commands run without DART noise now (:mod:`stages.engine.action_noise`; not recorded);
    stop_distance: while the base follows a path, its distance to the path's end [m] (inf
    otherwise; not recorded: :attr:`stages.engine.action_noise.ActionNoise.base_quiet_radius`)."""

    base_velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gripper: float = 0.0
    mode: int = 0
    steady: bool = False
    stop_distance: float = math.inf

    def row(self) -> np.ndarray:
        """These commands as one record (:data:`COMMAND_ROW`,) float64: base_velocity (3), gripper,
        mode, steady (0 or 1), stop_distance: a row of the worker processes' shared record
        (:mod:`stages.engine.remote`) and of the engine's reads of the threads' commands."""
        return np.array([*np.asarray(self.base_velocity, float), self.gripper, self.mode, float(self.steady),
                         self.stop_distance], np.float64)


COMMAND_ROW = 7  # the length of Commands.row()


def quat_wxyz(rot: np.ndarray, ref: np.ndarray | None = None) -> np.ndarray:
    """Rotation matrix (3, 3) -> unit quaternion (w, x, y, z) in the hemisphere of ``ref`` (4,)
    (q . ref >= 0; None: w >= 0; see :func:`stages.simulate.batch_fk.pose7_batch`)."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(rot).as_quat()
    q = np.array([w, x, y, z])
    return -q if (w if ref is None else float(q @ np.asarray(ref, float))) < 0 else q


def pose7(m: np.ndarray, ref: np.ndarray | None = None) -> np.ndarray:
    """4x4 -> (7,) x, y, z, qw, qx, qy, qz (quaternion in the hemisphere of ``ref``, :func:`quat_wxyz`)."""
    return np.concatenate([m[:3, 3], quat_wxyz(m[:3, :3], ref)])


def base_pose(sim, world: int = 0) -> np.ndarray:
    """The base's world pose (x, y, theta) [m, rad] from its joint coordinates and the spawn pose."""
    jq = sim.state_0.joint_q.numpy()
    lx, ly, lyaw = (float(jq[sim.world_coord(n, world)]) for n in sim.desc.base_joints)
    x0, y0, yaw0 = sim.spawn
    c, s = math.cos(yaw0), math.sin(yaw0)
    th = (yaw0 + lyaw + math.pi) % (2 * math.pi) - math.pi
    return np.array([x0 + c * lx - s * ly, y0 + s * lx + c * ly, th])


def arm_q(sim, world: int = 0) -> np.ndarray:
    jq = sim.state_0.joint_q.numpy()
    return np.array([jq[sim.world_coord(n, world)] for n in sim.desc.arm_joints])


class Recorder:
    """Pre-step callback capturing frames at ``fps``. ``rig``: a CameraRig (None: no images, for
    success-rate runs without recording); ``sink``: called with each Frame (None: frames are
    dropped); ``max_seconds``: raise :class:`EpisodeTimeout` past this simulated time."""

    def __init__(self, sim, ik, ctl, cmd: Commands, *, rig=None, sink=None, fps: int = 30,
                 max_seconds: float = 30.0, camera_names: dict[str, str] | None = None) -> None:
        self.sim, self.ik, self.ctl, self.cmd = sim, ik, ctl, cmd
        self.rig, self.sink, self.fps = rig, sink, fps
        self.max_seconds = max_seconds
        self.camera_names = camera_names or {}
        self.timings = Timings()
        self.active = False
        self._next = 0
        self._q0 = ik.neutral()
        self._ref: np.ndarray | None = None
        self._last_t = None
        sim.pre_step.append(self)

    def start(self, max_seconds: float) -> None:
        """Begin an episode (after ``sim.reset``): frames from time 0."""
        self.max_seconds = max_seconds
        self.active, self._next, self.frames = True, 0, 0
        self._last_t = time.perf_counter()

    def stop(self) -> None:
        self.active = False

    def __call__(self, sim) -> None:
        if not self.active:
            return
        if sim.time > self.max_seconds:
            self.active = False
            raise EpisodeTimeout(f"episode ran past {self.max_seconds:.1f} s")
        if sim.time + 1e-9 < self._next / self.fps:
            return
        self._next += 1
        self.capture()

    def ee_in_base(self, arm: np.ndarray) -> np.ndarray:
        """(7,) pose of the end-effector in the base frame for arm joint positions ``arm`` (7,)."""
        if self._ref is None:  # the orientation at the arm's home pose: the engine's hemisphere too
            self._ref = pose7(self.ik.fk(self.ik.with_arm(self._q0, np.asarray(self.sim.desc.arm_home, float))))[3:]
        return pose7(self.ik.fk(self.ik.with_arm(self._q0, arm)), self._ref)

    def capture(self) -> None:
        from stages.dataset import Frame, depth_m_to_mm

        t0 = time.perf_counter()
        q = arm_q(self.sim)
        target = self.ctl.arm_targets()
        state = dict(arm_joint_pos=q, ee_pose=self.ee_in_base(q), base_pose=base_pose(self.sim),
                     arm_joint_target=target, ee_target=self.ee_in_base(target),
                     base_velocity=np.asarray(self.cmd.base_velocity, float), gripper=float(self.cmd.gripper),
                     mode=int(self.cmd.mode))
        t1 = time.perf_counter()
        rgb, depth = {}, {}
        if self.rig is not None:
            for name, fr in self.rig.render().items():
                key = self.camera_names.get(name, name)
                rgb[key] = fr.rgb[0]
                depth[key] = depth_m_to_mm(fr.depth[0])
        t2 = time.perf_counter()
        if self.sink is not None:
            self.sink(Frame(**state, rgb=rgb, depth_mm=depth))
        t3 = time.perf_counter()
        tm = self.timings
        tm.control += t1 - t0
        tm.rendering += t2 - t1
        tm.encoding += t3 - t2
        tm.frames += 1
        self.frames += 1
