"""Decode-once frame cache for training on video datasets.

lerobot's ``LeRobotDataset.__getitem__`` decodes the frames of a sample by opening each camera's
video, seeking to the keyframe before the frame and decoding forward (PyAV): about 19 ms per sample
of three 128x96 cameras on the CPU, most of it opening and seeking, so that the data loader, not
the GPU, sets the pace of a training step. With the cache, the first query of a video file decodes
the whole file once in order (0.1-0.4 ms per frame) into ``DIR/<key>.frames.npy`` (uint8, (N, H, W,
3)) and ``DIR/<key>.ts.npy`` (float64 presentation times [s], (N,)); every later query, in any data
loader worker or training process that is given the same folder, reads the frames it needs from
that memory map (the page cache is shared). A query returns what lerobot's PyAV decoder returns:
the frame nearest each timestamp, (T, C, H, W), float32 in [0, 1] (uint8 with ``return_uint8``),
and the same ``FrameTimestampError`` beyond ``tolerance_s``. Depth videos go to lerobot's decoder.

Use: :func:`install` (``lerobot_train_run --frame-cache DIR``) replaces lerobot's
``DatasetReader._query_videos`` for RGB videos. Memory: N x H x W x 3 bytes per camera file (a family
of 64 episodes of ~400 frames at 128x96: about 0.95 GB for three cameras).
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np

_MEMO: dict[str, tuple[np.ndarray, np.ndarray]] = {}


def _key(video_path: Path) -> str:
    st = video_path.stat()
    return hashlib.sha1(f"{video_path.resolve()}|{st.st_size}|{st.st_mtime_ns}".encode()).hexdigest()[:20]


def decode_all(video_path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Every frame of ``video_path`` in order: (frames (N, H, W, 3) uint8, times (N,) [s])."""
    import av

    frames, times = [], []
    with av.open(str(video_path)) as container:
        stream = container.streams.video[0]
        for frame in container.decode(stream):
            if frame.pts is None:
                continue
            frames.append(frame.to_ndarray(format="rgb24"))
            times.append(float(frame.pts * stream.time_base))
    if not frames:
        raise ValueError(f"{video_path}: no frames could be decoded")
    return np.stack(frames), np.asarray(times, dtype=np.float64)


def cached_arrays(video_path: Path | str, cache_dir: Path | str) -> tuple[np.ndarray, np.ndarray]:
    """The frames and times of ``video_path`` from ``cache_dir`` (decoded and written there by the
    first caller; a concurrent first caller writes its own copy and the last rename wins)."""
    memo = f"{video_path}|{cache_dir}"  # a sample's hot path: no stat or hash once a file is open
    if memo in _MEMO:
        return _MEMO[memo]
    video_path, cache_dir = Path(video_path), Path(cache_dir)
    key = _key(video_path)
    fpath, tpath = cache_dir / f"{key}.frames.npy", cache_dir / f"{key}.ts.npy"
    if not (fpath.is_file() and tpath.is_file()):
        cache_dir.mkdir(parents=True, exist_ok=True)
        frames, times = decode_all(video_path)
        tag = f".tmp{os.getpid()}"
        for arr, path in ((times, tpath), (frames, fpath)):  # times first: frames present means both are
            tmp = path.with_name(path.name + tag)
            with tmp.open("wb") as f:
                np.save(f, arr)
            tmp.replace(path)
    out = (np.load(fpath, mmap_mode="r"), np.load(tpath))
    _MEMO[memo] = out
    return out


def query(video_path: Path | str, timestamps: list[float], tolerance_s: float, cache_dir: Path | str,
          return_uint8: bool = False):
    """The frames nearest ``timestamps`` [s] as lerobot's PyAV decoder returns them: a torch tensor
    (T, 3, H, W), float32 in [0, 1] or uint8; FrameTimestampError when one is over ``tolerance_s``."""
    import torch
    from lerobot.datasets.video_utils import FrameTimestampError

    frames, times = cached_arrays(video_path, cache_dir)
    q = np.asarray(timestamps, dtype=np.float64)
    hi = np.clip(np.searchsorted(times, q), 1, len(times) - 1) if len(times) > 1 else np.zeros(len(q), int)
    lo = np.maximum(hi - 1, 0)
    idx = np.where(np.abs(times[lo] - q) <= np.abs(times[hi] - q), lo, hi)
    err = np.abs(times[idx] - q)
    if not (err < tolerance_s).all():
        raise FrameTimestampError(f"{video_path}: query timestamps {q[err >= tolerance_s].tolist()} are more than "
                                  f"{tolerance_s=} from the nearest frame (frame cache)")
    out = torch.from_numpy(np.ascontiguousarray(frames[idx])).permute(0, 3, 1, 2).contiguous()
    return out if return_uint8 else out.type(torch.float32) / 255


def install(cache_dir: Path | str) -> None:
    """Make lerobot's dataset reader (``DatasetReader._query_videos``) take RGB video frames from
    the cache in ``cache_dir``, one camera after another (lerobot's own starts a thread pool per
    sample for several cameras, which costs more than the cached reads); depth videos as before."""
    from lerobot.datasets.dataset_reader import DatasetReader

    original = DatasetReader._query_videos

    def _query_videos(self, query_timestamps: dict[str, list[float]], ep_idx: int) -> dict:
        depth = {k: v for k, v in query_timestamps.items() if k in self._meta.depth_keys}
        out = original(self, depth, ep_idx) if depth else {}
        ep = self._meta.episodes[ep_idx]
        for key, ts in query_timestamps.items():
            if key in depth:
                continue
            start = ep[f"videos/{key}/from_timestamp"]
            path = self.root / self._meta.get_video_file_path(ep_idx, key)
            out[key] = query(path, [start + t for t in ts], self._tolerance_s, cache_dir,
                             return_uint8=self._return_uint8).squeeze(0)
        return out

    DatasetReader._query_videos = _query_videos
