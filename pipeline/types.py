"""The contract between the runner and the stages.

A *job* (``jobs/*.toml``) names one *job kind* per step. A job kind plans *work items*; the runner
hashes each item's inputs, skips items already done with the same hash, runs the rest on an executor,
and records status, errors and timings in ``<out>/state.sqlite``. A stage function never sees the
database, never picks its own output path and never seeds global random state.

Stage function signature (a module-level function, named by a ``"module:function"`` string so that a
process pool or a Ray worker can import it)::

    def ingest_asset(params: IngestParams, ctx: ItemContext) -> IngestResult: ...

``params`` and the result are pydantic models (JSON-serialisable). The function writes its files
under ``ctx.out_dir`` (a temporary folder); the runner renames it to the item's final folder only
after the function returned, so a crash or kill never leaves a half-written output. To fail an item
with a clear one-line reason, raise ``ItemError("<file>: <problem>")``.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel


class ItemError(Exception):
    """An expected, per-item failure (bad input). The message is the one-line reason shown to users."""


def derive_seed(job_seed: int, stage: str, item_id: str = "") -> int:
    """A 63-bit seed from (job seed, stage name, item id): adding a stage or item shifts nothing else."""
    h = hashlib.sha256(f"{int(job_seed)}\x00{stage}\x00{item_id}".encode()).digest()
    return int.from_bytes(h[:8], "little") & ((1 << 63) - 1)


@dataclass(frozen=True)
class ItemContext:
    """What the runner gives a stage function for one work item.

    out_dir: temporary output folder of this item (renamed to ``final_dir`` on success);
    final_dir: where the outputs will live (use it only for recording paths, never write there);
    work_dir: the job's output root (read outputs of earlier steps from here);
    seed: the item's seed, derived from the job seed, the stage name and the item id.
    """

    item_id: str
    stage: str
    seed: int
    out_dir: Path
    final_dir: Path
    work_dir: Path

    def rng(self, sub: str = "") -> np.random.Generator:
        """A fresh generator for this item (optionally for a named sub-step)."""
        return np.random.default_rng(derive_seed(self.seed, self.stage, sub))


@dataclass(frozen=True)
class WorkItem:
    """One unit of work.

    item_id: unique within its step, [A-Za-z0-9_.-]+ (names the output folder);
    fn: ``"module:function"`` of the stage function;
    params: the function's typed input (hashed as canonical JSON);
    input_files: files whose content is part of the cache key (sources, textures, ...);
    depends_on: item ids of earlier steps ("step/item_id") this item reads.
    """

    item_id: str
    fn: str
    params: BaseModel
    input_files: tuple[Path, ...] = ()
    depends_on: tuple[str, ...] = ()


@dataclass(frozen=True)
class PlanContext:
    """What a job kind's planner gets: the job file, its folder (relative paths in the job resolve
    against it), the output root, the job seed, results of earlier steps by step name
    ({item_id: result model}), and the items that could not even be planned (reported as failed)."""

    job_file: Path
    job_dir: Path
    work_dir: Path
    seed: int
    previous: dict[str, dict[str, Any]] = field(default_factory=dict)
    # Added by the runner (additive): the name of the step being planned/finalized, and the items of
    # this and earlier steps that failed, by step name ({item_id: one-line reason}). In ``finalize``,
    # ``previous[step]`` holds this step's succeeded results and ``failed[step]`` its failures.
    step: str = ""
    failed: dict[str, dict[str, str]] = field(default_factory=dict)


@dataclass(frozen=True)
class PlannedFailure:
    """An item rejected while planning (e.g. an invalid annotation entry): fails alone, with reason."""

    item_id: str
    reason: str


@dataclass(frozen=True)
class JobKind:
    """A kind of job step, registered in ``stages/jobkinds.py``.

    config: the pydantic model of the step's table in the job TOML (extra keys forbidden);
    plan: config, PlanContext -> items (and planned failures);
    finalize: optional, runs in the main process after all items of the step ran, with the results
    of the items that succeeded ({item_id: result}); e.g. writes the catalog index or merges shards.
    """

    name: str
    config: type[BaseModel]
    plan: Callable[[BaseModel, PlanContext], Sequence[WorkItem | PlannedFailure]]
    finalize: Callable[[BaseModel, PlanContext, dict[str, Any]], None] | None = None
    description: str = ""
