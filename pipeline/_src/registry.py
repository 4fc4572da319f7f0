"""Job kind lookup and ``"module:attribute"`` imports.

A step's ``kind`` is looked up in a registry: ``stages.jobkinds.JOB_KINDS`` by default, or a mapping
given to ``load_job``/``run_job`` (tests inject their own). Registry values are ``"module:attribute"``
strings or ``JobKind`` objects. A kind written as ``"module:attribute"`` in a job file is imported
directly (for plug-ins and tests that do not want an entry in the shared registry).
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from typing import Any

from pipeline.types import JobKind

Registry = Mapping[str, "str | JobKind"]


class KindError(LookupError):
    """A job kind or a ``"module:attribute"`` reference cannot be resolved; the message says why."""


def import_object(ref: str) -> Any:
    """Import ``"package.module:attr"`` (attr may be dotted, e.g. ``Class.method``)."""
    module_name, sep, attr = ref.partition(":")
    if not sep or not module_name or not attr:
        raise KindError(f"{ref!r} is not a 'module:attribute' reference")
    try:
        obj: Any = importlib.import_module(module_name)
    except ImportError as e:
        raise KindError(f"cannot import module {module_name!r} of {ref!r}: {e}") from e
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise KindError(f"module {module_name!r} has no attribute {attr!r} (from {ref!r})") from None
    return obj


def type_ref(cls: type) -> str:
    """The ``"module:QualName"`` of a class (the inverse of ``import_object``)."""
    return f"{cls.__module__}:{cls.__qualname__}"


def default_registry() -> dict[str, str | JobKind]:
    """``stages.jobkinds.JOB_KINDS`` (empty if the stages package is not importable)."""
    try:
        from stages.jobkinds import JOB_KINDS
    except ImportError:
        return {}
    return dict(JOB_KINDS)


def resolve_kind(kind: str, registry: Registry | None = None) -> JobKind:
    """The ``JobKind`` named ``kind`` (a registry key, or a direct ``"module:attribute"``)."""
    reg = default_registry() if registry is None else registry
    if kind in reg:
        entry = reg[kind]
        obj = import_object(entry) if isinstance(entry, str) else entry
        where = f"registry entry {kind!r}"
    elif ":" in kind:
        obj = import_object(kind)
        where = f"{kind!r}"
    else:
        known = ", ".join(sorted(reg)) or "none registered"
        raise KindError(f"unknown job kind {kind!r} (known: {known})")
    if not isinstance(obj, JobKind):
        raise KindError(f"{where} is a {type(obj).__name__}, not a pipeline.types.JobKind")
    if kind in reg and obj.name != kind:
        raise KindError(f"registry entry {kind!r} names a JobKind called {obj.name!r}; the names must match")
    return obj
