"""The worker side: run one stage function for one item, in whatever process the executor picked.

``execute_item`` never raises: every outcome (success, ItemError, unexpected exception) comes back
as a small dict of JSON-able values, so that process pools and Ray move only plain data.
"""

from __future__ import annotations

import logging
import time
import traceback
from functools import lru_cache
from typing import Any, NotRequired, TypedDict

from pydantic import BaseModel

from pipeline._src.registry import import_object, type_ref
from pipeline.types import ItemContext, ItemError

log = logging.getLogger(__name__)

MAX_ERROR_CHARS = 2000


class Outcome(TypedDict):
    """ok: the function returned; result_json: its result as JSON ("null" for None);
    result_type: ``"module:QualName"`` of the result model ("" for None);
    error_kind: "item" (ItemError), "exception" (anything else) or "" when ok;
    error: one-line reason; traceback: full traceback text for unexpected exceptions;
    started_at [s since epoch]; duration_s [s]; worker_died: set by an executor when the worker
    process died under the item (the item may be innocent: another item in the same pool may have
    killed it)."""

    ok: bool
    result_json: str
    result_type: str
    error_kind: str
    error: str
    traceback: str
    started_at: float
    duration_s: float
    worker_died: NotRequired[bool]


def one_line(text: str) -> str:
    """Collapse whitespace/newlines so a reason fits on one line (and cap its length)."""
    line = " ".join(str(text).split())
    return line if len(line) <= MAX_ERROR_CHARS else line[: MAX_ERROR_CHARS - 3] + "..."


@lru_cache(maxsize=256)
def _load(ref: str) -> Any:
    return import_object(ref)


def execute_item(fn: str, params_json: str, params_type: str, ctx: ItemContext) -> Outcome:
    """Import the stage function ``fn`` ("module:function") and the params model ``params_type``,
    validate the params from JSON, create ``ctx.out_dir`` and call ``fn(params, ctx)``."""
    t0 = time.time()
    p0 = time.perf_counter()
    try:
        func = _load(fn)
        params = _load(params_type).model_validate_json(params_json)
        ctx.out_dir.mkdir(parents=True, exist_ok=True)
        result = func(params, ctx)
        if result is None:
            rjson, rtype = "null", ""
        elif isinstance(result, BaseModel):
            rjson, rtype = result.model_dump_json(), type_ref(type(result))
        else:
            raise TypeError(f"stage function {fn} returned a {type(result).__name__}, "
                            "expected a pydantic model or None")
    except ItemError as e:
        return Outcome(ok=False, result_json="", result_type="", error_kind="item", error=one_line(str(e)),
                       traceback="", started_at=t0, duration_s=time.perf_counter() - p0)
    except Exception as e:  # reported to the runner, which retries, records and logs it
        msg = one_line(f"{type(e).__name__}: {e}")
        return Outcome(ok=False, result_json="", result_type="", error_kind="exception", error=msg,
                       traceback=traceback.format_exc(), started_at=t0, duration_s=time.perf_counter() - p0)
    return Outcome(ok=True, result_json=rjson, result_type=rtype, error_kind="", error="", traceback="",
                   started_at=t0, duration_s=time.perf_counter() - p0)


def init_pool_worker(queue: Any, level: int, parent_pid: int) -> None:
    """Process-pool initializer: die with the main process ``parent_pid`` (Linux), send this
    worker's log records to the main process's queue, and turn what third-party code prints or
    warns here into log records too (``chatter.capture_process_output``: job.log, not the console)."""
    _die_with_parent(parent_pid)
    from logging.handlers import QueueHandler

    from pipeline._src.chatter import capture_process_output

    root = logging.getLogger()
    root.handlers[:] = [QueueHandler(queue)]
    root.setLevel(level)
    capture_process_output()


def _die_with_parent(parent_pid: int) -> None:
    """Ask Linux to SIGKILL this process when its parent dies (``kill -9`` of the runner must not
    leave workers behind that could still write into the work dir)."""
    import sys

    if not sys.platform.startswith("linux"):
        return
    import ctypes
    import os
    import signal

    libc = ctypes.CDLL(None, use_errno=True)
    pr_set_pdeathsig = 1
    if libc.prctl(pr_set_pdeathsig, int(signal.SIGKILL), 0, 0, 0) != 0:
        log.warning("prctl(PR_SET_PDEATHSIG) failed: %s", os.strerror(ctypes.get_errno()))
    if os.getppid() != parent_pid:      # the parent died before prctl took effect
        os._exit(1)
