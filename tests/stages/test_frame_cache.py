"""stages.policy.frame_cache: frames read from the decode-once cache equal lerobot's PyAV decoder's."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("lerobot")
av = pytest.importorskip("av")


def _video(path: Path, n: int = 45, fps: int = 30, gop: int = 10) -> None:
    """An H.264 video of ``n`` 32x24 frames whose pixels change with the frame (so a wrong frame shows)."""
    rng = np.random.default_rng(0)
    with av.open(str(path), "w") as c:
        s = c.add_stream("libx264", rate=fps)
        s.width, s.height, s.pix_fmt = 32, 24, "yuv420p"
        s.codec_context.gop_size = gop
        for i in range(n):
            img = np.full((24, 32, 3), (i * 5) % 256, np.uint8)
            img[: 4 + i % 16, :, 1] = rng.integers(0, 255)
            for p in s.encode(av.VideoFrame.from_ndarray(img, format="rgb24")):
                c.mux(p)
        for p in s.encode():
            c.mux(p)


def test_cached_frames_equal_lerobots_pyav_decoder(tmp_path):
    from lerobot.datasets.video_utils import FrameTimestampError, decode_video_frames_pyav

    from stages.policy import frame_cache

    video = tmp_path / "v.mp4"
    _video(video)
    rng = np.random.default_rng(1)
    cache = tmp_path / "cache"
    for _ in range(25):
        ts = sorted(float(t) for t in rng.integers(0, 45, size=2) / 30.0)
        ref = decode_video_frames_pyav(video, ts, tolerance_s=1e-4)
        got = frame_cache.query(video, ts, 1e-4, cache)
        assert got.dtype == ref.dtype and got.shape == ref.shape == (2, 3, 24, 32)
        assert np.array_equal(got.numpy(), ref.numpy())
        assert np.array_equal(frame_cache.query(video, ts, 1e-4, cache, return_uint8=True).numpy(),
                              decode_video_frames_pyav(video, ts, 1e-4, return_uint8=True).numpy())
    assert len(list(cache.glob("*.frames.npy"))) == 1 and len(list(cache.glob("*.ts.npy"))) == 1
    frames, times = frame_cache.cached_arrays(video, cache)
    assert frames.shape == (45, 24, 32, 3) and np.allclose(np.diff(times), 1 / 30)
    with pytest.raises(FrameTimestampError):
        frame_cache.query(video, [2.0], 1e-4, cache)  # past the last frame (1.467 s)
