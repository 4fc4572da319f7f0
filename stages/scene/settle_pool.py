"""Settle and validate many scenes on one host: chunks of a few scenes, each settled as one model
by ``settle_batch`` and then validated (``stages.scene.validation``), in worker processes spread
over the host's devices, results streamed as chunks finish.

Why chunks: a chunk's scenes are the worlds of one model, padded to a common structure (see
``settle_batch``), so a chunk of K houses costs about K times one house's GPU work but one house's
kernel launches; too large a chunk pads more and builds its model (CPU, one process) for longer.
Side by side in one world (``worlds=False``) a model costs more than linearly in its scenes. The
chunks of a worker run one after another, and the workers (several per GPU) overlap one chunk's
CPU part (model build, upload, validation) with others' GPU steps.

Workers are spawned processes (``procs_per_device`` per device); a task sends scene paths and
gets back a ``ChunkResult`` (paths, numbers, instance names: results we made, between our own
processes). ``procs_per_device=0`` settles in this process, one chunk after another (the serial
path the parallel one is checked against).
"""

from __future__ import annotations

import json
import multiprocessing as mp
import time
from collections.abc import Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path

from stages.scene.settle_batch import BatchSettle


@dataclass(frozen=True)
class ChunkResult:
    """One chunk: its settle, validation errors per scene, timings [s] (settle_batch's build,
    finalize, simulate; validate) and the device and process that did it."""

    settle: BatchSettle
    errors: tuple[int, ...]
    seconds: dict[str, float]
    device: str
    pid: int


def scene_packages(scene: Path) -> list[Path]:
    """Root layers of the asset packages a scene's instances use (scene.json) + its layout layer."""
    from stages.scene.settle_batch import scene_layout

    info = json.loads((Path(scene).parent / "scene.json").read_text(encoding="utf-8"))
    return sorted({Path(i["usd"]) for i in info["instances"]}) + [scene_layout(Path(scene))]


def settle_validate(scenes: Sequence[Path], device: str, seconds: float, cache_dir: Path | None,
                    cuda_graph: bool = False, worlds: bool = True) -> ChunkResult:
    """Settle ``scenes`` as one model on ``device`` for ``seconds`` [s] (``worlds``: one world per
    scene, see ``settle_batch``), then validate each with the per-package check cache in
    ``cache_dir`` (None: memory only)."""
    import os

    from stages.scene.checkcache import process_cache
    from stages.scene.settle_batch import settle_batch
    from stages.scene.validation import validate_scene

    res = settle_batch(scenes, device=device, seconds=seconds, progress=False, cuda_graph=cuda_graph,
                       worlds=worlds)
    t = time.perf_counter()
    cache = process_cache(cache_dir)
    errors = tuple(len(validate_scene(s, scene_packages(s), cache).errors) for s in scenes)
    secs = {**res.seconds, "validate": round(time.perf_counter() - t, 3)}
    return ChunkResult(settle=res, errors=errors, seconds=secs, device=device, pid=os.getpid())


def _worker_init(device: str) -> None:
    import warp as wp

    wp.config.quiet = True
    wp.init()
    wp.set_device(device)


def chunks(scenes: Sequence[Path], size: int) -> list[list[Path]]:
    """``scenes`` in consecutive chunks of ``size`` (the last may be shorter)."""
    size = max(1, int(size))
    return [list(scenes[i:i + size]) for i in range(0, len(scenes), size)]


class SettlePool:
    """Worker processes settling + validating chunks (see the module docstring); a context manager.
    ``devices``: e.g. ["cuda:0", "cuda:1"] or ["cpu"]; ``procs_per_device`` workers each."""

    def __init__(self, devices: Sequence[str], procs_per_device: int = 1, *, seconds: float = 2.0,
                 cache_dir: Path | None = None, cuda_graph: bool = False, worlds: bool = True):
        self.devices = list(devices)
        self.procs = max(0, int(procs_per_device))
        self.seconds, self.cache_dir, self.cuda_graph, self.worlds = seconds, cache_dir, cuda_graph, worlds
        ctx = mp.get_context("spawn")
        self._pools = [ProcessPoolExecutor(self.procs, mp_context=ctx, initializer=_worker_init, initargs=(d,))
                       for d in self.devices] if self.procs else []

    @property
    def workers(self) -> int:
        return self.procs * len(self.devices) if self.procs else 1

    def run(self, scenes: Sequence[Path], chunk: int = 1, deadline: float | None = None) -> Iterator[ChunkResult]:
        """Results of ``scenes`` settled in chunks of ``chunk``, as they finish (in process: in
        order). ``deadline`` (``time.perf_counter()`` value): no chunk starts after it (chunks
        already running finish)."""
        parts = chunks(scenes, chunk)
        if not self._pools:
            for part in parts:
                if deadline is not None and time.perf_counter() > deadline:
                    return
                yield settle_validate(part, self.devices[0], self.seconds, self.cache_dir, self.cuda_graph, self.worlds)
            return
        todo = list(reversed(parts))
        running: dict = {}

        def submit(slot: int) -> None:
            fut = self._pools[slot % len(self._pools)].submit(
                settle_validate, todo.pop(), self.devices[slot % len(self._pools)], self.seconds, self.cache_dir,
                self.cuda_graph, self.worlds)
            running[fut] = slot

        # keep each worker busy with one chunk and one queued (no more: the deadline stays close)
        for slot in range(min(len(todo), 2 * self.workers)):
            submit(slot)
        while running:
            done, _ = wait(running, return_when=FIRST_COMPLETED)
            for fut in done:
                slot = running.pop(fut)
                if todo and (deadline is None or time.perf_counter() <= deadline):
                    submit(slot)
                yield fut.result()

    def close(self) -> None:
        for p in self._pools:
            p.shutdown(wait=True, cancel_futures=True)
        self._pools = []

    def __enter__(self) -> SettlePool:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
