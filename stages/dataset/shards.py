"""Shards: each worker writes its own LeRobot dataset; a shard is complete or absent.

A shard ``<shards_dir>/<shard_id>`` is written in a temporary sibling folder
``<shards_dir>/.tmp-<shard_id>-<pid>-<nonce>`` and renamed into place (one atomic ``rename``) only after
lerobot finalized every file and the sidecar ``meta/agentworld.json`` was written. A worker killed at
any point (even ``kill -9``) leaves at most a ``.tmp-*`` folder, which no reader lists and which the next
writer of the same shard id (or :func:`clean_stale_temps`, or the runner's next start: see
``pipeline.remove_orphaned_temps``) deletes once its process is gone.

Usage by the recorder::

    with open_shard(shards_dir, "worker-003", spec) as shard:
        shard.begin_episode(EpisodeInfo(task="put the mug in the bowl", task_kind="pick_place",
                                        scene_id="scene-0007", seed=seed, asset_ids=("mug_02", "bowl_01")))
        for step in ...: shard.add_frame(Frame(...))
        shard.end_episode(success=ok, reason=failure_reason)
    # leaving the block publishes the shard; an exception deletes the temporary folder instead
"""

from __future__ import annotations

import logging
import os
import re
import shutil
from dataclasses import dataclass
from pathlib import Path

from pipeline import remove_orphaned_temps, temp_sibling

from .schema import DatasetSpec
from .writer import SIDECAR_PATH, EpisodeWriter, WriterStats, read_sidecar

logger = logging.getLogger(__name__)

_SHARD_ID_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


class ShardExistsError(FileExistsError):
    """The shard was already completed (a finished shard is never overwritten)."""


@dataclass(frozen=True)
class ShardInfo:
    """A complete shard on disk: its folder, id, and the counts of its sidecar."""

    path: Path
    shard_id: str
    episodes: int
    frames: int
    failures: dict[str, int]


class ShardWriter(EpisodeWriter):
    """An :class:`EpisodeWriter` writing into a temporary folder, renamed to ``final`` on close()."""

    def __init__(self, shards_dir: Path, shard_id: str, spec: DatasetSpec, **kwargs) -> None:
        if not _SHARD_ID_RE.match(shard_id):
            raise ValueError(f"shard id {shard_id!r} must match [A-Za-z0-9][A-Za-z0-9_.-]*")
        self.shards_dir = Path(shards_dir)
        self.shard_id = shard_id
        self.final = self.shards_dir / shard_id
        temp = temp_sibling(self.final)
        kwargs.setdefault("repo_id", f"agentworld/{shard_id}")
        super().__init__(temp, spec, **kwargs)

    def open(self) -> ShardWriter:
        if self.final.exists():
            raise ShardExistsError(f"{self.final}: shard already complete")
        self.shards_dir.mkdir(parents=True, exist_ok=True)
        removed = clean_stale_temps(self.shards_dir, shard_id=self.shard_id)
        if removed:
            logger.warning("%s: removed %d interrupted temporary folder(s)", self.final, len(removed))
        super().open()
        return self

    def close(self) -> WriterStats:
        stats = self.finish()
        self.publish()
        return stats

    def finish(self) -> WriterStats:
        """Finalize the dataset in its temporary folder; it is not visible until :meth:`publish`
        (a pool of writers finishes every shard before it publishes any)."""
        return super().close()

    def publish(self) -> None:
        """Rename the finished dataset into place."""
        _fsync_dir(self.root)
        os.rename(self.root, self.final)  # atomic on one filesystem; fails if final appeared meanwhile
        _fsync_dir(self.shards_dir)
        self.root = self.final

    def abort(self) -> None:
        """Delete the temporary folder (also of a finished, unpublished shard); a published one stays."""
        super().abort()
        if self.root != self.final:
            shutil.rmtree(self.root, ignore_errors=True)


def open_shard(shards_dir: Path, shard_id: str, spec: DatasetSpec, **kwargs) -> ShardWriter:
    """A shard writer (use as a context manager); kwargs go to :class:`EpisodeWriter`."""
    return ShardWriter(shards_dir, shard_id, spec, **kwargs)


def clean_stale_temps(shards_dir: Path, shard_id: str | None = None) -> list[Path]:
    """Delete temporary folders of interrupted writers (of ``shard_id`` only, or all) whose process is
    gone; a live process's folder is kept. Returns the deleted folders."""
    return remove_orphaned_temps(Path(shards_dir), name=shard_id, max_depth=1)


def list_shards(shards_dir: Path) -> list[ShardInfo]:
    """The complete shards of ``shards_dir``, sorted by id (temporary folders are never listed)."""
    out = []
    for path in sorted(Path(shards_dir).iterdir()) if Path(shards_dir).is_dir() else []:
        if path.name.startswith(".") or not path.is_dir():
            continue
        out.append(shard_info(path))
    return out


def shard_info(path: Path, shard_id: str | None = None) -> ShardInfo:
    """The :class:`ShardInfo` of a complete dataset folder written by this package (id: its name)."""
    path = Path(path)
    if not (path / SIDECAR_PATH).is_file():
        raise FileNotFoundError(f"{path}: not a complete shard (no {SIDECAR_PATH}); remove or rewrite it")
    meta = read_sidecar(path)
    counts = meta["episodes_written"], meta["frames_written"], meta["failures"]
    return ShardInfo(path, shard_id or path.name, *counts)


def _fsync_dir(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
