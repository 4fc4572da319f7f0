"""The ``direct`` writer backend: LeRobot v3.0 written without lerobot's per-frame overheads.

Why: lerobot 0.6's streaming writer computes running quantile statistics on every RGB frame in its
encoder threads (4-11 ms per 320x240 frame and camera), stages depth frames as raw TIFF files embedded
uncompressed, and re-muxes the whole growing mp4 of a camera at every episode. Measured with
``tests/benchmarks/bench_dataset.py`` (3 RGB + 3 depth cameras at 320x240, one writer process): on the
16-core GPU host, lerobot's writer 149 frames/s, this one 364 frames/s (PyAV alone encodes the 3 RGB
streams at 739 frames/s); on the 2-core machine, shared, 13.5 vs 22.4 frames/s. Depth takes 450 KB per
frame with lerobot's TIFFs, 14 KB with these PNGs (synthetic test depth; a noise-free rendered room
compresses about 70x, depth with +-3 mm noise about 3x).

What is the same: the metadata goes through lerobot's own ``LeRobotDatasetMetadata`` (``create``,
``save_episode_tasks``, ``save_episode`` with per-episode stats, ``update_video_info``, ``finalize``),
so ``meta/info.json``, ``meta/tasks.parquet``, ``meta/episodes`` and ``meta/stats.json`` are lerobot's;
the data parquet has lerobot's Hugging Face schema (one row group per episode, snappy, rolled over at
``data_files_size_mb`` like lerobot); RGB is mp4 with the configured codec (frames converted to
yuv420p by :func:`video_frame`); numeric statistics are lerobot's ``compute_episode_stats`` (the same
values, computed faster: :mod:`stages.dataset.stats`); image statistics use the frames lerobot's
``sample_indices`` picks, in lerobot's layout, subsampled to at most 80 pixels a side and with exact
quantiles (lerobot estimates them from histograms).

What differs (all inside the v3.0 format, which maps every episode to a chunk/file and timestamps):
each episode's video is its own mp4 file (``videos/<key>/chunk-XXX/file-YYY.mp4``, from_timestamp 0),
so a failed episode is deleted without touching others and nothing is re-muxed; merging with
lerobot's aggregation packs them into size-limited files. Depth frames are 16-bit PNG (lossless,
zlib level 1, :mod:`stages.dataset.depth`) in ``depth.<camera>`` string columns, encoded as the
frames come by two threads shared by the process's writers; their stats are image stats in
millimetres, like lerobot's depth maps'.
The tests prove the result by loading it with ``LeRobotDataset`` and a torch DataLoader.
"""

from __future__ import annotations

import logging
import os
import queue
import threading
from concurrent.futures import Future, ThreadPoolExecutor
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

from ._lerobot import import_lerobot
from .depth import encode_depth
from .schema import ACTION_KEY, ENV_STATE_KEY, STATE_KEY, SUBTASK_KEY, DatasetSpec, Frame
from .stats import image_stats, numeric_episode_stats, stats_sample

logger = logging.getLogger(__name__)

# libx265 through FFmpeg 7.1 raises AVERROR_PATCHWELCOME on flushing 1 or 2 frames in about half of
# the tries at any frame size (measured 2026-11-26: 3, 5, 8 and 31 frames flushed 100 of 100 times)
_SHORT_FLUSH_FRAMES = 3


class _VideoStream:
    """One camera's episode video. ``threaded``: frames are encoded by a thread of the stream (PyAV
    releases the GIL) as they come, and put() blocks when ``queue_frames`` frames wait (never drops
    a frame); else put() encodes the frame before it returns (a pool's writer process: its parallelism
    is the processes, and a thread per stream only adds hand-overs, see :class:`DirectBackend`)."""

    def __init__(self, path: Path, fps: int, encoder: Any, threads: int | None, height: int, width: int,
                 queue_frames: int, threaded: bool = True) -> None:  # fmt: skip
        import av

        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self._container = av.open(str(path), "w")
        options = encoder.get_codec_options(threads, as_strings=True)
        stream = self._container.add_stream(encoder.vcodec, fps, options=options)
        stream.pix_fmt, stream.width, stream.height = encoder.pix_fmt, width, height
        stream.time_base = Fraction(1, fps)
        self._stream = stream
        self._pts = 0
        self._error: BaseException | None = None
        self._thread: threading.Thread | None = None
        if threaded:
            self._queue: queue.Queue = queue.Queue(maxsize=queue_frames)
            name = f"encode-{path.parent.parent.name}"
            self._thread = threading.Thread(target=self._run, name=name, daemon=True)
            self._thread.start()

    def _encode(self, frame: Any) -> None:
        """Encode and mux one frame (``None``: flush the encoder)."""
        if frame is not None:
            frame.pts = self._pts
            self._pts += 1
        try:
            for packet in self._stream.encode(frame):
                self._container.mux(packet)
        except Exception as e:
            if frame is None and self._pts < _SHORT_FLUSH_FRAMES and "265" in self._stream.codec_context.name:
                raise RuntimeError(f"{e}: libx265 (PyAV 15, FFmpeg 7.1) fails to flush {self._pts} frame(s) in "
                                   f"about half of the tries; episodes of hevc video need at least "
                                   f"{_SHORT_FLUSH_FRAMES} frames") from e
            raise

    def _run(self) -> None:
        ended = False  # the end marker (None) was taken from the queue
        try:
            while (frame := self._queue.get()) is not None:
                self._encode(frame)
            ended = True
            self._encode(None)
        except BaseException as e:  # reported to the caller by put() / close()
            self._error = e
            # drain so that put() never blocks forever; after the end marker nothing more comes
            while not ended and self._queue.get() is not None:
                pass
        finally:
            self._container.close()

    def put(self, img: np.ndarray) -> None:
        """Encode ``img`` (uint8 (H, W, 3)); it is copied (into the video frame) before this returns."""
        if self._error is not None:
            raise RuntimeError(f"{self.path}: video encoding failed: {self._error}") from self._error
        frame = video_frame(img, self._stream.pix_fmt)
        if self._thread is not None:
            self._queue.put(frame)
            return
        try:
            self._encode(frame)
        except Exception as e:
            self._error = e
            raise RuntimeError(f"{self.path}: video encoding failed: {e}") from e

    def _stop(self, flush: bool) -> None:
        if self._thread is not None:
            self._queue.put(None)
            self._thread.join()
            return
        try:
            if flush and self._error is None:
                self._encode(None)
        except Exception as e:
            self._error = e
        finally:
            self._container.close()

    def close(self) -> None:
        self._stop(flush=True)
        if self._error is not None:
            raise RuntimeError(f"{self.path}: video encoding failed: {self._error}") from self._error

    def discard(self) -> None:
        self._stop(flush=False)
        self.path.unlink(missing_ok=True)


# BT.601 chroma: OpenCV's YCrCb is full range (Cb = 128 + 0.564 (B - Y)), the encoder's limited
# range (U = 128 + 112/255 (B - Y) / 0.886): the same axis scaled by 224/255 around 128, as a table
_FULL_TO_LIMITED_CHROMA = np.clip(np.round(128.0 + (np.arange(256) - 128.0) * 224.0 / 255.0), 0, 255).astype(
    np.uint8)  # fmt: skip


def video_frame(rgb: np.ndarray, pix_fmt: str) -> Any:
    """An ``av.VideoFrame`` of uint8 (H, W, 3) RGB for a stream of ``pix_fmt``, not sharing ``rgb``'s memory.

    For yuv420p of even size the frame is converted here (BT.601, limited range, as the encoder's
    swscale does): luma from OpenCV's ``COLOR_RGB2YUV_I420`` (within 1 level of swscale's), chroma
    of the mean of each 2x2 block (``INTER_AREA``; OpenCV's I420 takes one pixel of each block,
    which costs 0.6 dB): OpenCV's full-range ``COLOR_RGB2YCrCb`` of the half-size image, then a
    table to limited range (within 1 level of the rounded exact value; ``cv2.transform`` with the
    limited range matrix did it in one rounding: resize + chroma 0.29 ms per 240x320 frame, now 0.17
    ms, medians of 15 alternated batches in one process, OpenCV single-threaded, the shared 2-core
    machine; luma unchanged; 25% of chroma samples differ by 1 level). Against an RGB frame and swscale in the
    encoder (0.37 ms): decoded PSNR 0.1 dB higher, files 2% larger (``tests/stages/test_dataset_encode.py``).
    CPU figures with OpenCV single-threaded (as in the shard pool's workers).
    Other formats and sizes go to the encoder as RGB (it converts)."""
    import av

    h, w = rgb.shape[:2]
    if pix_fmt != "yuv420p" or h % 2 or w % 2:
        return av.VideoFrame.from_ndarray(np.ascontiguousarray(rgb), format="rgb24")
    import cv2

    out = cv2.cvtColor(rgb, cv2.COLOR_RGB2YUV_I420)  # (3H/2, W): Y (H, W), then U and V (H/4, W) each
    half = cv2.resize(rgb, (w // 2, h // 2), interpolation=cv2.INTER_AREA)
    ycc = cv2.LUT(cv2.cvtColor(half, cv2.COLOR_RGB2YCrCb), _FULL_TO_LIMITED_CHROMA)  # Y (unused), Cr, Cb
    q = h // 4
    out[h:h + q] = ycc[..., 2].reshape(q, w)
    out[h + q:] = ycc[..., 1].reshape(q, w)
    return av.VideoFrame.from_numpy_buffer(out, format="yuv420p")


_DEPTH_THREADS = 2
_depth_pool: tuple[int, ThreadPoolExecutor] | None = None  # (pid that made it, executor)
_depth_pool_lock = threading.Lock()


def _depth_executor() -> ThreadPoolExecutor:
    """The process's depth PNG threads, shared by every writer of the process (a writer process
    holds a hundred shards: two threads each made hundreds of threads). A forked child makes its
    own (the parent's threads do not exist there)."""
    global _depth_pool
    with _depth_pool_lock:
        if _depth_pool is None or _depth_pool[0] != os.getpid():
            _depth_pool = (os.getpid(), ThreadPoolExecutor(max_workers=_DEPTH_THREADS,
                                                           thread_name_prefix="depth-png"))
        return _depth_pool[1]


class DirectBackend:
    """Backend of :class:`~stages.dataset.writer.EpisodeWriter` (same calls as its lerobot backend).

    ``inline``: encode RGB and depth in the calling thread, in add() (a shard pool's writer process,
    which holds a hundred shards: a thread per video stream and the depth threads made every frame
    six hand-overs between threads under the GIL; the files are the same bytes). Else videos are
    encoded by a thread per stream and depth by the process's two depth threads, beside the caller.
    """

    def __init__(self, root: Path, spec: DatasetSpec, repo_id: str, encoder_threads: int | None,
                 queue_frames: int, inline: bool = False) -> None:  # fmt: skip
        self.root, self.spec, self.repo_id = root, spec, repo_id
        self._encoder_threads, self._queue_frames = encoder_threads, queue_frames
        self._inline = inline
        self.meta: Any = None
        self._pq: Any = None
        self._data_file = 0  # running data file number (chunk = n // chunk_size)
        self._file_start_frame = 0
        self._video_file = 0  # running video file number (one file per episode and camera)
        self._reset_episode()

    def _reset_episode(self) -> None:
        self._videos: dict[str, _VideoStream] = {}
        self._states: list[np.ndarray] = []
        self._actions: list[np.ndarray] = []
        self._subtasks: list[int] = []
        self._env: list[np.ndarray] = []
        self._depth_png: dict[str, list[Future | str]] = {k: [] for k in self.spec.depth_keys().values()}
        self._samples: dict[str, list[np.ndarray]] = {}  # downsampled (C, h, w) copies for image stats

    # -- lifecycle ---------------------------------------------------------------------------------
    def open(self) -> None:
        import_lerobot()
        from lerobot.configs import RGBEncoderConfig
        from lerobot.datasets.dataset_metadata import LeRobotDatasetMetadata
        from lerobot.datasets.feature_utils import get_hf_features_from_features

        s = self.spec
        self.meta = LeRobotDatasetMetadata.create(
            repo_id=self.repo_id, fps=s.fps, features=s.features(), robot_type=s.robot_type, root=self.root,
            use_videos=True, chunks_size=s.chunk_size, data_files_size_in_mb=s.data_files_size_mb,
            video_files_size_in_mb=s.video_files_size_mb,
        )  # fmt: skip
        self._schema = get_hf_features_from_features(self.meta.features).arrow_schema
        v = s.video
        self._encoder = RGBEncoderConfig(
            vcodec=v.codec, pix_fmt=v.pix_fmt, g=v.gop, crf=v.crf, preset=v.preset
        )

    def finalize(self) -> None:
        if self._pq is not None:
            self._pq.close()
            self._pq = None
        if self.meta is not None:
            self.meta.finalize()

    # -- frames ------------------------------------------------------------------------------------
    def add(self, frame: Frame, task: str) -> None:
        if not self._states:
            self._open_videos()
        self._states.append(frame.state())
        self._actions.append(frame.action())
        self._subtasks.append(int(frame.subtask_index))
        if self.spec.environment_state:
            self._env.append(np.asarray(frame.environment_state, np.float32))
        for cam, key in self.spec.rgb_keys().items():
            img = frame.rgb[cam]
            self._videos[key].put(img)
            self._samples.setdefault(key, []).append(stats_sample(img.transpose(2, 0, 1)))
        for cam, key in self.spec.depth_keys().items():
            d = frame.depth_mm[cam].reshape(frame.depth_mm[cam].shape[:2])
            if self._inline:
                self._depth_png[key].append(encode_depth(d))
            else:
                self._depth_png[key].append(_depth_executor().submit(encode_depth, d.copy()))
            self._samples.setdefault(key, []).append(stats_sample(d[None]))

    def _open_videos(self) -> None:
        chunk, file = divmod(self._video_file, self.spec.chunk_size)
        for cam in self.spec.cameras:
            if cam.rgb:
                key = self.spec.rgb_keys()[cam.name]
                rel = self.meta.video_path.format(video_key=key, chunk_index=chunk, file_index=file)
                path = self.root / rel
                self._videos[key] = _VideoStream(path, self.spec.fps, self._encoder, self._encoder_threads,
                                                 cam.height, cam.width, self._queue_frames,
                                                 threaded=not self._inline)  # fmt: skip

    def discard(self) -> None:
        for stream in self._videos.values():
            stream.discard()
        for futures in self._depth_png.values():
            for f in futures:
                if isinstance(f, Future):
                    f.cancel()
        self._reset_episode()

    # -- saving ------------------------------------------------------------------------------------
    def save(self, task: str) -> None:
        n = len(self._states)
        ep_index, start = self.meta.total_episodes, self.meta.total_frames
        self.meta.save_episode_tasks([task])
        task_index = self.meta.get_task_index(task)
        columns = {
            STATE_KEY: np.stack(self._states),
            ACTION_KEY: np.stack(self._actions),
            "timestamp": (np.arange(n) / self.spec.fps).astype(np.float32),
            "frame_index": np.arange(n, dtype=np.int64),
            "episode_index": np.full(n, ep_index, dtype=np.int64),
            "index": np.arange(start, start + n, dtype=np.int64),
            "task_index": np.full(n, task_index, dtype=np.int64),
        }
        if self.spec.subtasks:
            columns[SUBTASK_KEY] = np.asarray(self._subtasks, dtype=np.int64)
        if self.spec.environment_state:
            columns[ENV_STATE_KEY] = np.stack(self._env)
        chunk, file = divmod(self._video_file, self.spec.chunk_size)
        ep_meta: dict[str, Any] = {}
        for key, stream in self._videos.items():
            stream.close()
            ep_meta.update({f"videos/{key}/chunk_index": chunk, f"videos/{key}/file_index": file,
                            f"videos/{key}/from_timestamp": 0.0,
                            f"videos/{key}/to_timestamp": self._duration(stream.path, n)})  # fmt: skip
        depth = {key: [f.result() if isinstance(f, Future) else f for f in futs]
                 for key, futs in self._depth_png.items()}  # fmt: skip
        ep_meta.update(self._write_data(columns, depth, start, n))
        stats = self._episode_stats(columns)
        self.meta.save_episode(ep_index, n, [task], stats, ep_meta)
        if ep_index == 0:
            from lerobot.datasets.io_utils import write_info

            for key in self._videos:
                self.meta.update_video_info(key, video_encoder=self._encoder)
            write_info(self.meta.info, self.root)
        if self._videos:
            self._video_file += 1
        self._reset_episode()

    def _duration(self, path: Path, n: int) -> float:
        """[s] of an episode's video of ``n`` frames: lerobot's ``get_video_duration_in_s`` (the mp4
        stream's duration), which is n / fps exactly for the x264 and x265 streams written here (tested),
        so those are not opened again; other codecs are probed."""
        if self.spec.video.codec in ("h264", "hevc"):
            return n / self.spec.fps
        from lerobot.datasets.video_utils import get_video_duration_in_s

        return get_video_duration_in_s(path)

    def _write_data(self, columns: dict[str, np.ndarray], depth: dict[str, list], start: int, n: int) -> dict:
        import pyarrow as pa
        import pyarrow.parquet as pq
        from lerobot.datasets.io_utils import get_file_size_in_mb

        arrays = []
        for name, typ in zip(self._schema.names, self._schema.types, strict=True):
            if name in depth:
                arrays.append(pa.array(depth[name], type=typ))
            elif pa.types.is_fixed_size_list(typ):
                values = columns[name]
                flat = pa.array(values.reshape(-1))
                arrays.append(pa.FixedSizeListArray.from_arrays(flat, values.shape[1]))
            else:
                arrays.append(pa.array(columns[name], type=typ))
        table = pa.Table.from_arrays(arrays, schema=self._schema)
        if self._pq is not None:  # roll over like lerobot: size so far + this episode at the average rate
            size = get_file_size_in_mb(self._data_path())
            per_frame = size / max(start - self._file_start_frame, 1)
            if size + per_frame * n >= self.spec.data_files_size_mb:
                self._pq.close()
                self._pq = None
                self._data_file += 1
        if self._pq is None:
            path = self._data_path()
            path.parent.mkdir(parents=True, exist_ok=True)
            self._pq = pq.ParquetWriter(path, schema=table.schema, compression="snappy", use_dictionary=True)
            self._file_start_frame = start
        self._pq.write_table(table)
        chunk, file = divmod(self._data_file, self.spec.chunk_size)
        return {"data/chunk_index": chunk, "data/file_index": file,
                "dataset_from_index": start, "dataset_to_index": start + n}  # fmt: skip

    def _data_path(self) -> Path:
        chunk, file = divmod(self._data_file, self.spec.chunk_size)
        return self.root / self.meta.data_path.format(chunk_index=chunk, file_index=file)

    def _episode_stats(self, columns: dict[str, np.ndarray]) -> dict:
        """lerobot's per-episode stats: numeric columns equal to lerobot's compute_episode_stats
        (:func:`~stages.dataset.stats.numeric_episode_stats`); images on the frames lerobot's
        sample_indices picks, per channel, (C, 1, 1) arrays (RGB scaled to [0, 1], depth in mm), with
        exact quantiles where lerobot uses histogram estimates."""
        from lerobot.datasets.compute_stats import sample_indices

        stats = numeric_episode_stats(columns, self.meta.features)
        depth_keys = set(self.spec.depth_keys().values())
        for key, frames in self._samples.items():
            sampled = np.stack([frames[i] for i in sample_indices(len(frames))])
            stats[key] = image_stats(sampled, scale=1.0 if key in depth_keys else 255.0)
        return stats
