"""Executors: where ``execute_item`` runs.

- ``inline``: in the calling process, one item at a time (debugging, profilers, pdb);
- ``local``: a ``ProcessPoolExecutor`` with the "spawn" start method, so no pxr/warp state is forked;
  worker log records are forwarded to the main process's logging;
- ``ray``: Ray tasks (one CPU each) on the cluster at ``address``, or on a local cluster started with
  ``num_cpus=workers`` and shut down again afterwards. Workers get the driver's source folders on
  PYTHONPATH; on a multi-node cluster the nodes must have the package installed and share the work
  directory's file system (outputs are written there directly).

All three take ``submit(token, task)`` and give back ``(token, Outcome)`` pairs from ``wait()``; the
runner owns retries and bookkeeping.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import sys
from collections import deque
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor
from concurrent.futures import wait as futures_wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from logging.handlers import QueueListener
from pathlib import Path
from typing import Any, Protocol

from pipeline._src.worker import Outcome, execute_item, init_pool_worker, one_line
from pipeline.types import ItemContext

log = logging.getLogger(__name__)

EXECUTORS = ("local", "ray", "inline")


@dataclass(frozen=True)
class Task:
    """What travels to a worker: the stage function, its params as JSON, their type, the context."""

    fn: str
    params_json: str
    params_type: str
    ctx: ItemContext


class Executor(Protocol):
    name: str
    workers: int

    def submit(self, token: int, task: Task) -> None: ...

    def wait(self) -> list[tuple[int, Outcome]]:
        """Block until at least one submitted task finished; return every finished one."""
        ...

    def close(self) -> None: ...


def _failure(error: str, tb: str = "", worker_died: bool = False) -> Outcome:
    return Outcome(ok=False, result_json="", result_type="", error_kind="exception", error=one_line(error),
                   traceback=tb, started_at=0.0, duration_s=0.0, worker_died=worker_died)


class InlineExecutor:
    """Runs each task in this process when ``wait`` is called."""

    name = "inline"

    def __init__(self) -> None:
        self.workers = 1
        self._queue: deque[tuple[int, Task]] = deque()

    def submit(self, token: int, task: Task) -> None:
        self._queue.append((token, task))

    def wait(self) -> list[tuple[int, Outcome]]:
        token, t = self._queue.popleft()
        return [(token, execute_item(t.fn, t.params_json, t.params_type, t.ctx))]

    def close(self) -> None:
        self._queue.clear()


class _ForwardToLogger:
    """QueueListener target: re-emit a worker's record through this process's logger of that name."""

    def handle(self, record: logging.LogRecord) -> None:
        logger = logging.getLogger(record.name)
        if logger.isEnabledFor(record.levelno):
            logger.handle(record)


class LocalExecutor:
    """A pool of ``workers`` spawned processes."""

    name = "local"

    def __init__(self, workers: int) -> None:
        self.workers = workers
        self._ctx = multiprocessing.get_context("spawn")
        self._queue = self._ctx.Queue()
        self._listener = QueueListener(self._queue, _ForwardToLogger())
        self._listener.start()
        self._pool: ProcessPoolExecutor | None = None
        self._futures: dict[Future, int] = {}

    def _ensure_pool(self) -> ProcessPoolExecutor:
        if self._pool is None:
            level = logging.getLogger().getEffectiveLevel()
            self._pool = ProcessPoolExecutor(self.workers, mp_context=self._ctx,
                                             initializer=init_pool_worker,
                                             initargs=(self._queue, level, os.getpid()))
        return self._pool

    def submit(self, token: int, task: Task) -> None:
        args = (task.fn, task.params_json, task.params_type, task.ctx)
        try:
            fut = self._ensure_pool().submit(execute_item, *args)
        except BrokenProcessPool:
            self._reset_pool()
            fut = self._ensure_pool().submit(execute_item, *args)
        self._futures[fut] = token

    def wait(self) -> list[tuple[int, Outcome]]:
        done, _ = futures_wait(list(self._futures), return_when=FIRST_COMPLETED)
        out: list[tuple[int, Outcome]] = []
        broken = False
        for fut in done:
            token = self._futures.pop(fut)
            try:
                out.append((token, fut.result()))
            except BrokenProcessPool as e:
                broken = True
                out.append((token, _failure(f"BrokenProcessPool: a worker process died abruptly ({e})",
                                            worker_died=True)))
            except Exception as e:  # e.g. an unpicklable argument; reported as the item's failure
                out.append((token, _failure(f"{type(e).__name__}: {e}")))
        if broken:
            self._reset_pool()
        return out

    def _reset_pool(self) -> None:
        log.warning("a worker process died; starting a new process pool")
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
        self._pool = None

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        self._listener.stop()
        self._queue.close()
        self._queue.join_thread()


def _driver_source_paths() -> list[str]:
    """This process's sys.path folders that are not part of the Python installation (source trees)."""
    prefixes = {Path(p).resolve() for p in (sys.prefix, sys.base_prefix, sys.exec_prefix)}
    out = []
    for p in sys.path:
        if not p or not Path(p).is_dir():
            continue
        rp = Path(p).resolve()
        if any(rp == pre or rp.is_relative_to(pre) for pre in prefixes):
            continue
        out.append(str(rp))
    cwd = str(Path.cwd())
    if cwd not in out:
        out.append(cwd)
    return out


class RayExecutor:
    """Ray tasks of one CPU each, on the cluster at ``address`` or on a local cluster it starts."""

    name = "ray"

    def __init__(self, workers: int, address: str | None = None) -> None:
        import ray

        os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
        self._ray = ray
        self._started = False
        if not ray.is_initialized():
            env = {"PYTHONPATH": os.pathsep.join(_driver_source_paths())}
            kw: dict[str, Any] = {"runtime_env": {"env_vars": env}, "logging_level": logging.WARNING,
                                  "log_to_driver": True}
            if address:
                log.info("connecting to the Ray cluster at %s", address)
                ray.init(address=address, **kw)
            else:
                log.info("starting a local Ray cluster with %d CPUs", workers)
                ray.init(num_cpus=workers, include_dashboard=False, **kw)
            self._started = True
        self.workers = int(ray.cluster_resources().get("CPU", workers))
        self._remote = ray.remote(num_cpus=1, max_retries=0)(execute_item)
        self._refs: dict[Any, int] = {}

    def submit(self, token: int, task: Task) -> None:
        ref = self._remote.remote(task.fn, task.params_json, task.params_type, task.ctx)
        self._refs[ref] = token

    def wait(self) -> list[tuple[int, Outcome]]:
        ray = self._ray
        refs = list(self._refs)
        ready, rest = ray.wait(refs, num_returns=1)
        if rest:
            more, _ = ray.wait(rest, num_returns=len(rest), timeout=0)
            ready += more
        out: list[tuple[int, Outcome]] = []
        for ref in ready:
            token = self._refs.pop(ref)
            try:
                out.append((token, ray.get(ref)))
            except Exception as e:  # RayTaskError, WorkerCrashedError, ...: the item's failure
                out.append((token, _failure(f"{type(e).__name__}: {e}")))
        return out

    def close(self) -> None:
        for ref in list(self._refs):
            self._ray.cancel(ref, force=True)
        self._refs.clear()
        if self._started:
            self._ray.shutdown()


def make_executor(name: str, workers: int, ray_address: str | None = None) -> Executor:
    """An executor by name ("local", "ray", "inline"); workers >= 1."""
    if name == "inline":
        return InlineExecutor()
    if name == "local":
        return LocalExecutor(workers)
    if name == "ray":
        return RayExecutor(workers, ray_address)
    raise ValueError(f"unknown executor {name!r}; expected one of {', '.join(EXECUTORS)}")
