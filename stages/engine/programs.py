"""The world-program side of the engine: one scripted-expert episode loop per world.

A :class:`WorldSide` runs the programs of some of the engine's worlds, in the engine's process
(coroutines) or in a worker process (:mod:`stages.engine.remote`), against world views
(:class:`~stages.engine.view.WorldView`) and command buffers. It talks to the engine through
arrays (episode step counters, recording flags, time limits) and ``emit(kind, world, payload)``
events, in order:

- ``("reset", w, coords)``: world-local joint coordinates of the next instance's start; the
  program then waits for the next synchronisation point, where the engine resets the world;
- ``("begin", w, ticket)``: an episode starts (the engine opens its frame sink);
- ``("stage", w, k)``: a multistage episode enters stage ``k`` (its next frames record it);
- ``("end", w, (ticket, result))``: it ended with an :class:`EpisodeResult`.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass

import numpy as np

from stages.demos.experts import EXPERTS, Driver, ExpertFailure
from stages.demos.multistage import MULTISTAGE, run_stages, sample_task, task_spec
from stages.demos.record import Commands, EpisodeTimeout
from stages.demos.sampling import object_coords

log = logging.getLogger(__name__)


@dataclass
class EpisodeResult:
    """success; reason: failure category ("" on success; "error" where the expert raised an
    unexpected exception, logged with its traceback: that episode fails, the run goes on); detail:
    message; frames recorded; sim_seconds: simulated time of the episode [s]; wall_seconds: from its
    reset to its end [s]."""

    success: bool
    reason: str
    detail: str
    frames: int
    sim_seconds: float
    wall_seconds: float


@dataclass(frozen=True)
class Ticket:
    """What the engine's process learns of an episode: task, seed, instruction, asset ids, the
    stages' instructions of a multistage task (empty otherwise) and the fixed world points of its
    environment state (:func:`stages.engine.env_state.episode_goal`)."""

    task: str
    seed: int
    instruction: str
    asset_ids: tuple[str, ...]
    subtasks: tuple[str, ...] = ()
    goal: tuple[float, ...] = ()  # fixed world points of its environment state (env_state.episode_goal)

    @classmethod
    def of(cls, inst) -> Ticket:
        from stages.engine.env_state import episode_goal

        ms = MULTISTAGE.get(inst.task)
        return cls(task=inst.task, seed=int(inst.seed), instruction=inst.instruction,
                   asset_ids=tuple(inst.asset_ids), subtasks=ms.subtasks if ms else (), goal=episode_goal(inst))


def instance_coords(inst, info, free: dict[str, int], scene_coord: dict[str, int]) -> dict[int, float]:
    """World-local joint coordinates of an instance's start: base joints (relative to the spawn
    pose ``info.spawn``), free objects (position, quaternion x, y, z, w) and scene joints."""
    values: dict[int, float] = {}
    x0, y0, yaw0 = info.spawn
    bx, by, byaw = inst.start_base
    cs, sn = math.cos(yaw0), math.sin(yaw0)
    dx, dy = bx - x0, by - y0
    local = (cs * dx + sn * dy, -sn * dx + cs * dy, byaw - yaw0)
    for name, v in zip(info.desc.base_joints, local, strict=True):
        values[info.robot.coord[name]] = v
    for body, pose in inst.objects.items():
        values.update(dict(enumerate(object_coords(pose), start=free[body])))
    for path, v in inst.joints.items():
        values[scene_coord[path]] = v
    return values


class _Rec:
    """What a Driver reads as its recorder: the frame rate."""

    def __init__(self, fps: int) -> None:
        self.fps = fps


class WorldSide:
    """Episode loops of worlds ``views`` (dict world -> view) with their ``controls``; ``ik``: a
    CLIK shared by the programs (one runs at a time); ``steps`` (W,) episode step counters,
    ``rec_active`` (W,) and ``rec_max`` (W,) recording flags and limits [steps], written here and
    read by the engine; ``lockstep``: the scheduler the programs park on; ``peaks``: start(w),
    stop(w), read(w) -> {joint path: peak}; ``emit``: the event callback; ``free`` /
    ``scene_coord``: world-local coordinates of free objects and scene joints."""

    def __init__(self, *, info, views: dict, controls: dict, ik, fps: int, steps_per_second: int,
                 steps: np.ndarray, rec_active: np.ndarray, rec_max: np.ndarray, lockstep, peaks, emit,
                 free: dict[str, int], scene_coord: dict[str, int], max_seconds: float | None = None,
                 act=None) -> None:
        self.info, self.views, self.controls, self.ik = info, views, controls, ik
        self.fps, self.steps_per_second = fps, steps_per_second
        self.steps, self.rec_active, self.rec_max = steps, rec_active, rec_max
        self.lockstep, self.peaks, self.emit = lockstep, peaks, emit
        self.free, self.scene_coord, self.max_seconds = free, scene_coord, max_seconds
        self.cmds = {w: Commands() for w in views}
        self.act = act

    def request_steps(self, w: int, n: int) -> None:
        """From world ``w``'s program: run ``n`` physics steps (episode time limit enforced)."""
        n = max(1, int(n))
        active = bool(self.rec_active[w])
        limit = int(self.rec_max[w])
        if active:
            left = limit + 1 - int(self.steps[w])
            if left <= 0:
                raise EpisodeTimeout(f"episode ran past {limit / self.steps_per_second:.1f} s")
            n = min(n, left)
        self.lockstep.wait_steps(w, n)
        if active and int(self.steps[w]) > limit:
            raise EpisodeTimeout(f"episode ran past {limit / self.steps_per_second:.1f} s")

    def program(self, w: int, next_instance):
        """World ``w``'s program: episodes from ``next_instance(w)`` until it returns None."""
        def main() -> None:
            while True:
                inst = next_instance(w)
                if inst is None:
                    return
                limit = None
                if isinstance(inst, tuple):
                    inst, limit = inst
                self.emit("reset", w, instance_coords(inst, self.info, self.free, self.scene_coord))
                self.lockstep.wait_sync(w)  # the engine resets this world at a sync point
                ticket = Ticket.of(inst)
                self.emit("begin", w, ticket)
                res = self.episode(w, inst, limit)
                self.emit("end", w, (ticket, res))
        return main

    def episode(self, w: int, inst, limit: float | None = None) -> EpisodeResult:
        from stages.simulate.state import read_state

        spec = task_spec(inst.task)
        ms = MULTISTAGE.get(inst.task)
        view, ctl = self.views[w], self.controls[w]
        cmd = self.cmds[w]
        cmd.base_velocity, cmd.gripper, cmd.mode, cmd.steady = np.zeros(3), 0.0, 0, False
        cmd.stop_distance = math.inf
        drv = Driver(view, ctl, self.ik, cmd, _Rec(self.fps), np.random.default_rng(inst.seed))
        t0 = time.perf_counter()
        if limit is None:
            limit = spec.max_seconds if self.max_seconds is None else self.max_seconds
        self.rec_max[w] = int(math.floor(limit * self.steps_per_second + 1e-9))
        self.rec_active[w] = 1
        self.peaks.start(w)
        reason = detail = ""
        try:
            if self.act is None and ms is not None:
                run_stages(ms, inst, drv, peaks=lambda: self.peaks.read(w),
                           on_stage=lambda k: self.emit("stage", w, k))
            elif self.act is None:
                EXPERTS[inst.task](inst, drv)
                drv.step(0.3)
            else:
                self.act(inst, drv)
        except ExpertFailure as e:
            reason, detail = e.reason, str(e)
        except EpisodeTimeout as e:
            reason, detail = "timeout", str(e)
        except Exception as e:  # noqa: BLE001 (a bug or bad instance fails its episode alone, not the run)
            reason, detail = "error", f"{type(e).__name__}: {e}"
            log.exception("world %d %s seed %d: the episode raised", w, inst.task, inst.seed)
        finally:
            self.rec_active[w] = 0
            self.peaks.stop(w)
            ctl.set_base_velocity(0.0, 0.0, 0.0)
        state = read_state(view)
        if not reason:
            ok, reason = spec.success(inst, state, peaks=self.peaks.read(w))
            detail = reason
        # frames: counted by the engine, which captures them (set when it receives the end event)
        res = EpisodeResult(success=not reason, reason=reason, detail=detail, frames=0,
                            sim_seconds=view.time, wall_seconds=time.perf_counter() - t0)
        log.info("world %d %s seed %d: %s %s (%.1f s sim)", w, inst.task, inst.seed,
                 "success" if res.success else "FAILED", detail, res.sim_seconds)
        return res



class RoundRobin:
    """An instance source for long runs and benchmarks (picklable, for worker processes): world
    ``w``'s ``k``-th episode is task ``tasks[(w + base + 7 k) mod len(tasks)]`` with seed
    ``1000 (w + base) + k`` in ``world`` (a kitchen)."""

    def __init__(self, world, tasks, base: int = 0) -> None:
        self.world, self.tasks, self.base = world, tuple(tasks), base
        self.count: dict[int, int] = {}

    def __call__(self, w: int):
        k = self.count.get(w, 0)
        self.count[w] = k + 1
        return sample_task(self.tasks[(w + self.base + 7 * k) % len(self.tasks)], self.world,
                               1000 * (w + self.base) + k)


class Listed:
    """An instance source from lists (picklable): ``queues`` world -> [(task, seed, max_seconds or
    None)], sampled in ``world`` (a kitchen) in order."""

    def __init__(self, world, queues: dict[int, list]) -> None:
        self.world = world
        self.queues = {w: list(q) for w, q in queues.items()}

    def __call__(self, w: int):
        q = self.queues.get(w)
        if not q:
            return None
        task, seed, limit = q.pop(0)
        inst = sample_task(task, self.world, seed)
        return inst if limit is None else (inst, limit)
