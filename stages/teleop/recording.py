"""Recorder glue: teleoperated episodes into the same LeRobot v3.0 schema as scripted demos.

Layout of a teleop output folder ``out``::

    out/shards/<session>-<k>/   one complete LeRobot dataset per saved episode (atomic: written
                                under a temporary name, renamed when complete; meta/teleop.json
                                holds its teleop metadata)
    out/dataset/                every shard merged (what ``LeRobotDataset`` loads); rebuilt in a
                                temporary folder after each save and swapped in; meta/teleop.json
                                lists the episodes' metadata in order
    out/logs/<session>.jsonl    the sessions' input logs (:mod:`stages.teleop.inputlog`)

A saved episode is on disk once its shard is renamed into place: a crash of the browser or the
server after that loses nothing, and one before it leaves only a ``.tmp-*`` folder that the next
session deletes. The shards are the source of truth; the merged dataset is rebuilt from them.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import threading
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

from stages.dataset.writer import write_json_atomic

log = logging.getLogger(__name__)

TELEOP_META = "meta/teleop.json"


def latency_stats(samples_ms: list[float]) -> dict:
    """count, mean, p50, p95, max of latencies [ms] (None where there is no sample)."""
    import numpy as np

    if not samples_ms:
        return {"count": 0, "mean_ms": None, "p50_ms": None, "p95_ms": None, "max_ms": None}
    a = np.asarray(samples_ms, float)
    return {"count": int(a.size), "mean_ms": round(float(a.mean()), 3),
            "p50_ms": round(float(np.percentile(a, 50)), 3), "p95_ms": round(float(np.percentile(a, 95)), 3),
            "max_ms": round(float(a.max()), 3)}


class TeleopRecorder:
    """Writes saved episodes as shards of ``out/shards`` and keeps ``out/dataset`` merged.
    ``spec``: the dataset spec (the engine's); ``session``: the shard id prefix of this session."""

    def __init__(self, out: Path, spec, session: str) -> None:
        from stages.dataset import clean_stale_temps

        self.out, self.spec, self.session = Path(out), spec, session
        self.shards = self.out / "shards"
        self.shards.mkdir(parents=True, exist_ok=True)
        removed = clean_stale_temps(self.shards)
        if removed:
            log.warning("teleop: removed %d unfinished episode folder(s) of an interrupted session", len(removed))
        self._writer = None
        self._merge = ThreadPoolExecutor(max_workers=1, thread_name_prefix="teleop-merge")
        self._lock = threading.Lock()
        self._pending: Future | None = None
        self.saved: list[Path] = []
        self._recover()

    def _recover(self) -> None:
        """After a crash: put back a dataset caught between the swap's two renames, and re-merge when
        the dataset does not hold exactly the complete shards' episodes."""
        from stages.dataset import list_shards

        final, old = self.out / "dataset", self.out / ".dataset-old"
        if not final.exists() and old.exists():
            os.rename(old, final)
        shards = sorted(s.shard_id for s in list_shards(self.shards) if s.episodes > 0)
        merged: list[str] = []
        meta = final / TELEOP_META
        if meta.is_file():
            try:
                merged = sorted(e["shard"] for e in json.loads(meta.read_text(encoding="utf-8"))["episodes"])
            except (ValueError, KeyError, TypeError):
                merged = []
        if shards and shards != merged:
            log.warning("teleop: %s holds %d of %d saved episodes; merging again", final, len(merged), len(shards))
            self.request_merge()

    @property
    def recording(self) -> bool:
        return self._writer is not None

    @staticmethod
    def preload() -> None:
        """Import what writing an episode needs (lerobot, datasets, PyAV: 10-30 s on the shared
        2-core machine), so that the first :meth:`begin` does not stall the session's thread."""
        from stages.dataset._lerobot import import_lerobot

        import_lerobot()

    def begin(self, k: int, info) -> None:
        """Open episode ``k``'s shard (an :class:`~stages.dataset.EpisodeInfo`)."""
        from stages.dataset import open_shard

        if self._writer is not None:
            raise RuntimeError("teleop recorder: an episode is already open")
        w = open_shard(self.shards, f"{self.session}-{k:04d}", self.spec)
        w.open()
        w.begin_episode(info)
        self._writer = w

    def add_frame(self, frame) -> None:
        if self._writer is not None:
            self._writer.add_frame(frame)

    def save(self, meta: dict) -> Path:
        """End the open episode as written, with its teleop metadata; returns the shard's folder."""
        w, self._writer = self._writer, None
        if w is None:
            raise RuntimeError("teleop recorder: no open episode to save")
        try:
            outcome = w.end_episode(success=True)
            if not outcome.written:
                raise RuntimeError(f"teleop recorder: episode not written ({outcome.reason})")
            write_json_atomic(w.root / TELEOP_META, meta)
            w.close()  # finalize, then rename into place (atomic)
        except BaseException:
            w.abort()
            raise
        self.saved.append(w.final)
        self.request_merge()
        return w.final

    def discard(self, reason: str) -> None:
        """Drop the open episode (its temporary folder is deleted)."""
        w, self._writer = self._writer, None
        if w is not None:
            w.end_episode(success=False, reason=reason or "discarded")
            w.abort()

    def request_merge(self) -> Future:
        """Rebuild ``out/dataset`` from every shard, in a background thread (one at a time)."""
        with self._lock:
            self._pending = self._merge.submit(merge_teleop_dataset, self.out)
            return self._pending

    def close(self) -> None:
        """Discard an open episode, wait for the last merge."""
        if self._writer is not None:
            self.discard("session_closed")
        self._merge.shutdown(wait=True)
        if self._pending is not None:
            self._pending.result()


def merge_teleop_dataset(out: Path) -> Path | None:
    """Merge ``out/shards`` into ``out/dataset`` (built aside, then swapped in); None if no shard
    holds an episode."""
    from stages.dataset import MergeError, list_shards, merge_datasets

    out = Path(out)
    shards = [s for s in list_shards(out / "shards") if s.episodes > 0]
    if not shards:
        return None
    final, nxt, old = out / "dataset", out / ".dataset-next", out / ".dataset-old"
    for p in (nxt, old):
        if p.exists():
            shutil.rmtree(p)
    try:
        merge_datasets([s.path for s in shards], nxt, repo_id="agentworld/teleop")
    except MergeError as e:
        log.error("teleop: merging %d episodes failed: %s", len(shards), e)
        raise
    metas = []
    for s in shards:
        p = s.path / TELEOP_META
        metas.append({"shard": s.shard_id, **(json.loads(p.read_text(encoding="utf-8")) if p.is_file() else {})})
    write_json_atomic(nxt / TELEOP_META, {"episodes": metas})
    if final.exists():
        os.rename(final, old)
    os.rename(nxt, final)
    shutil.rmtree(old, ignore_errors=True)
    return final
