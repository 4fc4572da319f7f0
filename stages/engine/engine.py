"""The batched demonstration engine: many task worlds in one simulation, episodes independent.

``worlds`` copies of a task world (a kitchen: :class:`~stages.demos.kitchen.KitchenWorld`) are one
Newton model stepped together (MuJoCo-Warp on CPU and CUDA alike, so a world's trajectory does not
depend on how many worlds run beside it; on CUDA the step replays as a CUDA graph). Every world runs
its own sequence of episodes: the engine asks ``next_instance(world)`` for a task instance, resets
that world alone (solver buffers, joints, objects, drive targets: the others keep running), runs
the task's scripted expert (:mod:`stages.demos.experts`) as the world's program
(:mod:`stages.engine.lockstep`), records its frames into the sink ``begin(world, instance)``
returned, evaluates the task's success predicate and reports through ``end(world, instance,
result)``; then the world takes its next instance, until ``next_instance`` returns None.

Per step, the engine's work is batched over worlds: one upload of the drive targets and base
commands, one kernel for the base velocity drives, one for the watched joints' peaks (a pressed
button), the physics step; per recorded frame, one render of every camera in every world and one
read of the state. Programs run between steps only when their requests are met (planning, IK at
waypoints: at phase changes).

Clocks: physics steps of ``dt`` [s]; frame ``k`` of an episode is captured before local step
``ceil(k * S / fps)`` (S = 1 / dt steps per second). Worlds start episodes only at synchronisation
points, every ``P = S / gcd(S, fps)`` steps, so every world's frames fall on the same global steps
and one render serves them all.

::

    eng = BatchEngine(kitchen, panda_root=None, work_dir=d, config=EngineConfig(worlds=4))
    eng.run(next_instance=lambda w: queue[w].pop() if queue[w] else None,
            begin=lambda w, inst: shard[w].add_frame, end=lambda w, inst, res: ...)
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from stages.demos.experts import timed_clik
from stages.demos.kitchen import FREE_ROLES, watched_joints
from stages.demos.record import Timings
from stages.engine.action_noise import ActionNoise, NoiseProcess, apply_noise
from stages.engine.capture import FrameCapture
from stages.engine.env_state import ticket_keys
from stages.engine.lockstep import Lockstep
from stages.engine.peaks import LocalPeaks, Peaks
from stages.engine.programs import EpisodeResult, WorldSide
from stages.engine.view import SimInfo, Snapshot, WorldControl, WorldView, _WorldModel

log = logging.getLogger(__name__)

CAMERAS = ("wrist", "head", "third_person")


@dataclass(frozen=True, kw_only=True)
class EngineConfig:
    """worlds: worlds stepped together; device: "cpu" or "cuda[:n]"; width, height: camera image
    size [px]; fps: recorded frames per second; record_images: render the cameras (False: state and
    action only); record_depth: with record_images, record each camera's depth too (False: RGB
    only; the render still makes depth, the recorder drops it); video_gop: keyframe interval of the
    recorded RGB videos [frames] (the dataset spec's VideoCodecSpec.gop); cameras: names of the
    recorded cameras (wrist, head, third_person);
    layout: "batched" (one model of ``worlds`` worlds, MuJoCo-Warp: the GPU layout), "per_world"
    (one single-world model per world, the MuJoCo C library: on a CPU it is several times faster
    than MuJoCo-Warp's CPU path) or "auto" (batched on CUDA, per_world on CPU);
    max_seconds: episode time limit [s] (None: the task's); program_procs: run the worlds' programs
    (experts: planning, IK) in this many worker processes (0: coroutines in the engine's process; the
    batched layout only); program_wait: with program_procs, how long [s] the engine waits for a
    batch of programs before it holds the worlds whose programs are still running
    (:mod:`stages.engine.hold`: the others step on, a held world's episode is unchanged) — None
    waits for every program (one planning world then stalls all); program_yield: with
    program_procs, a program that has run this long [s] since it was resumed parks at its next
    checkpoint (:mod:`stages.simulate.cooperative`: between IK solves, before a path search) and its
    worker tells the engine, which then holds its world without waiting ``program_wait`` for it;
    the worker runs its other worlds' requests first and goes on with the parked program when
    none is left (None: programs run to their next request); gripper: the Panda's end effector
    (``stages.simulate.robot.GripperKind``: panda_hand, robotiq_2f85, or a dexterous hand, allegro
    or shadow, whose joint positions and targets the frames then carry: ``DatasetSpec.hand_joints``);
    subtasks: frames record the stage of a multistage task (``subtask_index``; set it when any task
    is multistage); background_render: on the CPU, render each frame in a thread of its own from a
    copy of the body poses while the physics steps run on (:mod:`stages.simulate.compact`: the same
    images), and deliver the frame as soon as its render is done (teleop: the frames reach the page
    sooner; False: each render runs in the engine's thread); action_noise: execute every
    episode's commands with DART noise while the frames record the clean ones
    (:mod:`stages.engine.action_noise`; None: none); environment_state: the names of the task objects'
    state every frame records (``observation.environment_state``, :mod:`stages.engine.env_state`:
    ``state_names(task)``; every episode's task must have that layout; empty: none recorded)."""

    def resolved_layout(self) -> str:
        if self.layout != "auto":
            return self.layout
        return "batched" if self.device.startswith("cuda") else "per_world"

    worlds: int = 4
    device: str = "cpu"
    width: int = 128
    height: int = 96
    fps: int = 30
    record_images: bool = True
    record_depth: bool = True
    video_gop: int = 30
    cameras: tuple[str, ...] = CAMERAS
    layout: str = "auto"
    max_seconds: float | None = None
    program_procs: int = 0
    program_wait: float | None = None
    program_yield: float | None = 0.002
    gripper: str = "panda_hand"
    subtasks: bool = False
    background_render: bool = False
    action_noise: ActionNoise | None = None
    environment_state: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.layout not in ("auto", "batched", "per_world"):
            raise ValueError(f"engine: layout must be auto, batched or per_world, got {self.layout!r}")
        if self.worlds < 1:
            raise ValueError(f"engine: worlds must be >= 1, got {self.worlds}")
        if self.program_procs and self.resolved_layout() != "batched":
            raise ValueError("engine: program_procs needs the batched layout (one model of all worlds)")
        if self.program_wait is not None and (not self.program_procs or self.program_wait < 0):
            raise ValueError("engine: program_wait needs program_procs and must be >= 0 [s]")
        if self.program_yield is not None and self.program_yield < 0:
            raise ValueError(f"engine: program_yield must be >= 0 [s] or None, got {self.program_yield}")
        if self.gripper not in ("panda_hand", "robotiq_2f85", "allegro", "shadow"):
            raise ValueError(f"engine: gripper must be panda_hand, robotiq_2f85, allegro or shadow, "
                             f"got {self.gripper!r}")
        bad = set(self.cameras) - set(CAMERAS)
        if bad:
            raise ValueError(f"engine: unknown cameras {sorted(bad)}; known {CAMERAS}")

    def dataset_spec(self):
        """The dataset spec of what the engine records (3 cameras RGB + depth, RGB only without
        ``record_depth``, or none)."""
        from stages.dataset import CameraSpec, DatasetSpec, VideoCodecSpec

        cams = self.cameras if self.record_images else ()
        cameras = tuple(CameraSpec(c, height=self.height, width=self.width, depth=self.record_depth) for c in cams)
        return DatasetSpec(fps=self.fps, cameras=cameras, hand_joints=self.hand_joints(), subtasks=self.subtasks,
                           video=VideoCodecSpec(gop=self.video_gop), environment_state=self.environment_state)

    def hand_joints(self) -> tuple[str, ...]:
        """The dexterous hand's joints (control order), or () for a parallel gripper."""
        from stages.simulate.hands import allegro_info, shadow_info

        infos = {"allegro": allegro_info, "shadow": shadow_info}
        return infos[self.gripper]().joints if self.gripper in infos else ()


@dataclass(eq=False)
class _WorldRec:
    """A world's recording on the engine's side: its frame sink, the frames captured and the stage
    of a multistage task its frames are in."""

    frames: int = 0
    sink: Callable | None = None
    subtask: int = 0
    env: object = None  # the episode's EnvKeys (stages.engine.env_state), with environment_state


@dataclass(eq=False)
class _Bank:
    """One Sim of the engine: its control, state snapshot, per-world model arrays, cameras and
    peaks; its worlds are engine worlds ``first .. first + count - 1``."""

    sim: object
    ctl: object
    snapshot: Snapshot
    model: _WorldModel
    first: int
    count: int
    rig: object = None
    peaks: object = None
    hold: object = None  # WorldHold (batched layout)
    joint_world: np.ndarray | None = None  # model.joint_world on the host (read once)


@dataclass
class EngineStats:
    """Totals of a run: timings per stage [s] (simulation: physics steps and per-step kernels;
    rendering; control: programs' time between steps, planning and IK included; encoding: frame
    assembly and the sinks), physics steps, frames rendered, state reads, episodes, worlds."""

    timings: Timings = field(default_factory=Timings)
    steps: int = 0
    renders: int = 0
    episodes: int = 0
    worlds: int = 0
    startup_seconds: float = 0.0  # starting worker processes (program_procs)
    holds: int = 0  # worlds held while their programs ran (stages.engine.hold)
    held_steps: int = 0  # global steps those worlds stood still, summed
    yields: int = 0  # programs that parked planning (program_yield), held without a wait
    advances: int = 0  # engine steps (each: one round of the programs, then k physics steps)

    def to_json(self) -> dict:
        return {"timings": self.timings.to_json(), "steps": self.steps, "renders": self.renders,
                "episodes": self.episodes, "worlds": self.worlds,
                "startup_seconds": round(self.startup_seconds, 3), "holds": self.holds,
                "held_steps": self.held_steps, "yields": self.yields, "advances": self.advances}


def device_scope(device: str):
    """A context in which ``device`` is Warp's default device: "cuda:N" on a host of several GPUs
    keeps every allocation of an engine (and of the libraries under it that take Warp's default)
    on that GPU; a no-op for "cpu" and "cuda"."""
    import contextlib

    if not device.startswith("cuda:"):
        return contextlib.nullcontext()
    import warp as wp

    return wp.ScopedDevice(device)


class BatchEngine:
    """``config.worlds`` worlds of one task world in one simulation (see the module docstring).
    ``panda_root``: the Panda description's package root (None: pip example-robot-data)."""

    def __init__(self, world, *, panda_root: Path | None, work_dir: Path, config: EngineConfig,
                 seed: int = 0) -> None:
        from stages.simulate.robot import find_panda_description, write_robot_urdf

        t0 = time.perf_counter()
        self.world, self.config = world, config
        desc = write_robot_urdf(Path(work_dir) / "robot", panda_root=find_panda_description(panda_root),
                                gripper=config.gripper)
        n = config.worlds
        if config.resolved_layout() == "batched":
            self.banks = [self._bank(desc, n, 0, seed)]
        else:
            self.banks = [self._bank(desc, 1, w, seed) for w in range(n)]
        self._where = [(b, i) for b in self.banks for i in range(b.count)]
        self.ik = timed_clik(desc)
        sim = self.banks[0].sim
        self.info = SimInfo.of(sim)
        # per-world arrays shared with the world programs (shared memory with program_procs)
        self.steps = np.zeros(n, np.int64)  # physics steps since each world's episode started
        self.rec_active = np.zeros(n, np.int8)
        self.rec_max = np.zeros(n, np.int64)
        self.recs = [_WorldRec() for _ in range(n)]
        self.lockstep = Lockstep(n)
        steps_per_s = 1.0 / sim.settings.dt
        if abs(steps_per_s - round(steps_per_s)) > 1e-6:
            raise ValueError(f"engine: physics step {sim.settings.dt} s must divide one second")
        self.steps_per_second = int(round(steps_per_s))
        self.sync_period = self.steps_per_second // math.gcd(self.steps_per_second, config.fps)
        self.global_step = 0
        self.capture = FrameCapture(self, self._handle_event)
        self._free = {}
        qs = self.banks[0].model.joint_q_start.numpy()
        child = self.banks[0].model.joint_child.numpy()
        for k, p in world.placed.items():
            if k in FREE_ROLES:
                b = sim.body_of_path(p.body())
                self._free[p.body()] = int(qs[int(np.nonzero(child == b)[0][0])])
        for body in getattr(world, "drink", ()):  # the drink's spheres (stages.demos.skill_pour)
            self._free[body] = int(qs[int(np.nonzero(child == sim.body_of_path(body))[0][0])])
        self._scene_coord = {p: int(qs[j]) for j, p in sim.scene.joint_path.items()}
        self.watched = watched_joints(world)
        for b in self.banks:
            b.peaks = Peaks(b.sim, self.watched, self._scene_coord)
        self._pending_reset: dict[int, dict[int, float]] = {}
        # held worlds (stages.engine.hold): since which global step; the hold policy of the
        # threaded engine (benchmarks, tests): hold_policy(world, resume_index) -> sync periods
        self.held = np.zeros(n, bool)
        self.held_at = np.zeros(n, np.int64)
        self.hold_policy: Callable | None = None
        self._release_at: dict[int, int] = {}
        self._policy_done: set[int] = set()
        self._resumes = np.zeros(n, np.int64)
        if config.resolved_layout() == "batched":
            from stages.engine.hold import WorldHold

            for b in self.banks:
                b.hold = WorldHold(b.sim)
        self._begin = self._end = None
        self.side: WorldSide | None = None
        self.stats = EngineStats(worlds=n)
        self.noise = None if config.action_noise is None else NoiseProcess(
            config.action_noise, n, self.steps_per_second, len(desc.arm_joints))
        self.build_seconds = time.perf_counter() - t0

    def _bank(self, desc, count: int, first: int, seed: int) -> _Bank:
        """A Sim of ``count`` worlds (engine worlds ``first`` ...) with its controls and cameras."""
        from stages.simulate.control import RobotControl
        from stages.simulate.world import SimConfig, SolverSettings, build_sim

        cfg = self.config
        # batched: MuJoCo-Warp for any world count, so a world's trajectory does not depend on how
        # many run beside it; per_world: MuJoCo C (one world per model)
        # a world may ask for multi-CCD contacts (a bedroom: light things crept on the blanket's hull)
        solver = SolverSettings(use_mujoco_cpu=False if cfg.resolved_layout() == "batched" else None,
                                multiccd=bool(getattr(self.world, "multiccd", False)))
        sim = build_sim(SimConfig(scenes=(self.world.usd,), spawn=self.world.spawn, device=cfg.device,
                                  world_count=count, solver=solver), desc, np.random.default_rng(seed))
        bank = _Bank(sim=sim, ctl=RobotControl(sim), snapshot=Snapshot(sim), model=_WorldModel(sim),
                     first=first, count=count)
        bank.rig = self._rig(sim, desc) if cfg.record_images else None
        return bank

    def _rig(self, sim, desc):
        from stages.simulate.sensors import CameraRig, CameraSpec, look_at

        c = self.config
        cams = [CameraSpec(name=n, width=c.width, height=c.height, vertical_fov=desc.cameras[n].vertical_fov,
                           link=desc.cameras[n].link) for n in ("wrist", "head") if n in c.cameras]
        if "third_person" in c.cameras:
            sx, sy = self.world.size
            view = getattr(self.world, "third_person_view", None)  # a world's own view (a house's room)
            eye, target = view() if view is not None else ((0.3, 0.3, 2.3), (0.6 * sx, 0.6 * sy, 0.6))
            cams.append(CameraSpec(name="third_person", width=c.width, height=c.height, vertical_fov=1.0,
                                   pose=look_at(eye, target)))
        return CameraRig(sim, cams, segmentation=False, background=c.background_render)

    # -- the run ----------------------------------------------------------------------------
    def run(self, next_instance: Callable, *, begin: Callable | None = None,
            end: Callable | None = None, max_steps: int | None = None,
            act: Callable | None = None) -> EngineStats:
        """Run episodes in every world until ``next_instance(world)`` returns None for all of
        them. ``begin(world, instance)`` returns the episode's frame sink (or None: frames
        dropped); ``end(world, instance, EpisodeResult)`` is called when it ends. Both run in the
        engine's thread, one world at a time, in a deterministic order, after the frames captured
        before them were delivered (:mod:`stages.engine.capture`). ``next_instance``
        may return ``(instance, max_seconds)`` to give that episode its own time limit [s].
        ``max_steps``: stop after this many physics steps (episodes in progress are abandoned:
        neither ``end`` nor a result; for benchmarks). ``act(instance, driver)``: what drives each
        episode in place of the task's scripted expert (teleoperation; threads only, not with
        ``program_procs``)."""
        stop_at = None if max_steps is None else self.global_step + max_steps
        self._begin, self._end = begin, end
        self.rec_active[:] = 0  # episodes a previous run abandoned (max_steps) record no more frames
        for rec in self.recs:
            rec.sink = None
        self.__dict__.pop("_views", None)
        if act is not None and self.config.program_procs:
            raise ValueError("engine: act (a custom episode driver) runs in threads, not with program_procs")
        if self.config.program_procs:
            from stages.engine.remote import RemotePrograms

            t0 = time.perf_counter()
            ls = self.lockstep = RemotePrograms(self, next_instance)
            self.stats.startup_seconds += time.perf_counter() - t0
        else:
            ls = self.lockstep = Lockstep(self.config.worlds)
            self.side = self._local_side(ls)
            self.side.act = act
            for w in range(self.config.worlds):
                ls.start(w, self.side.program(w, next_instance))
        try:
            while ls.alive():
                t0 = time.perf_counter()
                self._release_due()
                self._apply_hold_policy()
                ls.resume_ready(skip=self.held)
                self.stats.timings.control += time.perf_counter() - t0
                if not ls.alive() or (stop_at is not None and self.global_step >= stop_at):
                    break
                if self._reset_due():
                    continue
                self.capture.collect()
                self._advance([w for w in ls.waiting_sync() if not self.held[w]])
                self._reset_due()  # before the render, so that reset worlds record this frame
                self.capture.launch()  # the GPU renders while the programs and steps run on
        finally:
            self.capture.close()
            ls.shutdown()
        return self.stats

    def _reset_due(self) -> bool:
        """At a sync point, reset the worlds waiting for it (not held) and let their programs go
        on. Not once this step's render is in flight (every step but the first launches one before
        the programs run): a world that asks then is reset at the next sync point, before its
        render, so that every episode records its first frame."""
        ls = self.lockstep
        if self.capture.launched_step == self.global_step:
            return False
        sync = [w for w in ls.waiting_sync() if not self.held[w]]
        if not sync or self.global_step % self.sync_period:
            return False
        self._reset_worlds(sync)
        ls.release_sync(sync)
        return True

    def _local_side(self, ls) -> WorldSide:
        """The world programs as coroutines of this process (:class:`Lockstep`)."""
        n = self.config.worlds
        views = {w: WorldView(None, w, b, i, b.model, self.steps) for w, (b, i) in enumerate(self._where)}
        side = WorldSide(info=self.info, views=views,
                         controls={w: WorldControl(b.ctl, i) for w, (b, i) in enumerate(self._where)},
                         ik=self.ik, fps=self.config.fps, steps_per_second=self.steps_per_second,
                         steps=self.steps, rec_active=self.rec_active, rec_max=self.rec_max, lockstep=ls,
                         peaks=LocalPeaks(self), emit=self.on_event, free=self._free,
                         scene_coord=self._scene_coord, max_seconds=self.config.max_seconds)
        for v in views.values():
            v._engine = side
        assert len(views) == n
        return side

    def on_event(self, kind: str, w: int, payload) -> None:
        """An event of world ``w``'s program (see :mod:`stages.engine.programs`)."""
        if self.noise is not None and kind == "begin":  # at once (not deferred): before the next step
            self.noise.begin(w, payload.task, payload.seed)
        elif self.noise is not None and kind == "end":
            self.noise.end(w)
        if kind == "reset":
            self._pending_reset[w] = payload
        elif kind in ("begin", "end", "stage"):
            if not self.capture.defer(kind, w, payload):  # after the frames collected before it
                self._handle_event(kind, w, payload)
        else:
            raise ValueError(f"engine: unknown event {kind!r} from world {w}")

    def _handle_event(self, kind: str, w: int, payload) -> None:
        if kind == "stage":  # the frames collected from here on are in stage ``payload``
            self.recs[w].subtask = int(payload)
        elif kind == "begin":
            self.recs[w].frames = 0
            self.recs[w].subtask = 0
            self.recs[w].sink = self._begin(w, payload) if self._begin is not None else None
            if self.config.environment_state:
                self.recs[w].env = ticket_keys(self, payload)
        elif kind == "end":
            ticket, res = payload
            res.frames = self.recs[w].frames
            self.recs[w].sink = None
            self.stats.episodes += 1
            if self._end is not None:
                self._end(w, ticket, res)

    def _advance(self, sync: list[int]) -> None:
        """Step every world by the largest count that meets no request, sync point, frame or
        held world's release point; held worlds stand still."""
        ls = self.lockstep
        held = self.held
        P = self.sync_period
        k = ls.min_pending(skip=held) or P
        if sync:
            k = min(k, P - self.global_step % P)
        # held worlds whose programs have answered release at whole periods of holding (those still
        # planning do not cut the step count: one that answers mid-way waits for the next period)
        ready = [w for w in np.nonzero(held)[0] if not ls.running(int(w))]
        if ready:
            k = min(k, int((P - (self.global_step - self.held_at[ready]) % P).min()))
        if self.noise is not None:  # execution offsets set, k cut at the next redraw
            k = apply_noise(self, k)
        k = max(1, min(k, self._next_frame_step() - self.global_step))
        # a frame rendering in the background (background_render): steps one at a time until its
        # render is done, then the frame is delivered and the rest of the steps run at once
        left, sim_s = k, 0.0
        while left:
            bg = self.config.background_render and self.capture.pending
            n = 1 if bg else left
            t0 = time.perf_counter()
            for b in self.banks:
                if b.hold is None and held[b.first:b.first + b.count].all():
                    continue  # per-world layout: a held world's model simply does not step
                b.sim.step(n)
                b.snapshot.invalidate()
            sim_s += time.perf_counter() - t0
            left -= n
            if bg:
                self.capture.deliver_ready()
        self.stats.timings.simulation += sim_s
        self.stats.steps += k
        self.stats.advances += 1
        self.global_step += k
        self.steps[~held] += k
        ls.advance(k, skip=held)

    # -- holding worlds (stages.engine.hold) ------------------------------------------------
    def hold(self, worlds) -> None:
        """Hold ``worlds`` still from the current step (their programs are still running)."""
        worlds = [int(w) for w in worlds if not self.held[int(w)]]
        for b in self.banks:
            mine = [self._where[w][1] for w in worlds if self._where[w][0] is b]
            if mine and b.hold is not None:
                b.hold.hold(mine)
        self.held[worlds] = True
        self.held_at[worlds] = self.global_step
        self.stats.holds += len(worlds)

    def _release(self, worlds: list[int]) -> None:
        for b in self.banks:
            mine = [self._where[w][1] for w in worlds if self._where[w][0] is b]
            if mine and b.hold is not None:
                b.hold.release(mine)
            if mine:
                b.ctl.mark_dirty()
        self.held[worlds] = False
        for w in worlds:
            self.stats.held_steps += int(self.global_step - self.held_at[w])
            if self._release_at.pop(w, None) is not None:
                self._policy_done.add(w)  # its program runs now: no second policy decision

    def _release_due(self) -> None:
        """Release held worlds whose programs have answered, at whole sync periods of holding."""
        if not self.held.any():
            return
        g, P = self.global_step, self.sync_period
        held = np.nonzero(self.held)[0]
        since = g - self.held_at[held]
        due = []
        for w in held[(since > 0) & (since % P == 0)].tolist():  # at whole periods of holding
            if w in self._release_at:
                if g >= self._release_at[w]:
                    due.append(w)
            elif not self.lockstep.running(w):
                due.append(w)
        if due:
            self._release(due)

    def _apply_hold_policy(self) -> None:
        """The threaded engine's hold policy: a world whose request falls due may be held for a
        number of sync periods before its program runs (the program then sees the held state)."""
        if self.hold_policy is None or self.config.program_procs:
            return
        for w in self.lockstep.ready(skip=self.held):
            if w in self._policy_done:
                self._policy_done.discard(w)
                continue
            self._resumes[w] += 1
            m = int(self.hold_policy(w, int(self._resumes[w])))
            if m > 0:
                self.hold([w])
                self._release_at[w] = self.global_step + m * self.sync_period

    def _next_frame_step(self) -> int:
        """The first global frame step after the current step (frames: ceil(K * S / fps))."""
        s, f = self.steps_per_second, self.config.fps
        k = (self.global_step * f) // s + 1
        return -(-k * s // f)

    def _is_frame_step(self, step: int) -> bool:
        s, f = self.steps_per_second, self.config.fps
        k = step * f // s  # the last frame at or before this step
        return -(-k * s // f) == step

    # -- batched engine work ----------------------------------------------------------------
    def _reset_worlds(self, worlds: list[int]) -> None:
        """Reset ``worlds`` to their pending instances (one batched update per Sim); every other
        world is untouched."""
        t0 = time.perf_counter()
        by_bank: dict[int, list[int]] = {}
        for w in worlds:
            by_bank.setdefault(id(self._where[w][0]), []).append(w)
        for ws in by_bank.values():
            self._reset_bank(self._where[ws[0]][0], ws)
        self.stats.timings.control += time.perf_counter() - t0

    def _reset_bank(self, bank: _Bank, worlds: list[int]) -> None:
        import newton
        import warp as wp

        sim = bank.sim
        local = [self._where[w][1] for w in worlds]
        mask = np.zeros(bank.count + 1, bool)
        mask[local] = True
        dev = sim.model.device
        sim.solver.reset(sim.state_0, world_mask=wp.array(mask, dtype=wp.bool, device=dev))
        # the state read of this step (no read that waits for a render in flight)
        q = bank.snapshot.get("joint_q").copy()
        c = sim.coords_per_world
        for w, i in zip(worlds, local, strict=True):
            for k, v in self._pending_reset.pop(w).items():
                q[i * c + k] = v
            bank.ctl.reset_world(i)
            self.steps[w] = 0
            if self.capture.launched_step == self.global_step:
                self.capture.stale.add(w)
        q_wp = wp.array(q, dtype=wp.float32, device=dev)
        sim.state_0.joint_q.assign(q_wp)
        if bank.joint_world is None:
            bank.joint_world = sim.model.joint_world.numpy()
        jmask = wp.array(np.isin(bank.joint_world, local), dtype=wp.bool, device=dev)
        newton.eval_fk(sim.model, q_wp, sim.state_0.joint_qd, sim.state_0, joint_mask=jmask)
        sim.state_1.assign(sim.state_0)
        bank.snapshot.invalidate()

    @property
    def arm_fk(self):
        """Batched end-effector FK in the base frame (other joints at the IK's neutral pose)."""
        if "_arm_fk" not in self.__dict__:
            from stages.simulate.batch_fk import ArmFK

            self._arm_fk = ArmFK(self.ik)
        return self._arm_fk

