"""The runner: a validated job -> planned items -> cached / computed / failed, step after step.

For each step, in order:

1. the step's JobKind plans items (``PlanContext.previous`` holds earlier steps' results);
2. each item gets a cache key (see ``pipeline._src.cache``); an item whose key matches a ``done`` row
   of ``<out>/state.sqlite`` and whose output folder exists is *cached*: its stored result is reused
   and nothing runs;
3. the other items are marked ``running`` and sent to the executor; each writes into
   ``<out>/<step>/.tmp/<item_id>.<nonce>/``; on success the runner moves that folder to
   ``<out>/<step>/<item_id>/`` (rename) and only then marks the item ``done``;
4. an ``ItemError`` fails the item at once; another exception is retried ``retries`` times, then fails
   the item with ``"ExceptionType: message"`` (traceback in the database and at DEBUG in the log);
   a failed item's stale output folder is removed;
5. the kind's ``finalize`` runs in this process with the step's succeeded results.

Crash safety: stale ``.tmp`` folders are removed on start, and so are the ``.tmp-<name>-<pid>-<nonce>``
temporaries of atomic writes (``pipeline._src.tempdirs``, e.g. a dataset merge) anywhere in the top
levels of the work dir whose process is dead; an item interrupted anywhere between
"running" and "done" is recomputed on the next run (stage functions are deterministic given the
item's seed), so ``kill -9`` at any moment and a re-run give the same outputs, one row per item.
A lock file (``<out>/.lock``) keeps two runs from sharing a work directory.
"""

from __future__ import annotations

import fcntl
import itertools
import logging
import os
import re
import shutil
import time
import uuid
from collections import deque
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from pipeline._src.cache import canonical_json, code_version, item_key, sha256_file
from pipeline._src.executors import Executor, Task, make_executor
from pipeline._src.jobspec import JobError, JobSpec, StepSpec, load_job
from pipeline._src.progress import StepProgress, make_progress
from pipeline._src.registry import KindError, Registry, import_object, resolve_kind, type_ref
from pipeline._src.report import Failure, JobSummary, StepSummary
from pipeline._src.state import StateDB, StateVersionError
from pipeline._src.tempdirs import remove_orphaned_temps
from pipeline._src.worker import Outcome, one_line
from pipeline.types import ItemContext, JobKind, PlanContext, PlannedFailure, WorkItem, derive_seed

log = logging.getLogger(__name__)

ITEM_ID_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,199}$")
STATE_DB = "state.sqlite"
LOG_RELPATH = Path("logs") / "job.log"
TMP_DIR = ".tmp"


@dataclass(frozen=True)
class RunOptions:
    """Effective settings of one run (job values overridden by the caller's)."""

    out: Path
    executor: str
    workers: int
    retries: int
    ray_address: str | None
    retry_failed: bool = False


@dataclass
class _Pending:
    """An item that has to be computed, with its bookkeeping."""

    item: WorkItem
    key: str
    params_json: str
    params_type: str
    ctx: ItemContext
    attempts: int = 0
    suspect: bool = False    # was in a process pool when a worker died: runs alone from now on


@dataclass
class _StepState:
    """Per-step counters and results while the step runs."""

    results: dict[str, Any]
    failures: dict[str, str]
    done: int = 0
    cached: int = 0
    failed_cached: int = 0
    compute_s: float = 0.0


def run_job(job: JobSpec | str | Path, *, out: str | Path | None = None, executor: str | None = None,
            workers: int | None = None, retries: int | None = None, ray_address: str | None = None,
            registry: Registry | None = None, progress: bool | None = None,
            log_level: int | str | None = None, console: Any = None,
            retry_failed: bool = False) -> JobSummary:
    """Run a job (a JobSpec, or the path of a job TOML) and return its summary.

    out / executor / workers / retries / ray_address override the job's values (workers 0 =
    os.cpu_count()); registry replaces ``stages.jobkinds.JOB_KINDS`` (name -> "module:attr" or
    JobKind); progress: show a rich progress bar (None: only on a terminal); log_level: the level
    of ``<out>/logs/job.log`` (and of the root logger while the job runs); console: the
    ``rich.console.Console`` the progress bar draws on (default: stderr); retry_failed: recompute
    items that failed with an ItemError and whose inputs did not change (by default such a failure
    is reused: bad input stays bad).

    Writes ``<out>/state.sqlite``, ``<out>/logs/job.log`` and ``<out>/reports/summary.json``.
    Item failures are reported in the summary, not raised; a failing ``finalize`` is raised after
    the summary (status "error") was written.
    """
    spec = job if isinstance(job, JobSpec) else load_job(job, registry=registry)
    opts = _options(spec, out, executor, workers, retries, ray_address, retry_failed)
    opts.out.mkdir(parents=True, exist_ok=True)
    with _work_dir_lock(opts.out), _job_logging(opts.out, log_level):
        return _Run(spec, opts, registry, progress, console).run()


def _options(spec: JobSpec, out: str | Path | None, executor: str | None, workers: int | None,
             retries: int | None, ray_address: str | None, retry_failed: bool = False) -> RunOptions:
    n = spec.workers if workers is None else int(workers)
    if n < 0:
        raise ValueError(f"workers must be >= 0, got {n}")
    n = n or (os.cpu_count() or 1)
    ex = executor or spec.executor
    return RunOptions(out=Path(out).resolve() if out is not None else spec.out, executor=ex,
                      workers=1 if ex == "inline" else n,
                      retries=spec.retries if retries is None else int(retries),
                      ray_address=ray_address if ray_address is not None else spec.ray_address,
                      retry_failed=retry_failed)


class _Run:
    """One run of a job (the state that lives as long as the run)."""

    def __init__(self, spec: JobSpec, opts: RunOptions, registry: Registry | None, progress: bool | None,
                 console: Any) -> None:
        self.spec = spec
        self.opts = opts
        self.registry = registry
        self.progress = make_progress(progress, console)
        self.executor: Executor | None = None
        self.previous: dict[str, dict[str, Any]] = {}
        self.failed: dict[str, dict[str, str]] = {}
        self.keys: dict[str, dict[str, str]] = {}
        self.tokens = itertools.count()

    # -- top level ----------------------------------------------------------------------------------

    def run(self) -> JobSummary:
        t0 = time.perf_counter()
        _remove_stale_tmp(self.opts.out, self.spec.steps)
        remove_orphaned_temps(self.opts.out)
        steps: list[StepSummary] = []
        try:
            db = StateDB(self.opts.out / STATE_DB)
        except StateVersionError as e:
            raise JobError(str(e)) from None
        with db, self.progress:
            self.db = db
            self.run_id = db.begin_run(self.spec.name)
            log.info("job %r: %d step(s), out=%s, executor=%s, workers=%d", self.spec.name,
                     len(self.spec.steps), self.opts.out, self.opts.executor, self.opts.workers)
            try:
                for step in self.spec.steps:
                    steps.append(self._run_step(step))
            except BaseException as e:
                status = "interrupted" if isinstance(e, KeyboardInterrupt) else "error"
                summary = self._summary(steps, time.perf_counter() - t0, status,
                                        one_line(f"{type(e).__name__}: {e}"))
                summary.write(self.opts.out)
                db.end_run(self.run_id, status, canonical_json(summary.to_dict()))
                raise
            finally:
                self._close_executor()
            summary = self._summary(steps, time.perf_counter() - t0, "ok" if not any(s.failed for s in steps)
                                    else "failed_items", "")
            summary.write(self.opts.out)
            db.end_run(self.run_id, summary.status, canonical_json(summary.to_dict()))
        log.info("job %r %s in %.2f s: done %d, cached %d, failed %d", self.spec.name, summary.status,
                 summary.seconds, summary.done, summary.cached, summary.failed)
        return summary

    def _summary(self, steps: list[StepSummary], seconds: float, status: str, error: str) -> JobSummary:
        return JobSummary(job=self.spec.name, out=str(self.opts.out), executor=self.opts.executor,
                          workers=self.opts.workers, seconds=seconds, steps=tuple(steps), status=status,
                          error=error, run_id=self.run_id)

    def _executor(self) -> Executor:
        if self.executor is None:
            self.executor = make_executor(self.opts.executor, self.opts.workers, self.opts.ray_address)
        return self.executor

    def _close_executor(self) -> None:
        if self.executor is not None:
            self.executor.close()
            self.executor = None

    # -- one step -----------------------------------------------------------------------------------

    def _run_step(self, step: StepSpec) -> StepSummary:
        t0 = time.perf_counter()
        try:
            kind = resolve_kind(step.kind, self.registry)
        except KindError as e:
            raise JobError(f"step {step.name!r}: {e}") from None
        pctx = self._plan_context(step.name)
        try:
            planned = list(kind.plan(step.config, pctx))
        except ValueError as e:  # e.g. CatalogError: a whole-input problem, reported in one line
            raise JobError(f"step {step.name!r}: {one_line(str(e))}") from e
        _check_plan(step.name, kind, planned)
        st = _StepState(results={}, failures={})
        self.keys[step.name] = {}
        bar = self.progress.add_step(step.name, len(planned))
        rows = {iid: row for (_, iid), row in self.db.items(step.name).items()}
        to_run: list[_Pending] = []
        cached: list[str] = []
        with self.db.transaction():
            for entry in planned:
                if isinstance(entry, PlannedFailure):
                    self._fail(step.name, entry.item_id, "", "", entry.reason, "planned", st, bar)
                    continue
                pending = self._prepare(step, kind, entry, st, bar)
                if pending is None:
                    continue
                row = rows.get(entry.item_id)
                if self._reuse_failure(row, pending):
                    st.failures[entry.item_id] = row.error
                    st.failed_cached += 1
                    cached.append(entry.item_id)
                    bar.advance("failed")
                    continue
                result = self._cached_result(row, pending)
                if result is not _MISS:
                    st.results[entry.item_id] = result
                    st.cached += 1
                    cached.append(entry.item_id)
                    bar.advance("cached")
                else:
                    to_run.append(pending)
        self.db.mark_cached(step.name, cached, self.run_id)
        if to_run:
            self._compute(step, to_run, st, bar)
        _rmtree(self.opts.out / step.name / TMP_DIR)
        # keep plan order in results (executors finish in any order)
        order = [e.item_id for e in planned]
        st.results = {i: st.results[i] for i in order if i in st.results}
        self.previous[step.name] = st.results
        self.failed[step.name] = {i: st.failures[i] for i in order if i in st.failures}
        if kind.finalize is not None:
            log.info("step %r: finalize (%d succeeded item(s))", step.name, len(st.results))
            kind.finalize(step.config, self._plan_context(step.name), st.results)
        bar.finish()
        secs = time.perf_counter() - t0
        log.info("step %r (%s): done %d, cached %d, failed %d in %.2f s", step.name, kind.name, st.done,
                 st.cached, len(st.failures), secs)
        return StepSummary(name=step.name, kind=kind.name, planned=len(planned), done=st.done,
                           cached=st.cached, failed=len(st.failures), failed_cached=st.failed_cached,
                           seconds=secs, compute_s=st.compute_s,
                           failures=tuple(Failure(i, r) for i, r in self.failed[step.name].items()))

    def _plan_context(self, step_name: str) -> PlanContext:
        spec = self.spec
        return PlanContext(job_file=spec.job_file or Path(spec.source or spec.name), job_dir=spec.base_dir,
                           work_dir=self.opts.out, seed=spec.seed, previous=dict(self.previous),
                           step=step_name, failed=dict(self.failed))

    def _prepare(self, step: StepSpec, kind: JobKind, item: WorkItem, st: _StepState,
                 bar: StepProgress) -> _Pending | None:
        """Cache key and context of one item; None (and the item failed) if its inputs are unusable."""
        iid = item.item_id
        try:
            params_json = canonical_json(item.params.model_dump(mode="json"))
            params_type = type_ref(type(item.params))
            code = code_version(item.fn)
            shas = [self._file_sha(Path(p)) for p in item.input_files]
            dep_keys = [self._dep_key(d) for d in item.depends_on]
        except _InputProblem as e:
            self._fail(step.name, iid, "", item.fn, str(e), "input", st, bar)
            return None
        except (LookupError, ValueError, ImportError) as e:
            self._fail(step.name, iid, "", item.fn, one_line(f"{type(e).__name__}: {e}"), "input", st, bar)
            return None
        seed = derive_seed(self.spec.seed, kind.name, iid)
        key = item_key(fn=item.fn, params_type=params_type, params_json=params_json, seed=seed,
                       input_shas=shas, code=code, dep_keys=dep_keys)
        self.keys[step.name][iid] = key
        step_dir = self.opts.out / step.name
        ctx = ItemContext(item_id=iid, stage=kind.name, seed=seed, out_dir=step_dir / TMP_DIR / iid,
                          final_dir=step_dir / iid, work_dir=self.opts.out)
        return _Pending(item=item, key=key, params_json=params_json, params_type=params_type, ctx=ctx)

    def _file_sha(self, path: Path) -> str:
        try:
            stt = path.stat()
        except FileNotFoundError:
            raise _InputProblem(f"{path}: input file not found") from None
        except OSError as e:
            raise _InputProblem(f"{path}: cannot read input file: {e.strerror or e}") from None
        if not path.is_file():
            raise _InputProblem(f"{path}: input is not a file")
        sp = str(path.resolve())
        sha = self.db.known_hash(sp, stt.st_size, stt.st_mtime_ns)
        if sha is None:
            sha = sha256_file(path)
            self.db.remember_hash(sp, stt.st_size, stt.st_mtime_ns, sha)
        return sha

    def _dep_key(self, dep: str) -> str:
        step, _, iid = dep.partition("/")
        if step not in self.keys or not iid:
            raise _InputProblem(f"depends on {dep!r}, which is not an item of an earlier step")
        if iid in self.failed.get(step, {}):
            raise _InputProblem(f"depends on failed item {dep}: {self.failed[step][iid]}")
        if iid not in self.keys[step] or iid not in self.previous.get(step, {}):
            raise _InputProblem(f"depends on {dep!r}, which is not an item of step {step!r}")
        return self.keys[step][iid]

    def _reuse_failure(self, row: Any, p: _Pending) -> bool:
        """An ItemError is bad input: while the item's key is unchanged, don't compute it again."""
        return (row is not None and not self.opts.retry_failed and row.status == "failed"
                and row.error_kind == "item" and row.key == p.key)

    def _cached_result(self, row: Any, p: _Pending) -> Any:
        if row is None or row.status != "done" or row.key != p.key or not p.ctx.final_dir.is_dir():
            return _MISS
        try:
            return _load_result(row.result_json, row.result_type)
        except Exception as e:  # e.g. the result model changed shape: recompute rather than fail
            log.info("%s: stored result unusable (%s); recomputing", p.item.item_id, one_line(str(e)))
            return _MISS

    # -- computing ----------------------------------------------------------------------------------

    def _compute(self, step: StepSpec, to_run: list[_Pending], st: _StepState, bar: StepProgress) -> None:
        self.db.mark_running(step.name, [(p.item.item_id, p.key, p.item.fn) for p in to_run], self.run_id)
        ex = self._executor()
        window = 1 if ex.name == "inline" else max(2 * ex.workers, 4)
        queue = deque(to_run)
        suspects: deque[_Pending] = deque()
        inflight: dict[int, tuple[_Pending, ItemContext]] = {}
        log.info("step %r: computing %d item(s) on %s (%d workers)", step.name, len(to_run), ex.name,
                 ex.workers)
        while queue or suspects or inflight:
            # items that were in the pool when a worker died run one at a time, so that only the item
            # that kills its worker is charged for it; the others go on as if nothing happened
            if not any(p.suspect for p, _ in inflight.values()):
                if suspects:
                    if not inflight:
                        self._submit(ex, suspects.popleft(), inflight)
                else:
                    while queue and len(inflight) < window:
                        self._submit(ex, queue.popleft(), inflight)
            for token, oc in ex.wait():
                p, ctx = inflight.pop(token)
                if oc.get("worker_died") and not p.suspect:
                    p.suspect = True
                    p.attempts -= 1
                    _rmtree(ctx.out_dir)
                    suspects.append(p)
                elif self._settle(step.name, p, ctx, oc, st, bar):
                    (suspects if p.suspect else queue).append(p)

    def _submit(self, ex: Executor, p: _Pending, inflight: dict[int, tuple[_Pending, ItemContext]]) -> None:
        p.attempts += 1
        ctx = replace(p.ctx, out_dir=p.ctx.out_dir.parent / f"{p.item.item_id}.{uuid.uuid4().hex[:12]}")
        token = next(self.tokens)
        inflight[token] = (p, ctx)
        ex.submit(token, Task(p.item.fn, p.params_json, p.params_type, ctx))

    def _settle(self, step: str, p: _Pending, ctx: ItemContext, oc: Outcome, st: _StepState,
                bar: StepProgress) -> bool:
        """Record one outcome; True if the item should be tried again."""
        iid = p.item.item_id
        st.compute_s += oc["duration_s"]
        if oc["ok"]:
            try:
                result = _load_result(oc["result_json"], oc["result_type"])
            except Exception as e:  # the result cannot be rebuilt here: the item's failure
                reason = f"result of {p.item.fn} unusable: {type(e).__name__}: {e}"
                oc = Outcome(**{**oc, "ok": False, "error_kind": "exception", "error": one_line(reason)})
            else:
                _commit_outputs(ctx.out_dir, ctx.final_dir)
                self.db.mark_done(step, iid, key=p.key, attempts=p.attempts, duration_s=oc["duration_s"],
                                  result_json=oc["result_json"], result_type=oc["result_type"],
                                  run_id=self.run_id)
                st.results[iid] = result
                st.done += 1
                bar.advance("done")
                return False
        _rmtree(ctx.out_dir)
        if oc["traceback"]:
            log.debug("%s/%s attempt %d:\n%s", step, iid, p.attempts, oc["traceback"])
        if oc["error_kind"] == "exception" and p.attempts <= self.opts.retries:
            log.warning("%s/%s: attempt %d failed (%s); retrying", step, iid, p.attempts, oc["error"])
            return True
        self._fail(step, iid, p.key, p.item.fn, oc["error"], oc["error_kind"], st, bar,
                   traceback=oc["traceback"], attempts=p.attempts, duration_s=oc["duration_s"],
                   final_dir=ctx.final_dir)
        return False

    def _fail(self, step: str, iid: str, key: str, fn: str, reason: str, kind: str, st: _StepState,
              bar: StepProgress,
              *, traceback: str = "", attempts: int = 0, duration_s: float | None = None,
              final_dir: Path | None = None) -> None:
        reason = one_line(reason)
        stale = final_dir or (self.opts.out / step / iid)
        if stale.exists():
            log.info("%s/%s: removing the output of an earlier run (the item failed now)", step, iid)
            _rmtree(stale)
        self.db.mark_failed(step, iid, key=key, fn=fn, error=reason, error_kind=kind, traceback=traceback,
                            attempts=attempts, duration_s=duration_s, run_id=self.run_id)
        st.failures[iid] = reason
        log.warning("%s/%s failed: %s", step, iid, reason)
        bar.advance("failed")


class _Miss:
    pass


_MISS = _Miss()


class _InputProblem(Exception):
    """An item's inputs are unusable (missing file, failed dependency): the item fails, one line."""


def _check_plan(step: str, kind: JobKind, planned: list[Any]) -> None:
    seen: set[str] = set()
    for e in planned:
        if not isinstance(e, (WorkItem, PlannedFailure)):
            raise JobError(f"step {step!r}: kind {kind.name!r} planned a {type(e).__name__}, "
                           "expected WorkItem or PlannedFailure")
        if not ITEM_ID_RE.match(e.item_id):
            raise JobError(f"step {step!r}: kind {kind.name!r} planned item id {e.item_id!r}; ids must match "
                           f"{ITEM_ID_RE.pattern}")
        if e.item_id in seen:
            raise JobError(f"step {step!r}: kind {kind.name!r} planned item id {e.item_id!r} twice")
        seen.add(e.item_id)
        if isinstance(e, WorkItem) and not isinstance(e.params, BaseModel):
            raise JobError(f"step {step!r}: item {e.item_id!r} params are a {type(e.params).__name__}, "
                           "expected a pydantic model")


def _load_result(result_json: str | None, result_type: str) -> Any:
    if not result_type:
        return None
    return import_object(result_type).model_validate_json(result_json or "null")


def load_results(work_dir: str | Path, step: str) -> dict[str, Any]:
    """The results of a step's ``done`` items in a work directory ({item_id: result model}, by id)."""
    path = Path(work_dir) / STATE_DB
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no state database (nothing has run in {work_dir})")
    with StateDB(path) as db:
        rows = db.items(step)
    return {iid: _load_result(r.result_json, r.result_type) for (_, iid), r in sorted(rows.items())
            if r.status == "done"}


def _commit_outputs(tmp: Path, final: Path) -> None:
    """Move a finished item's folder into place: old final -> aside, tmp -> final, drop the old one."""
    tmp.mkdir(parents=True, exist_ok=True)
    old = None
    if final.exists() or final.is_symlink():
        old = tmp.with_name(tmp.name + ".old")
        os.rename(final, old)
    os.rename(tmp, final)
    if old is not None:
        _rmtree(old)


def _rmtree(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    elif path.exists() or path.is_symlink():
        path.unlink()


def _remove_stale_tmp(out: Path, steps: tuple[StepSpec, ...]) -> None:
    for step in steps:
        tmp = out / step.name / TMP_DIR
        if tmp.exists():
            log.info("removing stale temporary outputs %s", tmp)
            _rmtree(tmp)


@contextmanager
def _work_dir_lock(out: Path) -> Iterator[None]:
    """Hold ``<out>/.lock`` (flock) while the run lasts; released by the OS even after kill -9."""
    path = out / ".lock"
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise JobError(f"{out}: another run is using this work directory") from None
        yield
    finally:
        os.close(fd)


@contextmanager
def _job_logging(out: Path, level: int | str | None) -> Iterator[None]:
    """Log to ``<out>/logs/job.log`` while the job runs (and lower the root level to ``level``);
    Python warnings become log records meanwhile, and job.log keeps each third-party message once
    (``chatter.DedupFilter``)."""
    from pipeline._src.chatter import DedupFilter

    lvl = logging.getLevelName(level.upper()) if isinstance(level, str) else level
    if lvl is not None and not isinstance(lvl, int):
        raise ValueError(f"unknown log level {level!r}")
    path = out / LOG_RELPATH
    path.parent.mkdir(parents=True, exist_ok=True)
    handler = logging.FileHandler(path, encoding="utf-8")
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(processName)s %(name)s: %(message)s"))
    root = logging.getLogger()
    old_level = root.level
    new_level = lvl if lvl is not None else min(old_level or logging.WARNING, logging.INFO)
    handler.setLevel(new_level)
    dedup = DedupFilter()
    handler.addFilter(dedup)
    root.addHandler(handler)
    root.setLevel(new_level)
    captured = getattr(logging, "_warnings_showwarning", None) is not None
    logging.captureWarnings(True)
    try:
        yield
    finally:
        if not captured:
            logging.captureWarnings(False)
        if dedup.dropped:
            log.debug("job.log: %d repeated third-party message(s) left out", dedup.dropped)
        root.removeHandler(handler)
        root.setLevel(old_level)
        handler.close()
