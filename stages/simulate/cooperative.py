"""Yield points of long computations (planning, IK), for programs scheduled cooperatively.

A scripted expert that plans (A*, base poses, reach searches: tens of IK solves) runs for
milliseconds to seconds between two physics requests. Where programs of several worlds share one
process (the engine's expert workers, :mod:`stages.engine.remote`), the scheduler of that thread
may install a hook (:func:`set_hook`) that :func:`checkpoint` calls: the hook may park the program
there and run other worlds' programs first. A checkpoint sits only where no shared object is
mid-use (a Clik's Pinocchio ``data`` between solves or lane iterations), so parking there changes
nothing that the program computes. Without a hook (a lone program, the engine's own threads) a
checkpoint is one attribute lookup.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

_local = threading.local()


def checkpoint() -> None:
    """A point where this thread's program may be parked (see the module docstring)."""
    fn = getattr(_local, "fn", None)
    if fn is not None:
        fn()


def set_hook(fn: Callable[[], None] | None) -> None:
    """Make ``fn()`` what :func:`checkpoint` calls in this thread (None: nothing)."""
    _local.fn = fn
