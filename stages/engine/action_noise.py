"""Noise injected into what the robot executes while the scripted expert records (DART).

Behaviour cloning on clean demonstrations sees only states on the expert's path; a policy that
drifts off it (a few centimetres of base position) has never seen how to come back. DART (Laskey
et al. 2017, "DART: Noise Injection for Robust Imitation Learning") perturbs the execution at
recording time: each world executes its expert's command plus a random offset, while the frames
record the expert's clean command as the action and the measured (perturbed) state. The expert is
closed loop (it plans from the measured state), so the data shows states off the nominal path
labelled with the expert's corrections.

Per world in an episode, a draw of arm joint offsets (7,) [rad] ~ N(0, arm_std) and base velocity
offsets (3,) ~ N(0, base_std) [m/s, m/s, rad/s] is held ``hold_seconds`` of episode time, then
redrawn. The draws come from a generator seeded by (task, episode seed): a recording is the same
whatever other worlds run beside it. The offsets reach the simulation through
:meth:`stages.simulate.control.RobotControl.set_execution_offset` (added at the upload only);
``mode_aware``: base offsets only while the expert drives (mode 0, a nonzero base command), arm
offsets only in manipulation (mode 1). An expert may ask for none for a while
(:attr:`stages.demos.record.Commands.steady`, :meth:`stages.demos.driver.Driver.steady`: the
drawer's grasp, so that the fingers close with the hand on the bar); the draws go on in order.
``base_quiet_radius`` [m]: no base offsets while the base is within this distance of the end of
the path it follows (:attr:`stages.demos.record.Commands.stop_distance`): the drive is perturbed,
its arrival is not (session 25: base noise up to the stop taught policies to keep driving there).
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass

import numpy as np

_SALT = zlib.crc32(b"action_noise")


@dataclass(frozen=True, kw_only=True)
class ActionNoise:
    """arm_std: standard deviation of each arm joint's offset [rad]; base_std: of the base
    velocity offsets (vx, vy [m/s], vtheta [rad/s]) in the base frame; hold_seconds: each draw is
    held this long [s] of episode time, then redrawn; mode_aware: base offsets only while the base
    is driven (mode 0 with a nonzero base command), arm offsets only in manipulation (mode 1)
    (False: both always); base_quiet_radius: no base offsets within this distance [m] of the
    stop of the drive in progress (0: none kept quiet)."""

    arm_std: float = 0.02
    base_std: tuple[float, float, float] = (0.05, 0.05, 0.1)
    hold_seconds: float = 0.3
    mode_aware: bool = True
    base_quiet_radius: float = 0.0

    def __post_init__(self) -> None:
        stds = (self.arm_std, *self.base_std)
        if len(self.base_std) != 3:
            raise ValueError(f"action noise: base_std needs 3 values (vx, vy, vtheta), got {self.base_std}")
        if not all(math.isfinite(s) and s >= 0 for s in stds):
            raise ValueError(f"action noise: standard deviations must be finite and >= 0, got arm_std "
                             f"{self.arm_std}, base_std {self.base_std}")
        if not (math.isfinite(self.base_quiet_radius) and self.base_quiet_radius >= 0):
            raise ValueError(f"action noise: base_quiet_radius must be >= 0 [m], got {self.base_quiet_radius}")
        if not (math.isfinite(self.hold_seconds) and self.hold_seconds > 0):
            raise ValueError(f"action noise: hold_seconds must be > 0 [s], got {self.hold_seconds}")


def noise_rng(task: str, seed: int) -> np.random.Generator:
    """The noise generator of the episode of ``task`` with episode seed ``seed`` (its own stream:
    the expert's generator of the same seed draws nothing of it)."""
    return np.random.default_rng([int(seed) % (1 << 63), zlib.crc32(task.encode()), _SALT])


class NoiseProcess:
    """The offsets of ``worlds`` worlds (7 arm joints each) under ``cfg`` at ``steps_per_second``
    physics steps per second. :meth:`begin` / :meth:`end` bracket a world's episode; draw ``j``
    of an episode is in force over its steps ``[j H, (j + 1) H)`` (H = hold steps)."""

    def __init__(self, cfg: ActionNoise, worlds: int, steps_per_second: int, arm_joints: int = 7) -> None:
        self.cfg = cfg
        self.hold_steps = max(1, int(round(cfg.hold_seconds * steps_per_second)))
        self._rng: list[np.random.Generator | None] = [None] * worlds
        self._index = np.full(worlds, -1, np.int64)  # the draw in force
        self.arm = np.zeros((worlds, arm_joints))  # the current draws [rad]
        self.base = np.zeros((worlds, 3))  # [m/s, m/s, rad/s]

    def begin(self, w: int, task: str, seed: int) -> None:
        """World ``w`` starts an episode (at its step 0)."""
        self._rng[w] = noise_rng(task, seed)
        self._index[w] = -1
        self.arm[w] = self.base[w] = 0.0

    def end(self, w: int) -> None:
        self._rng[w] = None
        self.arm[w] = self.base[w] = 0.0

    def active(self, w: int) -> bool:
        return self._rng[w] is not None

    def steps_to_redraw(self, step: int) -> int:
        """Steps from episode step ``step`` to the next draw (1 .. H)."""
        return self.hold_steps - int(step) % self.hold_steps

    def offsets(self, w: int, step: int, mode: int | None = None,
                base_cmd=None) -> tuple[np.ndarray, np.ndarray]:
        """World ``w``'s arm (7,) [rad] and base (3,) offsets at episode step ``step``, given the
        expert's mode (0 locomotion, 1 manipulation) and base command (3,) (``mode_aware``).
        Draws are taken in order (arm, then base), the same whichever offsets the mode gates."""
        rng = self._rng[w]
        if rng is None:
            return np.zeros(self.arm.shape[1]), np.zeros(3)
        j = int(step) // self.hold_steps
        while self._index[w] < j:
            self.arm[w] = rng.normal(0.0, 1.0, self.arm.shape[1]) * self.cfg.arm_std
            self.base[w] = rng.normal(0.0, 1.0, 3) * np.asarray(self.cfg.base_std, float)
            self._index[w] += 1
        arm, base = self.arm[w].copy(), self.base[w].copy()
        if self.cfg.mode_aware:
            driving = mode == 0 and base_cmd is not None and bool(np.any(np.asarray(base_cmd) != 0))
            if mode != 1:
                arm[:] = 0.0
            if not driving:
                base[:] = 0.0
        return arm, base


def apply_noise(engine, k: int) -> int:
    """Before ``engine`` (a :class:`~stages.engine.BatchEngine` with an ``action_noise``) steps
    ``k`` physics steps: set every world's execution offsets for its current step (zero for worlds
    not recording an episode) and return ``k`` cut at the first redraw of a stepping world."""
    proc: NoiseProcess = engine.noise
    moving = [w for w in range(len(engine.held)) if not engine.held[w]]
    live = [w for w in moving if proc.active(w) and engine.rec_active[w]]
    base_v, modes, steady, stop = engine.capture.noise_inputs(live) if live else (None, [], [], np.zeros(0))
    radius = proc.cfg.base_quiet_radius
    near = (stop < radius).tolist() if radius > 0 else [False] * len(live)
    row = {w: j for j, w in enumerate(live)}
    for w in moving:
        bank, i = engine._where[w]
        j = row.get(w)
        if j is None:
            bank.ctl.set_execution_offset(i)
            continue
        step = int(engine.steps[w])
        arm, base = proc.offsets(w, step, modes[j], base_v[j])  # drawn even when steady: the stream stays in order
        if near[j]:
            base = np.zeros(3)
        bank.ctl.set_execution_offset(i, *((None, None) if steady[j] else (arm, base)))
        k = min(k, proc.steps_to_redraw(step))
    return k
