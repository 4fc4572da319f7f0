"""Merge complete shards into one LeRobot v3.0 dataset (lerobot's ``aggregate_datasets``), and load it.

The merged dataset is built in a temporary sibling folder and renamed into place, like a shard; a
temporary left by a killed merge into the same folder is deleted first (``pipeline.remove_orphaned_temps``).
Episodes keep their shard order (shards sorted by id, episodes in recording order); the
``agentworld/`` columns of ``meta/episodes`` travel with them; the sidecar ``meta/agentworld.json``
sums the shards' counts and failure reasons.
"""

from __future__ import annotations

import logging
import os
import shutil
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pipeline import remove_orphaned_temps, temp_sibling

from .schema import EPISODE_COLUMN_PREFIX, DatasetSpec
from .shards import ShardInfo, list_shards, shard_info
from .writer import canonical_stats, import_lerobot, read_sidecar, write_json_atomic

logger = logging.getLogger(__name__)


class MergeError(ValueError):
    """Shards that cannot be merged (none complete, different specs, output exists)."""


@dataclass(frozen=True)
class MergeResult:
    """The merged dataset: folder, counts, and per-reason failures summed over shards."""

    root: Path
    shards: tuple[str, ...]
    episodes: int
    frames: int
    failures: dict[str, int] = field(default_factory=dict)


def merge_shards(
    shards_dir: Path,
    out_dir: Path,
    *,
    repo_id: str = "agentworld/merged",
    data_files_size_mb: float | None = None,
    video_files_size_mb: float | None = None,
) -> MergeResult:
    """Merge every complete shard of ``shards_dir`` into a new dataset at ``out_dir`` (must not exist).

    File size limits default to the shards' spec. Shards with no episode contribute only their failure
    counts. Raises :class:`MergeError` if there is nothing to merge or the shards' specs differ.
    """
    shards = list_shards(shards_dir)
    if not shards:
        raise MergeError(f"{shards_dir}: no complete shard to merge")
    return _merge(shards, Path(out_dir), str(shards_dir), repo_id, data_files_size_mb, video_files_size_mb)


def merge_datasets(
    roots: Sequence[Path],
    out_dir: Path,
    *,
    repo_id: str = "agentworld/merged",
    data_files_size_mb: float | None = None,
    video_files_size_mb: float | None = None,
) -> MergeResult:
    """Like :func:`merge_shards`, for complete datasets anywhere, merged in the given order (e.g. the
    ``dataset`` folder of each runner work item). Their ids are their folder names where unique, else
    ``shard-<k>``."""
    paths = [Path(r) for r in roots]
    if not paths:
        raise MergeError(f"{out_dir}: no dataset to merge")
    names = [p.name for p in paths]
    unique = len(set(names)) == len(names)
    shards = [shard_info(p, None if unique else f"shard-{k:04d}") for k, p in enumerate(paths)]
    return _merge(shards, Path(out_dir), f"{len(paths)} datasets", repo_id, data_files_size_mb,
                  video_files_size_mb)  # fmt: skip


def _merge(shards: list[ShardInfo], out_dir: Path, where: str, repo_id: str, data_files_size_mb: float | None,
           video_files_size_mb: float | None) -> MergeResult:  # fmt: skip
    if out_dir.exists():
        raise MergeError(f"{out_dir}: output dataset already exists")
    spec = _common_spec(shards)
    filled = [s for s in shards if s.episodes > 0]
    if not filled:
        raise MergeError(f"{where}: the {len(shards)} shard(s) hold no successful episode")
    remove_orphaned_temps(out_dir.parent, name=out_dir.name, max_depth=1)
    tmp = temp_sibling(out_dir)
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    try:
        _aggregate(filled, tmp, repo_id, spec, data_files_size_mb, video_files_size_mb)
        canonical_stats(tmp)
        failures: Counter[str] = Counter()
        for s in shards:
            failures.update(s.failures)
        result = MergeResult(
            root=out_dir,
            shards=tuple(s.shard_id for s in shards),
            episodes=sum(s.episodes for s in shards),
            frames=sum(s.frames for s in shards),
            failures=dict(sorted(failures.items())),
        )
        write_json_atomic(tmp / "meta" / "agentworld.json", _merged_sidecar(result, spec, shards, repo_id))
        os.rename(tmp, out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    logger.info("merged %d shards into %s: %d episodes, %d frames", len(shards), out_dir,
                result.episodes, result.frames)
    return result


def _common_spec(shards: list[ShardInfo]) -> DatasetSpec:
    specs = {s.shard_id: read_sidecar(s.path)["spec"] for s in shards}
    first_id, first = next(iter(specs.items()))
    differing = [sid for sid, sp in specs.items() if sp != first]
    if differing:
        raise MergeError(f"shards {differing} have a different spec than {first_id}")
    return DatasetSpec.from_json(first)


def _aggregate(shards: list[ShardInfo], tmp: Path, repo_id: str, spec: DatasetSpec,
               data_mb: float | None, video_mb: float | None) -> None:  # fmt: skip
    import contextlib
    import io
    import logging

    import_lerobot()
    from lerobot.datasets.aggregate import aggregate_datasets

    # lerobot's progress bars (tqdm on stderr) are third-party chatter: the job's log, not the console
    with contextlib.redirect_stderr(io.StringIO()) as bars:
        aggregate_datasets(
            repo_ids=[f"agentworld/shard-{k:04d}" for k in range(len(shards))],
            aggr_repo_id=repo_id,
            roots=[s.path for s in shards],
            aggr_root=tmp,
            data_files_size_in_mb=data_mb or spec.data_files_size_mb,
            video_files_size_in_mb=video_mb or spec.video_files_size_mb,
            chunk_size=spec.chunk_size,
        )
    lines = [ln for ln in bars.getvalue().replace("\r", "\n").splitlines() if ln.strip()]
    if lines:
        logging.getLogger("lerobot.aggregate").info("%s", lines[-1])


def _merged_sidecar(result: MergeResult, spec: DatasetSpec, shards: list[ShardInfo], repo_id: str) -> dict:
    return {
        "format": "agentworld-lerobot-v3.0",
        "spec": spec.to_json(),
        "repo_id": repo_id,
        "episodes_written": result.episodes,
        "frames_written": result.frames,
        "episodes_failed": sum(result.failures.values()),
        "failures": result.failures,
        "shards": [{"id": s.shard_id, "episodes": s.episodes, "frames": s.frames, "failures": s.failures}
                   for s in shards],
    }  # fmt: skip


def load_dataset(root: Path, *, episodes: list[int] | None = None, **kwargs: Any) -> Any:
    """Open a dataset written by this package with ``LeRobotDataset`` (local, offline, PyAV decoding).

    Items hold ``observation.state`` / ``action`` float32 tensors, RGB videos as float32 (3, H, W) in
    [0, 1], depth as ``depth.<camera>`` text (:func:`stages.dataset.depth.decode_depth`: uint16 (H, W)
    [mm], exact), ``timestamp``, ``task``. kwargs go to LeRobotDataset
    (e.g. ``delta_timestamps``, ``episode_filter=lambda ep: ep["agentworld/task_kind"] == "pick_place"``).
    """
    lds = import_lerobot()
    root = Path(root)
    if not (root / "meta" / "info.json").is_file():
        raise FileNotFoundError(f"{root}: no meta/info.json (not a LeRobot dataset)")
    kwargs.setdefault("video_backend", "pyav")
    return lds.LeRobotDataset(read_sidecar(root).get("repo_id", "agentworld/dataset"), root=root,
                              episodes=episodes, **kwargs)  # fmt: skip


def read_episode_columns(root: Path) -> list[dict[str, Any]]:
    """The ``agentworld/`` columns of ``meta/episodes`` (prefix stripped) plus episode_index, length
    and tasks, one dict per episode in episode order."""
    import pyarrow.parquet as pq

    rows: list[dict[str, Any]] = []
    for path in sorted((Path(root) / "meta" / "episodes").glob("*/*.parquet")):
        table = pq.read_table(path)
        names = ["episode_index", "length", "tasks", *(n for n in table.column_names
                                                         if n.startswith(EPISODE_COLUMN_PREFIX))]  # fmt: skip
        for row in table.select(names).to_pylist():
            rows.append({k.removeprefix(EPISODE_COLUMN_PREFIX): v for k, v in row.items()})
    return sorted(rows, key=lambda r: r["episode_index"])
