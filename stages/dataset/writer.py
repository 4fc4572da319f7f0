"""Episode writer: records successful episodes into one LeRobot v3.0 dataset folder.

Lifecycle (enforced; misuse raises ``RuntimeError``)::

    with EpisodeWriter(root, spec) as w:          # open(): creates ``root`` (must not exist)
        w.begin_episode(EpisodeInfo(...))
        for ...: w.add_frame(Frame(...))          # validated: all problems in one FrameError
        w.end_episode(success=True)               # written; success=False -> discarded, counted by reason
    # close(): finalize parquet footers + metadata, add the agentworld/ episode columns, write the sidecar

An exception inside the ``with`` block aborts: the folder is deleted. Atomic publication (a shard is
complete or absent) is :mod:`stages.dataset.shards`' job; this class writes in place.

Two backends write the same format. ``direct`` (default, :mod:`stages.dataset.direct`) uses lerobot's
metadata classes and writes data and videos itself, 2-3x faster. ``lerobot`` uses lerobot's writer as is
(``LeRobotDataset.create`` / ``add_frame`` / ``save_episode`` / ``finalize``) with streaming video
encoding configured from :class:`~stages.dataset.schema.VideoCodecSpec`, and one change: its streaming
encoder drops frames when its queue is full (it logs a warning); ours blocks instead, since a dropped
frame would desynchronise video and parquet.
"""

from __future__ import annotations

import json
import logging
import os
import queue
import shutil
import time
from collections import Counter
from dataclasses import dataclass, field
from enum import Enum
from pathlib import Path
from typing import Any

import numpy as np

from ._lerobot import import_lerobot
from .depth import encode_depth
from .direct import DirectBackend
from .stats import image_stats, stats_sample
from .schema import (
    ACTION_KEY,
    ENV_STATE_KEY,
    STATE_KEY,
    SUBTASK_KEY,
    DatasetSpec,
    EpisodeInfo,
    Frame,
    FrameError,
    episode_columns,
    validate_frame,
)

logger = logging.getLogger(__name__)

SIDECAR_PATH = "meta/agentworld.json"
"""Per-dataset summary lerobot ignores: spec, counts, failure reasons (written last by close())."""


@dataclass(frozen=True)
class EpisodeOutcome:
    """Result of one end_episode call: written (with its index in this dataset) or discarded."""

    written: bool
    episode_index: int | None
    num_frames: int
    reason: str = ""


@dataclass
class WriterStats:
    """Counters and wall times [s] of a writer (add: add_frame calls; save: save_episode calls)."""

    episodes_written: int = 0
    frames_written: int = 0
    frames_discarded: int = 0
    failures: Counter[str] = field(default_factory=Counter)
    add_frame_s: float = 0.0
    save_episode_s: float = 0.0
    finalize_s: float = 0.0

    def to_json(self) -> dict[str, Any]:
        return {
            "episodes_written": self.episodes_written,
            "frames_written": self.frames_written,
            "frames_discarded": self.frames_discarded,
            "episodes_failed": sum(self.failures.values()),
            "failures": dict(sorted(self.failures.items())),
            "timings_s": {"add_frame": self.add_frame_s, "save_episode": self.save_episode_s,
                          "finalize": self.finalize_s},
        }  # fmt: skip


class _State(Enum):
    NEW = "new"
    OPEN = "open"
    IN_EPISODE = "in_episode"
    CLOSED = "closed"


class _LerobotBackend:
    """Writes through ``LeRobotDataset.create`` / ``add_frame`` / ``save_episode`` / ``finalize``."""

    def __init__(self, root: Path, spec: DatasetSpec, repo_id: str, encoder_threads: int | None,
                 queue_frames: int) -> None:  # fmt: skip
        self.root, self.spec, self.repo_id = root, spec, repo_id
        self._encoder_threads, self._queue_frames = encoder_threads, queue_frames
        self._ds: Any = None

    def open(self) -> None:
        import_lerobot()
        from lerobot.configs import RGBEncoderConfig

        v = self.spec.video
        rgb = RGBEncoderConfig(vcodec=v.codec, pix_fmt=v.pix_fmt, g=v.gop, crf=v.crf, preset=v.preset)
        self._ds = _blocking_encoder_dataset_class().create(
            self.repo_id,
            fps=self.spec.fps,
            features=self.spec.features(),
            root=self.root,
            robot_type=self.spec.robot_type,
            use_videos=True,
            video_backend="pyav",
            rgb_encoder=rgb,
            streaming_encoding=True,
            encoder_queue_maxsize=self._queue_frames,
            encoder_threads=self._encoder_threads,
            image_writer_threads=0,
            data_files_size_in_mb=self.spec.data_files_size_mb,
            video_files_size_in_mb=self.spec.video_files_size_mb,
        )
        self._ds.meta.info.chunks_size = self.spec.chunk_size
        self._depth_samples: dict[str, list[np.ndarray]] = {}
        save_meta = self._ds.meta.save_episode

        def save_episode(episode_index, episode_length, episode_tasks, episode_stats, episode_metadata):
            # lerobot computes no stats of string features: add the depth frames' image stats [mm]
            from lerobot.datasets.compute_stats import sample_indices

            for key, frames in self._depth_samples.items():
                sampled = np.stack([frames[i] for i in sample_indices(len(frames))])
                episode_stats[key] = image_stats(sampled, scale=1.0)
            self._depth_samples = {}
            return save_meta(episode_index, episode_length, episode_tasks, episode_stats, episode_metadata)

        self._ds.meta.save_episode = save_episode

    def add(self, frame: Frame, task: str) -> None:
        row: dict[str, Any] = {STATE_KEY: frame.state(), ACTION_KEY: frame.action(), "task": task}
        if self.spec.subtasks:
            row[SUBTASK_KEY] = np.array([frame.subtask_index], np.int64)
        if self.spec.environment_state:
            row[ENV_STATE_KEY] = np.asarray(frame.environment_state, np.float32)
        for cam, key in self.spec.rgb_keys().items():
            row[key] = frame.rgb[cam]
        for cam, key in self.spec.depth_keys().items():
            d = frame.depth_mm[cam].reshape(frame.depth_mm[cam].shape[:2])
            row[key] = encode_depth(d)
            self._depth_samples.setdefault(key, []).append(stats_sample(d[None]))
        self._ds.add_frame(row)

    def save(self, task: str) -> None:
        self._ds.save_episode()

    def discard(self) -> None:
        self._ds.clear_episode_buffer()
        self._depth_samples = {}

    def finalize(self) -> None:
        self._ds.finalize()


def _blocking_encoder_dataset_class() -> type:
    """A LeRobotDataset subclass whose streaming encoder never drops frames (blocks on a full queue)."""
    lds = import_lerobot()
    from lerobot.datasets.video_utils import StreamingVideoEncoder

    class _BlockingStreamingVideoEncoder(StreamingVideoEncoder):
        def feed_frame(self, video_key: str, image: np.ndarray) -> None:
            if not self._episode_active:
                raise RuntimeError("No active episode. Call start_episode() first.")
            thread, frames = self._threads[video_key], self._frame_queues[video_key]
            item = np.array(image, copy=True)
            while True:
                try:
                    frames.put(item, timeout=1.0)
                    return
                except queue.Full:
                    if not thread.is_alive():
                        raise RuntimeError(f"video encoder thread for {video_key} died") from None

    class _Dataset(lds.LeRobotDataset):
        @staticmethod
        def _build_streaming_encoder(fps, rgb_encoder, depth_encoder, encoder_queue_maxsize, encoder_threads):
            return _BlockingStreamingVideoEncoder(
                fps=fps, rgb_encoder=rgb_encoder, depth_encoder=depth_encoder,
                queue_maxsize=encoder_queue_maxsize, encoder_threads=encoder_threads,
            )  # fmt: skip

    return _Dataset


BACKENDS = ("direct", "lerobot")


class EpisodeWriter:
    """Writes episodes of ``spec`` into a new LeRobot v3.0 dataset at ``root`` (see module docstring).

    backend: ``"direct"`` (default; :mod:`stages.dataset.direct`, the same format written without
    lerobot's per-frame overheads) or ``"lerobot"`` (lerobot's own writer);
    encoder_threads: threads per video encoder (``None``: the codec decides);
    queue_frames: frames buffered per camera before add_frame blocks on the encoder;
    inline_encoding: the direct backend encodes RGB and depth in add_frame's thread (no encoder or
    depth threads: what a shard pool's writer process wants, see :class:`~stages.dataset.direct.DirectBackend`).
    """

    def __init__(
        self,
        root: Path,
        spec: DatasetSpec,
        *,
        backend: str = "direct",
        repo_id: str = "agentworld/dataset",
        encoder_threads: int | None = 1,
        queue_frames: int = 60,
        inline_encoding: bool = False,
    ) -> None:
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
        if inline_encoding and backend != "direct":
            raise ValueError(f"inline_encoding needs the direct backend, got backend {backend!r}")
        self.root = Path(root)
        self.spec = spec
        self.repo_id = repo_id
        self.backend = backend
        self.stats = WriterStats()
        self._encoder_threads = encoder_threads
        self._queue_frames = queue_frames
        self._inline_encoding = inline_encoding
        self._state = _State.NEW
        self._impl: Any = None
        self._episode: EpisodeInfo | None = None
        self._episode_frames = 0
        self._reached: list[int] = []  # the episode's stages (subtask_index) in the order its frames enter them
        self._columns: list[dict[str, Any]] = []  # extra meta/episodes columns, by episode index

    # -- lifecycle -------------------------------------------------------------------------------
    def open(self) -> EpisodeWriter:
        """Create the dataset folder (must not exist) and the backend's writer."""
        self._require(_State.NEW, "open")
        if self.root.exists():
            raise FileExistsError(f"{self.root}: dataset folder already exists")
        args = (self.root, self.spec, self.repo_id, self._encoder_threads, self._queue_frames)
        if self.backend == "lerobot":
            impl: Any = _LerobotBackend(*args)
        else:
            impl = DirectBackend(*args, inline=self._inline_encoding)
        impl.open()
        self._impl = impl
        self._state = _State.OPEN
        return self

    def close(self) -> WriterStats:
        """Finish the dataset: flush the writers, add the episode columns, write the sidecar."""
        if self._state is _State.IN_EPISODE:
            raise RuntimeError(f"{self.root}: close() inside an episode; call end_episode() first")
        self._require(_State.OPEN, "close")
        t0 = time.perf_counter()
        self._impl.finalize()
        canonical_stats(self.root)
        if self._columns:
            add_episode_columns(self.root, self._columns)
        extra = {"repo_id": self.repo_id, "backend": self.backend}
        write_sidecar(self.root, self.spec, self.stats, extra=extra)
        self.stats.finalize_s = time.perf_counter() - t0
        self._state = _State.CLOSED
        logger.info("%s: %d episodes, %d frames written, %d failed", self.root,
                    self.stats.episodes_written, self.stats.frames_written, sum(self.stats.failures.values()))
        return self.stats

    def abort(self) -> None:
        """Stop writing and delete the folder (used when an exception escapes the recording loop)."""
        if self._state in (_State.OPEN, _State.IN_EPISODE) and self._impl is not None:
            try:
                if self._state is _State.IN_EPISODE:
                    self._impl.discard()
                self._impl.finalize()
            finally:
                shutil.rmtree(self.root, ignore_errors=True)
        self._state = _State.CLOSED

    def __enter__(self) -> EpisodeWriter:
        return self.open() if self._state is _State.NEW else self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    # -- episodes --------------------------------------------------------------------------------
    def begin_episode(self, info: EpisodeInfo) -> None:
        """Start an episode; its frames are buffered (video encoded as they arrive) until end_episode."""
        self._require(_State.OPEN, "begin_episode")
        problems = info.problems()
        if problems:
            raise FrameError(f"{self.root}: episode info: " + "; ".join(problems))
        self._episode, self._episode_frames, self._reached = info, 0, []
        self._state = _State.IN_EPISODE

    def add_frame(self, frame: Frame, *, validated: bool = False) -> None:
        """Validate and append one frame (timestamp = frame_index / fps). ``validated``: the caller
        has checked it against this writer's spec already (a ShardPool does, in the engine's process).
        The direct backend copies what it keeps: the frame's arrays may be reused once this returns."""
        self._require(_State.IN_EPISODE, "add_frame")
        if not validated:
            validate_frame(self.spec, frame, where=f"{self.root} frame {self._episode_frames}")
        t0 = time.perf_counter()
        self._impl.add(frame, self._episode.task)
        self.stats.add_frame_s += time.perf_counter() - t0
        self._episode_frames += 1
        if self.spec.subtasks and (not self._reached or self._reached[-1] != int(frame.subtask_index)):
            self._reached.append(int(frame.subtask_index))

    def end_episode(self, success: bool, reason: str = "") -> EpisodeOutcome:
        """Write the episode if ``success`` (and it has frames), else discard it and count ``reason``."""
        self._require(_State.IN_EPISODE, "end_episode")
        n, info = self._episode_frames, self._episode
        self._state, self._episode = _State.OPEN, None
        if not success or n == 0:
            why = (reason or "unspecified") if not success else "no frames"
            self._impl.discard()
            self.stats.failures[why] += 1
            self.stats.frames_discarded += n
            return EpisodeOutcome(False, None, n, why)
        t0 = time.perf_counter()
        self._impl.save(info.task)
        self.stats.save_episode_s += time.perf_counter() - t0
        index = self.stats.episodes_written
        self._columns.append(episode_columns(info, success=True,
                                             reached=tuple(self._reached) if self.spec.subtasks else None))
        self.stats.episodes_written += 1
        self.stats.frames_written += n
        return EpisodeOutcome(True, index, n)

    def _require(self, state: _State, op: str) -> None:
        if self._state is not state:
            raise RuntimeError(
                f"{self.root}: {op}() needs writer state {state.value}, it is {self._state.value}"
            )


def add_episode_columns(root: Path, columns: list[dict[str, Any]]) -> None:
    """Append the agentworld/ columns to every ``meta/episodes`` parquet file (rows by episode_index)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    for path in sorted((root / "meta" / "episodes").glob("*/*.parquet")):
        table = pq.read_table(path)
        idx = table.column("episode_index").to_pylist()
        for name in columns[0]:
            values = [columns[i][name] for i in idx]
            table = table.append_column(name, pa.array(values))
        tmp = path.with_suffix(".parquet.tmp")
        pq.write_table(table, tmp, compression="snappy")
        os.replace(tmp, path)


def write_sidecar(
    root: Path, spec: DatasetSpec, stats: WriterStats, extra: dict[str, Any] | None = None
) -> None:
    """Write ``meta/agentworld.json`` (atomically: temp file, fsync, rename)."""
    data = {"format": "agentworld-lerobot-v3.0", "spec": spec.to_json(), **stats.to_json(), **(extra or {})}
    write_json_atomic(root / SIDECAR_PATH, data)


def canonical_stats(root: Path) -> None:
    """Rewrite ``meta/stats.json`` with its features in ``meta/info.json``'s order (same values).

    lerobot's ``aggregate_stats`` collects the feature keys in a set, so the file's key order follows
    the process's string hash seed: two processes writing the same episodes wrote different bytes."""
    path, info = root / "meta" / "stats.json", root / "meta" / "info.json"
    if not path.is_file() or not info.is_file():
        return
    stats = json.loads(path.read_text())
    order = list(json.loads(info.read_text()).get("features", {}))
    keys = [k for k in order if k in stats] + sorted(k for k in stats if k not in order)
    text = json.dumps({k: stats[k] for k in keys}, indent=4, ensure_ascii=False)
    if text != path.read_text():
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(text)
        os.replace(tmp, path)


def write_json_atomic(path: Path, data: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w") as f:
        json.dump(data, f, indent=2, sort_keys=True)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def read_sidecar(root: Path) -> dict[str, Any]:
    """The ``meta/agentworld.json`` of a dataset written by this package."""
    path = Path(root) / SIDECAR_PATH
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: missing (not a complete AgentWorld dataset)") from None
