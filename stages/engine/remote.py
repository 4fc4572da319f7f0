"""World programs in worker processes: the engine's planning and IK on every core.

With ``EngineConfig(program_procs=K)`` the engine's process keeps the simulation, the cameras and
the recording, and K worker processes run the worlds' programs (blocks of worlds each: a world's
program always runs in the same process, its programs one at a time). They share, in shared memory:

- the state snapshot (joint_q, joint_qd, body_q, the watched joints' peaks), written by the
  engine once before every batch of resumes;
- the command buffers (drive targets, base commands; the engine's ``RobotControl`` is bound to
  them and uploads them after every batch) and the recorded commands (base velocity, gripper, mode);
- per world: episode step counter, recording flag and time limit, pending steps, and flags
  (waiting for a sync point, done, peaks on, peaks fresh).

Per batch the engine sends every worker the list of its worlds whose requests are met; the workers
resume them in parallel and answer, world by world, with the programs' events (reset coordinates,
episode begin and end), which the engine handles in world order. A world's program sees only its
own world and its own commands, so which process runs it changes nothing: episodes equal those of
the threaded engine. With ``EngineConfig.program_wait`` the engine waits only that long for a
batch: worlds whose programs are still running (planning) are held (:mod:`stages.engine.hold`)
and the rest step on; a held world is released once its program has answered. With
``EngineConfig.program_yield`` a program that plans longer than that parks at its next checkpoint
(:mod:`stages.simulate.cooperative`): its worker sends a busy notice, the engine holds that world
without waiting for it, and the worker answers its other worlds' requests before it goes on with
the parked program, so one world's planning stalls neither the engine nor its worker's other worlds.

``next_instance`` must be picklable here (a module-level function or an object): each worker
calls it for its worlds.
"""

from __future__ import annotations

import logging
import time
from collections import deque
from types import SimpleNamespace

import numpy as np

log = logging.getLogger(__name__)

SYNC, DONE, PEAKS_ON, PEAKS_FRESH = range(4)


class _Shared:
    """Named shared-memory numpy arrays: created by the engine (``specs``: name -> (shape,
    dtype)), attached by the workers (``names``: name -> (shm name, shape, dtype))."""

    def __init__(self, specs: dict | None = None, names: dict | None = None) -> None:
        from multiprocessing import shared_memory

        self.arrays: dict[str, np.ndarray] = {}
        self._shm = []
        self.owner = specs is not None
        if specs is not None:
            names = {}
            for key, (shape, dtype) in specs.items():
                size = max(1, int(np.prod(shape)) * np.dtype(dtype).itemsize)
                shm = shared_memory.SharedMemory(create=True, size=size)
                names[key] = (shm.name, tuple(shape), np.dtype(dtype).str)
                self._shm.append(shm)
                self.arrays[key] = np.ndarray(shape, dtype, buffer=shm.buf)
                self.arrays[key][...] = 0
        else:
            for key, (name, shape, dtype) in names.items():
                shm = shared_memory.SharedMemory(name=name)
                self._shm.append(shm)
                self.arrays[key] = np.ndarray(shape, np.dtype(dtype), buffer=shm.buf)
        self.names = names

    def close(self) -> None:
        self.arrays.clear()
        for shm in self._shm:
            shm.close()
            if self.owner:
                shm.unlink()
        self._shm.clear()


class _SharedSnapshot:
    """A :class:`~stages.engine.view.Snapshot` over shared arrays (the engine writes them)."""

    def __init__(self, arrays: dict) -> None:
        self.arrays = arrays

    def get(self, name: str) -> np.ndarray:
        return self.arrays[name]

    def invalidate(self) -> None:
        pass


class _SharedPeaks:
    """Peaks of a worker's worlds: flags for the engine, values from the snapshot."""

    def __init__(self, arrays: dict, paths: list[str]) -> None:
        self.a, self.paths = arrays, paths

    def start(self, w: int) -> None:
        self.a["flags"][w, PEAKS_ON] = 1
        self.a["flags"][w, PEAKS_FRESH] = 1

    def stop(self, w: int) -> None:
        self.a["flags"][w, PEAKS_ON] = 0

    def read(self, w: int) -> dict[str, float]:
        return {p: float(self.a["peaks"][w, i]) for i, p in enumerate(self.paths)}


def _worker(conn, init: dict) -> None:
    """A worker process: the programs of ``init["worlds"]``, resumed on the engine's request."""
    import usd_schemas  # noqa: F401  (the schema registry before pxr is used)
    from stages.demos.experts import timed_clik
    from stages.engine.lockstep import Lockstep
    from stages.engine.programs import WorldSide
    from stages.engine.view import WorldControl, WorldView
    from stages.simulate.control import CommandBuffers

    shared = _Shared(names=init["shm"])
    a = shared.arrays
    info, model, worlds = init["info"], init["model"], init["worlds"]
    n = len(a["steps"])
    cmdbuf = CommandBuffers(info.desc, info.robot.coord, info.coords_per_world, init["arm_lower"],
                            init["arm_upper"], targets=a["targets"], cmd=a["cmd"])
    bank = SimpleNamespace(sim=info, snapshot=_SharedSnapshot(a), model=model)
    queue: deque[int] = deque()  # worlds the engine resumed, not started yet
    busy: deque[int] = deque()  # worlds parked mid-computation at a checkpoint
    notified: set[int] = set()  # busy worlds the engine was told of
    yield_after = init["yield_after"]

    def yield_check(w: int, seconds: float) -> bool:
        # a program planning for yield_after [s] parks once (the engine is told and holds its
        # world at once) and again whenever other worlds' requests wait behind it
        return seconds >= yield_after and (w not in notified or bool(queue) or conn.poll())

    ls = Lockstep(n, yield_check=None if yield_after is None else yield_check)
    events: dict[int, list] = {w: [] for w in worlds}
    views = {w: WorldView(None, w, bank, w, model, a["steps"]) for w in worlds}
    side = WorldSide(info=info, views=views, controls={w: WorldControl(cmdbuf, w) for w in worlds},
                     ik=timed_clik(info.desc), fps=init["fps"], steps_per_second=init["steps_per_second"],
                     steps=a["steps"], rec_active=a["rec_active"], rec_max=a["rec_max"], lockstep=ls,
                     peaks=_SharedPeaks(a, init["paths"]), emit=lambda k, w, p: events[w].append((k, w, p)),
                     free=init["free"], scene_coord=init["scene_coord"], max_seconds=init["max_seconds"])
    for v in views.values():
        v._engine = side
    for w in worlds:
        ls.start(w, side.program(w, init["next_instance"]))
    conn.send(("ready", None))
    try:
        while True:
            # every request that arrived; block only when no world is left to run
            while conn.poll() or not (queue or busy):
                msg, arg = conn.recv()
                if msg == "stop":
                    return
                for w in arg:
                    ls.slots[w].sync, ls.slots[w].pending = False, 0  # the engine met its request
                queue.extend(arg)
            # the requests first, in the engine's order; parked computations when none is left
            w = queue.popleft() if queue else busy.popleft()
            try:
                ls._resume(w)
            except RuntimeError as e:
                conn.send(("error", w, str(e)))
                continue
            s = ls.slots[w]
            if s.busy:
                if w not in notified:
                    notified.add(w)
                    conn.send(("busy", w))
                busy.append(w)
                continue
            notified.discard(w)
            a["pending"][w] = s.pending  # one answer per world, as soon as its program blocks again
            a["flags"][w, SYNC] = int(s.sync)
            a["flags"][w, DONE] = int(s.done)
            a["cmdrec"][w] = side.cmds[w].row()
            conn.send(("ok", w, events[w]))
            events[w] = []
    finally:
        ls.shutdown()
        shared.close()


class RemotePrograms:
    """The engine's side of the worker processes, with :class:`~stages.engine.lockstep.Lockstep`'s
    engine-facing methods."""

    def __init__(self, engine, next_instance) -> None:
        import multiprocessing as mp

        self.engine = engine
        bank = engine.banks[0]
        from stages.demos.record import COMMAND_ROW

        sim = bank.sim
        n = engine.config.worlds
        k = max(1, min(engine.config.program_procs, n))
        st = sim.state_0
        specs = {
            "joint_q": (st.joint_q.shape, np.float32), "joint_qd": (st.joint_qd.shape, np.float32),
            "body_q": ((st.body_q.shape[0], 7), np.float32),
            "peaks": ((n, max(1, len(bank.peaks.paths))), np.float32),
            "targets": (bank.ctl._targets.shape, bank.ctl._targets.dtype), "cmd": ((n, 3), np.float32),
            "cmdrec": ((n, COMMAND_ROW), np.float64), "steps": ((n,), np.int64), "rec_active": ((n,), np.int8),
            "rec_max": ((n,), np.int64), "pending": ((n,), np.int64), "flags": ((n, 4), np.int8),
        }
        self.shared = _Shared(specs=specs)
        a = self.a = self.shared.arrays
        for key in ("steps", "rec_active", "rec_max"):
            a[key][:] = getattr(engine, key)
            setattr(engine, key, a[key])
        bank.ctl.bind(a["targets"], a["cmd"])
        self.blocks = [list(range(i * n // k, (i + 1) * n // k)) for i in range(k)]
        self.in_flight = np.zeros(n, bool)  # sent to a worker, no answer yet
        self.busy = np.zeros(n, bool)  # in flight, and its worker said it is planning (parked)
        ctx = mp.get_context("spawn")
        self.procs, self.conns = [], []
        for worlds in self.blocks:
            parent, child = ctx.Pipe()
            init = dict(shm=self.shared.names, worlds=worlds, info=engine.info, model=bank.model,
                        arm_lower=bank.ctl.arm_lower, arm_upper=bank.ctl.arm_upper, fps=engine.config.fps,
                        steps_per_second=engine.steps_per_second, paths=list(bank.peaks.paths),
                        free=engine._free, scene_coord=engine._scene_coord,
                        max_seconds=engine.config.max_seconds, next_instance=next_instance,
                        yield_after=engine.config.program_yield)
            p = ctx.Process(target=_worker, args=(child, init), name=f"engine-programs-{len(self.procs)}",
                            daemon=True)
            p.start()
            self.procs.append(p)
            self.conns.append(parent)
        for c in self.conns:
            self._reply(c)

    def _reply(self, conn):
        kind, payload = conn.recv()
        if kind == "error":
            raise RuntimeError(payload)
        return payload

    def _drain(self, timeout: float | None) -> list:
        """Answers that arrived within ``timeout`` [s] (None: wait for at least one message): (world,
        events) each; their worlds are no longer in flight. A worker's notice that a world's
        program is planning (parked at a checkpoint) marks it busy."""
        from multiprocessing.connection import wait

        out = []
        for conn in wait(self.conns, timeout):
            while conn.poll():
                msg = conn.recv()
                if msg[0] == "error":
                    raise RuntimeError(msg[2])
                if msg[0] == "busy":
                    self.busy[msg[1]] = True
                    self.engine.stats.yields += 1
                    continue
                _, w, events = msg
                self.in_flight[w] = self.busy[w] = False
                out.append((w, events))
        return out

    def _waited(self, ready: list[int], limit: float | None) -> np.ndarray:
        """Which of ``ready`` the engine still waits for: in flight, and with a ``limit`` not busy
        (a planning world is held at once)."""
        if limit is None:
            return self.in_flight[ready]
        return self.in_flight[ready] & ~self.busy[ready]

    def _write_snapshot(self) -> None:
        bank = self.engine.banks[0]
        snap = bank.snapshot  # read once per step (before a render is enqueued at frame steps)
        a = self.a
        for name in ("joint_q", "joint_qd", "body_q"):
            a[name][:] = snap.get(name).reshape(a[name].shape)
        if bank.peaks.paths:
            a["peaks"][:] = bank.peaks.host()

    # -- Lockstep's engine-side interface --------------------------------------------------------
    def ready(self, skip=None) -> list[int]:
        a = self.a
        f = a["flags"]
        m = (f[:, DONE] == 0) & (f[:, SYNC] == 0) & (a["pending"] == 0) & ~self.in_flight
        if skip is not None:
            m &= ~np.asarray(skip, bool)
        return [int(w) for w in np.nonzero(m)[0]]

    def running(self, world: int) -> bool:
        return bool(self.in_flight[world])

    def resume_ready(self, skip=None) -> int:
        """Resume the ready worlds (not ``skip[w]``) in the workers; wait for their answers (at
        most ``program_wait`` seconds, then hold the late ones); handle every answer that came,
        in world order."""
        replies = self._drain(0) if self.in_flight.any() else []
        ready = self.ready(skip)
        if ready:
            self._write_snapshot()
            rs = set(ready)
            for conn, worlds in zip(self.conns, self.blocks, strict=True):
                mine = [w for w in worlds if w in rs]
                if mine:
                    conn.send(("resume", mine))
            self.in_flight[ready] = True
            limit = self.engine.config.program_wait
            t_end = None if limit is None else time.perf_counter() + limit
            while self._waited(ready, limit).any():
                timeout = None if t_end is None else t_end - time.perf_counter()
                if timeout is not None and timeout <= 0:
                    break
                replies += self._drain(timeout)
            late = [int(w) for w in np.nonzero(self.in_flight)[0] if not self.engine.held[w]]
            if late:
                self.engine.hold(late)
        live = self.a["flags"][:, DONE] == 0
        while not replies and self.in_flight.any() and (self.in_flight | ~live).all():
            replies += self._drain(None)  # every live world is planning: wait for one (no spinning)
        if not replies:
            return len(ready)
        f = self.a["flags"]
        replies.sort(key=lambda r: r[0])
        for w, events in replies:
            for kind, ew, payload in events:
                self.engine.on_event(kind, ew, payload)
        peaks = self.engine.banks[0].peaks
        for w, _ in replies:
            if f[w, PEAKS_FRESH]:
                peaks.start(w)
                f[w, PEAKS_FRESH] = 0
            elif not f[w, PEAKS_ON] and peaks._active_np[w]:
                peaks.stop(w)
        self.engine.banks[0].ctl.mark_dirty()
        return len(ready)

    def waiting_sync(self) -> list[int]:
        f = self.a["flags"]
        # a worker writes the flags before its answer arrives: only answered worlds count
        return [int(w) for w in np.nonzero((f[:, SYNC] == 1) & (f[:, DONE] == 0) & ~self.in_flight)[0]]

    def release_sync(self, worlds) -> None:
        for w in worlds:
            self.a["flags"][w, SYNC] = 0

    def min_pending(self, skip=None) -> int | None:
        a = self.a
        m = (a["flags"][:, DONE] == 0) & (a["flags"][:, SYNC] == 0) & (a["pending"] > 0) & ~self.in_flight
        if skip is not None:
            m &= ~np.asarray(skip, bool)
        return int(a["pending"][m].min()) if m.any() else None

    def advance(self, k: int, skip=None) -> None:
        p = self.a["pending"]
        m = (self.a["flags"][:, DONE] == 0) & (p > 0) & ~self.in_flight
        if skip is not None:
            m &= ~np.asarray(skip, bool)
        p[m] = np.maximum(0, p[m] - k)

    def alive(self) -> bool:
        """A world's program still runs, or its last answer (with its episode's end) has not
        arrived yet: a worker sets DONE before its answer reaches the engine."""
        return bool(((self.a["flags"][:, DONE] == 0) | self.in_flight).any())

    def shutdown(self) -> None:
        e = self.engine
        for key in ("steps", "rec_active", "rec_max"):
            setattr(e, key, np.array(getattr(e, key)))
        bank = e.banks[0]
        bank.ctl._targets, bank.ctl._cmd_np = np.array(bank.ctl._targets), np.array(bank.ctl._cmd_np)
        for conn in self.conns:
            try:
                conn.send(("stop", None))
            except (BrokenPipeError, OSError):
                pass
        for p in self.procs:
            p.join(timeout=10)
            if p.is_alive():
                p.terminate()
        self.shared.close()
