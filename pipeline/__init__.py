"""AgentWorld's batch runner: jobs of typed stage functions with caching, resume and executors.

Public API (everything else lives in ``pipeline._src`` and is internal)::

    from pipeline import load_job, run_job
    summary = run_job(load_job("jobs/main.toml"), executor="local", workers=2)
    print(summary.done, summary.cached, summary.failed)

Job kinds and stage functions use the contract in ``pipeline.types`` (``JobKind``, ``WorkItem``,
``PlanContext``, ``PlannedFailure``, ``ItemContext``, ``ItemError``, ``derive_seed``).

Names are loaded lazily, so ``import pipeline`` stays cheap (no pxr, warp or torch, ever).
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

__all__ = [
    "ItemContext",
    "ItemError",
    "JobError",
    "JobKind",
    "JobSpec",
    "JobSummary",
    "PlanContext",
    "PlannedFailure",
    "StepSpec",
    "StepSummary",
    "WorkItem",
    "build_job",
    "derive_seed",
    "load_job",
    "load_results",
    "read_summary",
    "remove_orphaned_temps",
    "run_job",
    "temp_sibling",
]

_WHERE = {
    "ItemContext": "pipeline.types",
    "ItemError": "pipeline.types",
    "JobKind": "pipeline.types",
    "PlanContext": "pipeline.types",
    "PlannedFailure": "pipeline.types",
    "WorkItem": "pipeline.types",
    "derive_seed": "pipeline.types",
    "JobError": "pipeline._src.jobspec",
    "JobSpec": "pipeline._src.jobspec",
    "StepSpec": "pipeline._src.jobspec",
    "build_job": "pipeline._src.jobspec",
    "load_job": "pipeline._src.jobspec",
    "JobSummary": "pipeline._src.report",
    "StepSummary": "pipeline._src.report",
    "read_summary": "pipeline._src.report",
    "run_job": "pipeline._src.runner",
    "load_results": "pipeline._src.runner",
    "temp_sibling": "pipeline._src.tempdirs",
    "remove_orphaned_temps": "pipeline._src.tempdirs",
}

if TYPE_CHECKING:
    from pipeline._src.jobspec import JobError, JobSpec, StepSpec, build_job, load_job
    from pipeline._src.report import JobSummary, StepSummary, read_summary
    from pipeline._src.runner import load_results, run_job
    from pipeline._src.tempdirs import remove_orphaned_temps, temp_sibling
    from pipeline.types import (ItemContext, ItemError, JobKind, PlanContext, PlannedFailure, WorkItem,
                                derive_seed)


def __getattr__(name: str) -> Any:
    try:
        module = _WHERE[name]
    except KeyError:
        raise AttributeError(f"module 'pipeline' has no attribute {name!r}") from None
    value = getattr(import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
