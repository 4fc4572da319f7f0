"""Operator controls -> robot commands, one tick (one recorded frame) at a time.

A :class:`Tick` is what the operator held during one frame period (1 / fps [s]): base axes
(vx, vy, v_theta) and end-effector jog axes (x, y, z, roll, pitch, yaw), each in [-1, 1], the mode
(0 locomotion, 1 manipulation) and the gripper (0 open, 1 closed). :class:`TickApplier` turns it
into commands of the engine's world through the expert's :class:`~stages.demos.driver.Driver`:

- mode 0: base velocity = axes x (max_base_speed, max_base_speed, max_base_turn) in the base
  frame [m/s, m/s, rad/s]; the arm holds its targets.
- mode 1: the base stops; the end-effector target moves by jog axes x (max_jog_speed [m/s],
  max_jog_turn [rad/s]) x 1 / fps [s] in the base frame, and CLIK (the engine's Pinocchio solver,
  from the current joint state and arm targets) gives the arm joint targets; a target CLIK cannot
  reach within 5 mm / 3 degrees is not taken (the hand stops at the edge of the workspace).
- an end-effector pose (``ee``, from WebXR wrists: :mod:`stages.teleop.xr`): the base stops and
  CLIK takes the hand to that pose (4, 4, in the base frame) if it can within 5 mm / 3 degrees.
- gripper: the command as is (the parallel gripper's finger targets; a dexterous hand's closing
  synergy, :mod:`stages.simulate.hands`).
- hand (``hand``, from WebXR hand joints retargeted by :mod:`stages.teleop.hand_retarget`): a
  dexterous hand's joint targets [rad], in place of the gripper's synergy.

The applier is deterministic: the same ticks from the same reset give the same commands (this is
what ``--replay`` relies on).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True, kw_only=True)
class TeleopConfig:
    """Teleoperation settings.

    max_base_speed: base speed at full axis [m/s]; max_base_turn: base turn rate at full axis
    [rad/s]; max_jog_speed: end-effector speed at full jog axis [m/s]; max_jog_turn: its turn rate
    [rad/s]; fps: recorded (and streamed) frames per second; width, height: camera images [px];
    cameras: recorded cameras (wrist, head, third_person); episode_seconds: longest recorded
    episode [s] (then it is discarded as "timeout"); realtime: pace the simulation to the wall
    clock (False: as fast as it runs, for replays); device: "cpu" or "cuda[:n]"; seed: seed of
    the first episode's task instance (episode k: seed + k); jpeg_quality: streamed JPEG quality
    (1-95); input_device: what drives the session ("keyboard", "webxr", "replay"), recorded;
    command_timeout: controls older than this [s] count as released (axes to zero; the page repeats
    its controls every 0.1 s, so a stalled or vanished page stops the robot; None: never); hand:
    a dexterous hand on the Panda instead of its parallel gripper ("allegro" or "shadow"), driven
    by the WebXR hand's fingers; retarget: dex-retargeting's optimizer for it ("dexpilot": fingertip
    and thumb-to-finger vectors, keeps pinches; "vector": wrist-to-fingertip vectors); layout: the
    engine's layout ("auto": one MuJoCo C world on the CPU, whose frames render in threads beside
    the physics; on CUDA the batched layout: MuJoCo-Warp stepped as a CUDA graph, rendered on the
    GPU; "batched" on the CPU runs that GPU code path, rendering in the engine's thread as there)."""

    max_base_speed: float = 0.5
    max_base_turn: float = 1.0
    max_jog_speed: float = 0.15
    max_jog_turn: float = 0.8
    fps: int = 30
    width: int = 160
    height: int = 120
    cameras: tuple[str, ...] = ("wrist", "head", "third_person")
    episode_seconds: float = 300.0
    realtime: bool = True
    device: str = "cpu"
    seed: int = 0
    jpeg_quality: int = 80
    input_device: str = "keyboard"
    command_timeout: float | None = 1.0
    hand: str | None = None
    retarget: str = "dexpilot"
    layout: str = "auto"

    def __post_init__(self) -> None:
        problems = []
        for name in ("max_base_speed", "max_base_turn", "max_jog_speed", "max_jog_turn", "episode_seconds"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                problems.append(f"{name} must be a positive number, got {v}")
        if not 1 <= self.fps <= 120:
            problems.append(f"fps must be in [1, 120], got {self.fps}")
        if not (16 <= self.width <= 1920 and 16 <= self.height <= 1080):
            problems.append(f"image size {self.width}x{self.height} must be within 16x16 .. 1920x1080")
        if not 1 <= self.jpeg_quality <= 95:
            problems.append(f"jpeg_quality must be in [1, 95], got {self.jpeg_quality}")
        if self.input_device not in ("keyboard", "webxr", "replay"):
            problems.append(f"input_device must be keyboard, webxr or replay, got {self.input_device!r}")
        if not 0 <= self.seed < 2**62:
            problems.append(f"seed must be in [0, 2**62), got {self.seed}")
        if self.command_timeout is not None and not (math.isfinite(self.command_timeout) and self.command_timeout > 0):
            problems.append(f"command_timeout must be a positive number or None, got {self.command_timeout}")
        if self.hand not in (None, "allegro", "shadow"):
            problems.append(f"hand must be allegro, shadow or None, got {self.hand!r}")
        if self.retarget not in ("vector", "dexpilot"):
            problems.append(f"retarget must be vector or dexpilot, got {self.retarget!r}")
        if self.layout not in ("auto", "batched", "per_world"):
            problems.append(f"layout must be auto, batched or per_world, got {self.layout!r}")
        if problems:
            raise ValueError("teleop config: " + "; ".join(problems))


@dataclass(frozen=True)
class Tick:
    """One frame period's controls: base (3,) and jog (6,) axes in [-1, 1], mode 0/1, gripper 0/1;
    ee: an end-effector target (16 numbers, a row-major 4x4 in the base frame [m]) or None; hand:
    a dexterous hand's joint targets (n numbers [rad], its joint order) or None."""

    base: tuple[float, float, float] = (0.0, 0.0, 0.0)
    jog: tuple[float, ...] = (0.0,) * 6
    mode: int = 0
    gripper: int = 0
    ee: tuple[float, ...] | None = None
    hand: tuple[float, ...] | None = None

    def to_json(self) -> dict:
        d = {"base": list(self.base), "jog": list(self.jog), "mode": self.mode, "gripper": self.gripper}
        if self.ee is not None:
            d["ee"] = list(self.ee)
        if self.hand is not None:
            d["hand"] = list(self.hand)
        return d


class TickApplier:
    """Applies ticks to one episode's driver (see the module docstring); ``ik_misses`` counts jog
    targets CLIK could not reach."""

    POS_TOL, ROT_TOL = 0.005, math.radians(3.0)  # [m], [rad]

    def __init__(self, cfg: TeleopConfig, drv) -> None:
        self.cfg, self.drv = cfg, drv
        self.target: np.ndarray | None = None  # end-effector target (4, 4) in the robot root frame
        self.ik_misses = 0

    def apply(self, tick: Tick) -> None:
        d, cfg = self.drv, self.cfg
        d.cmd.mode = int(tick.mode)
        if tick.ee is not None:
            d.base((0.0, 0.0, 0.0))
            self._reach(np.asarray(tick.ee, float).reshape(4, 4))
        elif tick.mode == 0:
            b = tick.base
            d.base((b[0] * cfg.max_base_speed, b[1] * cfg.max_base_speed, b[2] * cfg.max_base_turn))
            self.target = None
        else:
            d.base((0.0, 0.0, 0.0))
            if any(tick.jog):
                self._jog(np.asarray(tick.jog, float))
            else:
                self.target = None  # re-seeded from the arm targets at the next jog
        d.cmd.gripper = float(tick.gripper)
        d.ctl.set_gripper(float(tick.gripper))
        if tick.hand is not None:
            d.ctl.set_finger_targets(np.asarray(tick.hand, float))

    def _q(self) -> np.ndarray:
        ik, d = self.drv.ik, self.drv
        return ik.with_arm(ik.from_sim(d.sim), d.ctl.arm_targets())

    def _reach(self, ee_base: np.ndarray) -> None:
        """CLIK to an end-effector pose in the base frame (4, 4)."""
        from stages.teleop.xr import base_to_root

        d, ik = self.drv, self.drv.ik
        q0 = self._q()
        qb = tuple(float(q0[ik.q_idx[n]]) for n in d.sim.desc.base_joints)
        res = ik.solve(base_to_root(qb) @ ee_base, q0, max_iters=300)
        self.target = None
        if res.position_error > self.POS_TOL or res.rotation_error > self.ROT_TOL:
            self.ik_misses += 1
            return
        d.ctl.set_arm_targets(ik.arm_q(res.q))

    def _jog(self, jog: np.ndarray) -> None:
        from scipy.spatial.transform import Rotation

        d, ik, cfg = self.drv, self.drv.ik, self.cfg
        q0 = self._q()
        if self.target is None:
            self.target = ik.fk(q0)
        dt = 1.0 / cfg.fps
        yaw = float(q0[ik.q_idx[d.sim.desc.base_joints[2]]])  # base yaw in the root frame [rad]
        c, s = math.cos(yaw), math.sin(yaw)
        r_base = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        goal = self.target.copy()
        goal[:3, 3] += r_base @ (jog[:3] * cfg.max_jog_speed * dt)
        rotvec = r_base @ (jog[3:] * cfg.max_jog_turn * dt)
        goal[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix() @ goal[:3, :3]
        res = ik.solve(goal, q0, max_iters=100)
        if res.position_error > self.POS_TOL or res.rotation_error > self.ROT_TOL:
            self.ik_misses += 1
            return
        self.target = goal
        d.ctl.set_arm_targets(ik.arm_q(res.q))
