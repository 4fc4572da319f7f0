"""Shard writers in worker processes: the recorder hands frames over shared memory (issue 12).

Why: a batched engine records hundreds of worlds in one process. Writing a frame inline (the shard's
``add_frame``: validation, column buffers, handing RGB to the video encoder threads, PNG-compressing
depth) costs the engine process's interpreter time on every frame of every world, beside the
simulation and the experts. :class:`ShardPool` moves the shards' writers into ``workers`` processes;
the engine process only validates a frame, copies its images into a free slot of the owning worker's
shared-memory ring and sends a few hundred bytes (slot, numeric fields) down a pipe.

The result is the same dataset: each shard is written by the same :class:`~stages.dataset.ShardWriter`
with the same frames in the same order (tests compare the files); a shard is complete or absent as
before, and the pool is all or nothing: every shard is finished before any is published (when the pool
closes); when it aborts or a worker fails, every temporary folder is removed (see
:mod:`stages.dataset.shards`).

Usage (shard ``i`` of ``shard_ids``)::

    with ShardPool(shards_dir, ["dataset_w000", "dataset_w001"], spec, PoolConfig(workers=2)) as pool:
        pool.begin_episode(0, EpisodeInfo(...))
        sink = pool.sink(0)          # a frame sink (callable); it copies the frame's arrays
        sink(frame)                  # or pool.add_frame(0, frame)
        pool.end_episode(0, success=True)
    # leaving the block publishes every shard; an exception (or a worker's failure) removes them all

A batched engine hands a whole frame step over at once: ``pool.add_frames(shards, columns, images,
rows)`` (the frames' numeric fields as :class:`~stages.dataset.columns.FrameColumns`, the images as the
render's stacked buffers) screens all frames with a few array operations (a suspect frame gets the
per-frame check and its error), copies each frame's images into a slot and sends each worker one
message per run of free slots; the worker writes the same frames in the same order (same files).
The engine's capture uses it for sinks that are a pool's (:func:`pool_target`). Measured on the CPU
(``tests/benchmarks/bench_handoff.py``, 256 worlds, 3 cameras 240x320 RGB + depth): see its JSON.

Frames in flight are bounded by ``slots`` per worker: ``add_frame`` blocks (never drops a frame) until
the worker has copied an earlier frame out of its slot. A worker that fails reports one line
(``ShardPoolError``: the worker, the shard and the problem) at the next call.
"""

from __future__ import annotations

import dataclasses
import json
import multiprocessing as mp
import struct
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from multiprocessing.shared_memory import SharedMemory
from pathlib import Path
from typing import Any

import numpy as np

from .columns import NUMERIC as _NUMERIC
from .columns import SCALAR_FLOAT as _SCALAR_FLOAT
from .columns import SCALAR_INT as _SCALAR_INT
from .columns import VECTOR as _VECTOR
from .columns import NONE as _NONE
from .columns import FrameColumns, Images, frame_images, pack_columns, suspect_rows
from .schema import DatasetSpec, EpisodeInfo, Frame, frame_problems, validate_frame

_HEAD = struct.Struct("<iiI")  # shard, slot, bitmask of the images present (2 bits per camera)
_COUNT = struct.Struct("<i")  # frames in a batch message (b"G")
_RELEASE_EVERY = 8  # a writer process hands freed slots back in groups of this many (or at a batch's end)


class ShardPoolError(RuntimeError):
    """A writer process failed (or died); the pool is unusable and its shards are removed."""


@dataclass(frozen=True)
class PoolConfig:
    """workers: writer processes (shard ``i`` goes to worker ``i % workers``); slots: frames in flight
    per worker (each slot holds one frame's images: 3 cameras of 240x320 RGB + depth take 1.15 MB);
    writer: keyword arguments of each :class:`~stages.dataset.ShardWriter` (backend, encoder_threads,
    queue_frames, inline_encoding; default: ``encoder_threads=1``: a worker encodes each of its shards'
    video streams in a thread of its own already, and x264's automatic thread count (1.5 per core) in
    each of hundreds of streams only oversubscribes a many-core host. ``inline_encoding=True`` encodes
    in the worker's own thread instead (no hand-overs between threads; the same files): on the shared
    2-core machine 12.2 against 13.1 ms of writer CPU per timestep (medians of 3, within the noise),
    but one core per worker at most (25 against 47 timesteps/s wall with one worker), so it needs
    about twice the workers); timeout: [s] a blocked call waits this long for a worker before failing."""

    workers: int = 2
    slots: int = 32
    writer: dict[str, Any] = dataclasses.field(default_factory=lambda: {"encoder_threads": 1})
    timeout: float = 600.0

    def __post_init__(self) -> None:
        if self.workers < 1 or self.slots < 1:
            raise ValueError(f"PoolConfig: workers and slots must be >= 1, got {self.workers}, {self.slots}")


def _layout(spec: DatasetSpec) -> list[tuple[str, str, tuple[int, ...], np.dtype, int]]:
    """(camera, field, shape, dtype, byte offset) of every image a slot holds, in spec order."""
    out, off = [], 0
    for cam in spec.cameras:
        for field, on, shape, dtype in (("rgb", cam.rgb, (cam.height, cam.width, 3), np.dtype(np.uint8)),
                                        ("depth_mm", cam.depth, (cam.height, cam.width), np.dtype(np.uint16))):
            if on:
                out.append((cam.name, field, shape, dtype, off))
                off += int(np.prod(shape)) * dtype.itemsize
    return out


def _slot_bytes(layout) -> int:
    if not layout:
        return 1
    _, _, shape, dtype, off = layout[-1]
    return off + int(np.prod(shape)) * dtype.itemsize


def _pack_numeric(frame: Frame) -> bytes:
    """The frame's non-image fields: per field (kind, length) then float64 values."""
    kinds, values = [], []
    for name in _NUMERIC:
        v = getattr(frame, name)
        if v is None:  # Frame.state_vector / action_vector of the single-arm layout
            kinds.append((_NONE, 0))
        elif isinstance(v, (int, np.integer)) and not isinstance(v, bool):
            kinds.append((_SCALAR_INT, 1))
            values.append(np.array([v], np.float64))
        elif np.ndim(v) == 0:
            kinds.append((_SCALAR_FLOAT, 1))
            values.append(np.array([v], np.float64))
        else:
            a = np.asarray(v, np.float64).ravel()
            kinds.append((_VECTOR, a.size))
            values.append(a)
    head = struct.pack(f"<{2 * len(kinds)}H", *[x for k in kinds for x in k])
    return head + np.concatenate(values).tobytes()


def _unpack_numeric(buf: bytes) -> dict[str, Any]:
    n = len(_NUMERIC)
    kinds = struct.unpack_from(f"<{2 * n}H", buf)
    vals = np.frombuffer(buf, np.float64, offset=4 * n)
    out, i = {}, 0
    for j, name in enumerate(_NUMERIC):
        kind, length = kinds[2 * j], kinds[2 * j + 1]
        chunk = vals[i:i + length]
        i += length
        out[name] = None if kind == _NONE else int(chunk[0]) if kind == _SCALAR_INT \
            else float(chunk[0]) if kind == _SCALAR_FLOAT else chunk.copy()
    return out


def _worker(k: int, conn_in, conn_out, shm_name: str, slots: int, slot_bytes: int, shards_dir: str,
            ids: dict[int, str], spec: DatasetSpec, writer_kwargs: dict[str, Any]) -> None:
    """Writer process ``k``: owns the shards ``ids`` (pool index -> shard id) until told to close."""
    import cv2

    from .shards import open_shard

    # OpenCV's RGB -> yuv420p conversion of a frame (direct.video_frame) is too small to split over
    # threads: its default pool (one thread per core) only adds CPU in a process that is one of many
    cv2.setNumThreads(1)
    shm = SharedMemory(name=shm_name)
    layout = _layout(spec)
    # the direct backend copies what it keeps, so it reads the images in place and the slot is freed
    # after add_frame; lerobot's writer keeps the arrays it is given: they are copied out first
    in_place = writer_kwargs.get("backend", "direct") == "direct"
    writers: dict[int, Any] = {}
    where = "opening"
    try:
        for i, sid in ids.items():
            where = sid
            writers[i] = open_shard(Path(shards_dir), sid, spec, **writer_kwargs).open()
        conn_out.send_bytes(b"O")  # ready
        freed: list[int] = []

        def free(slot: int, flush: bool) -> None:  # slots go back in groups (one message each)
            freed.append(slot)
            if flush or len(freed) >= _RELEASE_EVERY:
                conn_out.send_bytes(b"R" + struct.pack(f"<{len(freed)}i", *freed))
                freed.clear()

        def take(i: int, slot: int, mask: int, fields: dict[str, Any], last: bool) -> None:
            base = slot * slot_bytes
            rgb, depth = {}, {}
            for b, (cam, field, shape, dtype, off) in enumerate(layout):
                if mask >> b & 1:
                    a = np.ndarray(shape, dtype, buffer=shm.buf, offset=base + off)
                    (rgb if field == "rgb" else depth)[cam] = a if in_place else a.copy()
            if not in_place:
                free(slot, last)  # the slot is free again
            # validated by the engine's process (ShardPool.add_frame[s]) against the same spec
            writers[i].add_frame(Frame(**fields, rgb=rgb, depth_mm=depth), validated=True)
            if in_place:
                rgb = depth = None  # no view of the slot outlives it
                free(slot, last)

        while True:
            msg = conn_in.recv_bytes()
            kind = msg[:1]
            if kind == b"F":
                i, slot, mask = _HEAD.unpack_from(msg, 1)
                where = ids[i]
                take(i, slot, mask, _unpack_numeric(msg[1 + _HEAD.size:]), True)
            elif kind == b"G":  # frames of several shards: heads, the fields' kinds, a (m, L) float64 block
                m = _COUNT.unpack_from(msg, 1)[0]
                at = 1 + _COUNT.size + m * _HEAD.size
                kinds = msg[at:at + 4 * len(_NUMERIC)]
                vals = np.frombuffer(msg, np.uint8, offset=at + len(kinds)).reshape(m, (len(msg) - at - len(kinds)) // m)
                for j in range(m):
                    i, slot, mask = _HEAD.unpack_from(msg, 1 + _COUNT.size + j * _HEAD.size)
                    where = ids[i]
                    take(i, slot, mask, _unpack_numeric(kinds + vals[j].tobytes()), j == m - 1)
            elif kind == b"B":
                i, info = json.loads(msg[1:])
                where = ids[i]
                writers[i].begin_episode(EpisodeInfo(**{**info, "asset_ids": tuple(info["asset_ids"])}))
            elif kind == b"E":
                i, success, reason = json.loads(msg[1:])
                where = ids[i]
                writers[i].end_episode(success=success, reason=reason)
            elif kind == b"C":  # finish every shard (not yet visible), report, wait for publish
                stats = {}
                for i, w in sorted(writers.items()):
                    where = ids[i]
                    st = w.finish()
                    stats[ids[i]] = {"episodes": st.episodes_written, "frames": st.frames_written}
                conn_out.send_bytes(b"D" + json.dumps(stats).encode())
            elif kind == b"P":
                for i, w in sorted(writers.items()):
                    where = ids[i]
                    w.publish()
                writers.clear()
                conn_out.send_bytes(b"P")
                return
            else:  # b"A": abort
                return
    except BaseException as e:  # noqa: BLE001 - reported to the engine process as one line
        try:
            conn_out.send_bytes(b"X" + f"writer process {k}, shard {where}: {type(e).__name__}: {e}".encode())
        except OSError:
            pass
    finally:
        for w in writers.values():
            try:
                w.abort()
            except Exception:  # noqa: BLE001 - best effort: the next open cleans its temps
                pass
        try:
            shm.close()
        except BufferError:  # a failed frame's traceback still holds views of the slot: the exit frees it
            pass


class _Worker:
    """The engine side of one writer process: its pipes, ring of slots and free list."""

    def __init__(self, k: int, ctx, slots: int, slot_bytes: int) -> None:
        self.k = k
        self.shm = SharedMemory(create=True, size=slots * slot_bytes)
        self.send_in, self.recv_in = ctx.Pipe(duplex=False)[::-1]  # engine writes send_in
        self.recv_out, self.send_out = ctx.Pipe(duplex=False)     # engine reads recv_out
        self.free = list(range(slots))[::-1]
        self.ring: list[np.ndarray] = []  # per layout entry: (slots, *shape) view of the ring
        self.proc = None
        self.error: str | None = None
        self.done: dict | None = None
        self.published = False
        self.ready = False


class ShardPool:
    """Shards ``shard_ids`` in ``shards_dir`` written by ``config.workers`` processes (module docstring)."""

    def __init__(self, shards_dir: Path, shard_ids: list[str], spec: DatasetSpec,
                 config: PoolConfig | None = None) -> None:
        self.shards_dir, self.ids, self.spec = Path(shards_dir), list(shard_ids), spec
        self.config = config or PoolConfig()
        self._layout = _layout(spec)
        self._slot_bytes = _slot_bytes(self._layout)
        self._workers: list[_Worker] = []
        self._frames = [0] * len(self.ids)
        self.wait_s = 0.0  # [s] add_frame spent waiting for a free slot (the workers behind)

    # -- lifecycle ------------------------------------------------------------------------------
    def open(self) -> ShardPool:
        ctx = mp.get_context("spawn")  # the engine process holds CUDA: never fork it
        n = min(self.config.workers, max(1, len(self.ids)))
        for k in range(n):
            w = _Worker(k, ctx, self.config.slots, self._slot_bytes)
            w.ring = [np.ndarray((self.config.slots, *shape), dtype, buffer=w.shm.buf, offset=off,
                                 strides=(self._slot_bytes, *np.empty(shape, dtype).strides))
                      for _, _, shape, dtype, off in self._layout]
            ids = {i: sid for i, sid in enumerate(self.ids) if i % n == k}
            w.proc = ctx.Process(target=_worker, name=f"shard-writer-{k}", daemon=True,
                                 args=(k, w.recv_in, w.send_out, w.shm.name, self.config.slots, self._slot_bytes,
                                       str(self.shards_dir), ids, self.spec, dict(self.config.writer)))
            w.proc.start()
            w.recv_in.close()
            w.send_out.close()
            self._workers.append(w)
        return self

    def wait_ready(self) -> None:
        """Block until every worker has started and opened its shards (for benchmarks: frames
        handed over before that wait in the slots)."""
        for w in self._workers:
            while not w.ready:
                self._receive(w, block=True)

    def close(self) -> dict[str, dict]:
        """Publish every shard; returns shard id -> {episodes, frames} written."""
        out: dict[str, dict] = {}
        try:
            for w in self._workers:
                self._send(w, b"C")
            for w in self._workers:
                while w.done is None:
                    self._receive(w, block=True)
                out.update(w.done)
            for w in self._workers:  # every shard finished: publish them all
                self._send(w, b"P")
            for w in self._workers:
                while not w.published:
                    self._receive(w, block=True)
        except BaseException:
            self.abort()
            raise
        self._release()
        return out

    def abort(self) -> None:
        """Stop the workers; their shards' temporary folders are removed (nothing is published)."""
        for w in self._workers:
            if w.proc.is_alive() and w.error is None and not w.published:
                try:
                    w.send_in.send_bytes(b"A")
                except OSError:
                    pass
        for w in self._workers:
            w.proc.join(timeout=30)
            if w.proc.is_alive():
                w.proc.kill()
                w.proc.join()
        from .shards import clean_stale_temps

        clean_stale_temps(self.shards_dir)  # a killed worker's temporary folders (its process is gone)
        self._release()

    def __enter__(self) -> ShardPool:
        return self.open() if not self._workers else self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    # -- episodes -------------------------------------------------------------------------------
    def begin_episode(self, i: int, info: EpisodeInfo) -> None:
        problems = info.problems()
        if problems:
            raise ValueError(f"{self.shards_dir / self.ids[i]}: episode info: " + "; ".join(problems))
        self._frames[i] = 0
        d = dataclasses.asdict(info)
        d["asset_ids"] = list(d["asset_ids"])
        self._send(self._owner(i), b"B" + json.dumps([i, d]).encode())

    def add_frame(self, i: int, frame: Frame) -> None:
        """Validate the frame here (errors are raised at once, naming the shard), then hand it over."""
        if frame_problems(self.spec, frame):  # the message (and its path) is made only for a bad frame
            validate_frame(self.spec, frame, where=f"{self.shards_dir / self.ids[i]} frame {self._frames[i]}")
        w = self._owner(i)
        self._receive(w, block=False)
        self._wait_free(w)
        slot = w.free.pop()
        mask = 0
        for b, (cam, field, shape, _, _) in enumerate(self._layout):
            src = getattr(frame, field).get(cam)
            if src is None:
                continue
            w.ring[b][slot] = np.asarray(src).reshape(shape)
            mask |= 1 << b
        self._send(w, b"F" + _HEAD.pack(i, slot, mask) + _pack_numeric(frame))
        self._frames[i] += 1

    def add_frames(self, shards: list[int], cols: FrameColumns, images: Images, rows: list[int]) -> None:
        """Hand K frames over at once, the same as ``add_frame(shards[j], frame j)`` for j in order
        (the same files): frame j's numeric fields are row j of ``cols``, its images row ``rows[j]``
        of ``images`` (camera -> RGB (B, H, W, 3) uint8, depth (B, H, W) uint16 [mm]; views of
        buffers the caller reuses: copied before this returns). The frames are screened together
        (:func:`~stages.dataset.columns.suspect_rows`); a suspect one gets the per-frame check, and
        a bad one raises its :class:`FrameError` naming the shard before any of the K is handed
        over. Each writer process gets one message per run of free slots (one per call when the
        writers keep up)."""
        k = len(shards)
        if len(cols) != k or len(rows) != k:
            raise ValueError(f"{self.shards_dir}: add_frames: {k} shards, {len(cols)} frames, {len(rows)} rows")
        suspect = set(np.nonzero(suspect_rows(self.spec, cols, images))[0].tolist())
        if suspect:
            seen: dict[int, int] = {}
            for j in range(k):  # frame numbers as add_frame would count them
                i = shards[j]
                seen[i] = seen.get(i, -1) + 1
                if j in suspect:
                    frame = cols.frame(j, *frame_images(images, rows[j]))
                    if frame_problems(self.spec, frame):
                        validate_frame(self.spec, frame, where=f"{self.shards_dir / self.ids[i]} frame "
                                                               f"{self._frames[i] + seen[i]}")
        head, values = pack_columns(cols)
        srcs = [images.get(cam, (None, None))[0 if field == "rgb" else 1] for cam, field, *_ in self._layout]
        mask = sum(1 << b for b, src in enumerate(srcs) if src is not None)
        shapes = [shape for _, _, shape, _, _ in self._layout]
        by_worker: dict[int, list[int]] = {}
        for j in range(k):
            by_worker.setdefault(self._owner(shards[j]).k, []).append(j)
        for wk, js in by_worker.items():
            w = self._workers[wk]
            while js:
                self._receive(w, block=False)
                self._wait_free(w)
                take, js = js[:len(w.free)], js[len(w.free):]
                heads = []
                for j in take:
                    slot = w.free.pop()
                    r = rows[j]
                    for b, src in enumerate(srcs):
                        if src is not None:
                            w.ring[b][slot] = src[r].reshape(shapes[b])
                    heads.append(_HEAD.pack(shards[j], slot, mask))
                    self._frames[shards[j]] += 1
                self._send(w, b"G" + _COUNT.pack(len(take)) + b"".join(heads) + head + values[take].tobytes())

    def _wait_free(self, w: _Worker) -> None:
        """Block until worker ``w`` has a free slot (counted in ``wait_s``)."""
        if not w.free:
            t0 = time.perf_counter()
            while not w.free:
                self._receive(w, block=True)
            self.wait_s += time.perf_counter() - t0

    def end_episode(self, i: int, success: bool, reason: str = "") -> None:
        self._send(self._owner(i), b"E" + json.dumps([i, bool(success), str(reason)]).encode())

    def sink(self, i: int):
        """A frame sink for shard ``i`` (what the engine's ``begin`` returns)."""
        return PoolShard(self, i).add_frame

    # -- plumbing -------------------------------------------------------------------------------
    def _owner(self, i: int) -> _Worker:
        if not 0 <= i < len(self.ids):
            raise IndexError(f"shard index {i} out of range (0..{len(self.ids) - 1})")
        return self._workers[i % len(self._workers)]

    def _send(self, w: _Worker, msg: bytes) -> None:
        self._receive(w, block=False)
        try:
            w.send_in.send_bytes(msg)
        except OSError:
            self._receive(w, block=True)  # the worker is gone: its report (or the death) raises
            raise ShardPoolError(f"writer process {w.k} is gone") from None

    def _receive(self, w: _Worker, block: bool) -> None:
        """Drain the worker's messages (freed slots, its close report, its error); when ``block``,
        wait for at least one. Raises :class:`ShardPoolError` if it failed or died."""
        deadline = time.monotonic() + self.config.timeout
        while True:
            if w.recv_out.poll(0.5 if block else 0):
                try:
                    msg = w.recv_out.recv_bytes()
                except EOFError:
                    msg = b"X" + f"writer process {w.k} exited (code {w.proc.exitcode})".encode()
                kind = msg[:1]
                if kind == b"R":
                    w.free.extend(struct.unpack_from(f"<{(len(msg) - 1) // 4}i", msg, 1))
                elif kind == b"D":
                    w.done = json.loads(msg[1:])
                elif kind == b"P":
                    w.published = True
                elif kind == b"O":
                    w.ready = True
                else:
                    w.error = msg[1:].decode(errors="replace")
                    raise ShardPoolError(w.error)
                block = False
                continue
            if not block:
                return
            if not w.proc.is_alive():
                raise ShardPoolError(f"writer process {w.k} exited (code {w.proc.exitcode})")
            if time.monotonic() > deadline:
                raise ShardPoolError(f"writer process {w.k}: no answer in {self.config.timeout:.0f} s")

    def _release(self) -> None:
        for w in self._workers:
            for c in (w.send_in, w.recv_out):
                c.close()
            w.ring = []  # no view of the ring outlives it
            w.shm.close()
            w.shm.unlink()
        self._workers = []


class PoolShard:
    """Shard ``i`` of a pool with a :class:`~stages.dataset.ShardWriter`'s episode methods; its
    ``add_frame`` copies the frame's arrays before returning (``takes_views``: a caller may pass views
    of buffers it reuses)."""

    def __init__(self, pool: ShardPool, i: int) -> None:
        self.pool, self.i = pool, i

    def begin_episode(self, info: EpisodeInfo) -> None:
        self.pool.begin_episode(self.i, info)

    def add_frame(self, frame: Frame) -> None:
        self.pool.add_frame(self.i, frame)

    add_frame.takes_views = True  # type: ignore[attr-defined]  # read through bound methods too

    def end_episode(self, success: bool, reason: str = "") -> None:
        self.pool.end_episode(self.i, success, reason)


def pool_target(sink) -> tuple[ShardPool, int] | None:
    """(pool, shard index) when ``sink`` is a :class:`PoolShard`'s ``add_frame`` (its frames may be
    handed over in batches: :meth:`ShardPool.add_frames`), else None."""
    owner = getattr(sink, "__self__", None)
    return (owner.pool, owner.i) if isinstance(owner, PoolShard) else None


def ring_slots(shards: int, workers: int, slot_bytes: int, *, steps: int = 2, least: int = 32,
               max_bytes: int = 1 << 30) -> int:
    """Slots per writer for ``shards`` shards written by ``workers`` processes: ``steps`` frame steps
    of a worker's shards (an engine hands every world's frame over at once, then simulates while the
    writers catch up: a ring smaller than one step's frames makes it wait mid-step for the writers),
    at least ``least``, at most ``max_bytes`` [bytes] of shared memory per worker. Measured on the CPU
    (``bench_handoff.py --worlds 32 --gap 1.5 --writer-procs 2``, 16 shards per writer): 4 slots
    waited 0.62 s in 4 steps, 32 slots 0.0 s."""
    per_worker = -(-shards // max(1, workers))
    return max(1, min(max(least, steps * per_worker), max_bytes // max(1, slot_bytes)))


@contextmanager
def open_shards(shards_dir: Path, shard_ids: list[str], spec: DatasetSpec, writer_procs: int = 0,
                slots: int | None = None) -> Iterator[list]:
    """Writers of the shards ``shard_ids`` (one per engine world): inline shard writers when
    ``writer_procs`` is 0, else :class:`PoolShard` handles of a :class:`ShardPool` of that many processes
    (``slots`` per process; None: :func:`ring_slots`, two frame steps of its shards).
    Leaving the block publishes them; an exception removes them."""
    from .shards import open_shard

    if writer_procs <= 0:
        with ExitStack() as stack:
            yield [stack.enter_context(open_shard(shards_dir, sid, spec)) for sid in shard_ids]
        return
    if slots is None:
        slots = ring_slots(len(shard_ids), min(writer_procs, max(1, len(shard_ids))), _slot_bytes(_layout(spec)))
    with ShardPool(shards_dir, shard_ids, spec, PoolConfig(workers=writer_procs, slots=slots)) as pool:
        yield [PoolShard(pool, i) for i in range(len(shard_ids))]
