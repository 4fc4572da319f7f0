"""The direct writer's faster encoding keeps the data: statistics equal lerobot's, RGB colours and
quality as the encoder's own conversion gave, video durations as lerobot measures them (issue 12)."""

from __future__ import annotations

import io
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("lerobot.datasets")
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from bench_encode import decode_video, psnr, render_like_frames, ssim  # noqa: E402


def _columns(n: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Episode columns like the writer's: float32 vectors, int64 counters, float32 timestamps, a
    constant column, rounded values (repeated histogram bins) and float64 values of wide range."""
    return {
        "observation.state": rng.normal(size=(n, 9)).astype(np.float32),
        "action": np.round(rng.normal(size=(n, 4)), 1).astype(np.float32),
        "timestamp": (np.arange(n) / 30).astype(np.float32),
        "index": np.arange(100, 100 + n, dtype=np.int64),
        "task_index": np.full(n, 3, np.int64),
        "wide": rng.normal(size=(n, 3)) * 1e4,
    }


@pytest.mark.parametrize("n", [1, 2, 3, 30, 451])
def test_numeric_episode_stats_equal_lerobots_bit_for_bit(n):
    from lerobot.datasets.compute_stats import compute_episode_stats

    from stages.dataset.stats import numeric_episode_stats

    cols = _columns(n, np.random.default_rng(n))
    features = {k: {"dtype": "float32"} for k in cols}
    want, got = compute_episode_stats(cols, features), numeric_episode_stats(cols, features)
    assert want.keys() == got.keys()
    for key in want:
        assert want[key].keys() == got[key].keys(), key
        for stat, w in want[key].items():
            g = got[key][stat]
            assert (g.dtype, g.shape) == (w.dtype, w.shape), (key, stat)
            np.testing.assert_array_equal(g, w, err_msg=f"{key} {stat}")


def test_numeric_episode_stats_of_a_nearly_constant_float32_column_warn_nothing():
    """A float32 dimension whose range is below 5,000 ulps of its value (a coordinate held still, e.g.
    the base at x = 1002.06 m, moving 0.16 m) has repeated histogram edges. The quantiles' vectorised
    interpolation multiplied -inf (an empty bin, masked afterwards) by a zero bin width there: numpy's
    ``invalid value encountered in multiply`` on every such episode; the values are lerobot's."""
    import warnings

    from lerobot.datasets.compute_stats import compute_episode_stats

    from stages.dataset.stats import numeric_episode_stats

    held = np.r_[np.full(20, 1002.05817), np.full(39, 1002.21594)].astype(np.float32)
    cols = {"observation.state": np.stack([held, np.linspace(0, 1, held.size, dtype=np.float32)], axis=1)}
    features = {"observation.state": {"dtype": "float32"}}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = numeric_episode_stats(cols, features)["observation.state"]
    want = compute_episode_stats(cols, features)["observation.state"]
    for stat, w in want.items():
        assert np.isfinite(got[stat]).all(), stat
        np.testing.assert_array_equal(got[stat], w, err_msg=stat)


def test_video_frame_converts_like_the_encoder_within_a_level():
    import av

    from stages.dataset.direct import video_frame

    for rgb in render_like_frames(3, 240, 320):
        ours = video_frame(rgb, "yuv420p").to_ndarray().astype(int)  # (360, 320): Y, then U and V
        sws = av.VideoFrame.from_ndarray(rgb, format="rgb24").reformat(format="yuv420p").to_ndarray()
        diff = np.abs(ours - sws)
        assert diff[:240].max() <= 1  # luma: the same BT.601 limited-range matrix
        assert diff[240:].mean() < 1.0 and diff[240:].max() <= 10  # chroma: 2x2 means, close to swscale's
    odd = render_like_frames(1, 49, 64)[0]  # odd height: the encoder converts
    assert video_frame(odd, "yuv420p").format.name == "rgb24"


def test_video_frame_chroma_within_a_level_of_bt601_limited_range():
    """U and V of each 2x2 block: BT.601 limited range of the block's mean (OpenCV's INTER_AREA
    half-size image) rounded, within one level (full-range YCrCb through a table rounds twice)."""
    import cv2

    from stages.dataset.direct import video_frame

    for rgb in render_like_frames(3, 240, 320):
        yuv = video_frame(rgb, "yuv420p").to_ndarray().astype(float)
        half = cv2.resize(rgb, (160, 120), interpolation=cv2.INTER_AREA).astype(float)
        r, g, b = half[..., 0], half[..., 1], half[..., 2]
        u = 128 + (-37.797 * r - 74.203 * g + 112.0 * b) / 255
        v = 128 + (112.0 * r - 93.786 * g - 18.214 * b) / 255
        assert np.abs(yuv[240:300].reshape(120, 160) - np.round(u)).max() <= 1
        assert np.abs(yuv[300:].reshape(120, 160) - np.round(v)).max() <= 1


def _encode(frames: np.ndarray, convert) -> bytes:
    import av

    buf = io.BytesIO()
    with av.open(buf, "w", format="mp4") as c:
        opts = {"g": "30", "crf": "23", "preset": "ultrafast", "threads": "1"}
        st = c.add_stream("libx264", 30, options=opts)
        st.width, st.height, st.pix_fmt = frames.shape[2], frames.shape[1], "yuv420p"
        st.time_base = Fraction(1, 30)
        for i, f in enumerate(frames):
            vf = convert(f)
            vf.pts = i
            for p in st.encode(vf):
                c.mux(p)
        for p in st.encode():
            c.mux(p)
    return buf.getvalue()


def test_converted_frames_encode_to_the_same_quality():
    import av

    from stages.dataset.direct import video_frame

    raw = render_like_frames(30, 240, 320)
    old = _encode(raw, lambda f: av.VideoFrame.from_ndarray(f, format="rgb24"))  # the encoder converts
    new = _encode(raw, lambda f: video_frame(f, "yuv420p"))
    d_old, d_new = decode_video(old), decode_video(new)
    assert d_new.shape == raw.shape
    assert psnr(raw, d_new) >= psnr(raw, d_old) - 0.05, (psnr(raw, d_new), psnr(raw, d_old))
    assert ssim(raw, d_new) >= ssim(raw, d_old) - 0.002
    assert len(new) < 1.1 * len(old)


@pytest.mark.parametrize("codec", ["h264", "hevc"])
def test_episode_video_duration_is_lerobots(tmp_path, codec):
    from lerobot.configs import RGBEncoderConfig
    from lerobot.datasets.video_utils import get_video_duration_in_s

    from stages.dataset.direct import DirectBackend, _VideoStream
    from stages.dataset.schema import CameraSpec, DatasetSpec, VideoCodecSpec

    frames = render_like_frames(4, 48, 64)
    for fps in (30, 7):
        spec = DatasetSpec(cameras=(CameraSpec("head", 48, 64),), fps=fps,
                           video=VideoCodecSpec(codec=codec, preset="veryfast"))  # fmt: skip
        backend = DirectBackend(tmp_path, spec, "t/t", 1, 8)
        for n in (1, 2, 31) if codec == "h264" else (3, 31):  # libx265 fails on flushing 1-2 frames
            enc = RGBEncoderConfig(vcodec=codec, pix_fmt="yuv420p", g=30, crf=23, preset="veryfast")
            stream = _VideoStream(tmp_path / f"{codec}-{fps}-{n}" / "v" / "e.mp4", fps, enc, 1, 48, 64, 8)
            for i in range(n):
                stream.put(frames[i % 4])
            stream.close()
            assert backend._duration(stream.path, n) == get_video_duration_in_s(stream.path), (fps, n)


def test_a_failed_flush_is_reported_by_close_not_a_hang(tmp_path):
    """The encoder thread takes the end marker, then the flush fails: close() raises (it waited for a
    second end marker before, and CI ran into its time limit)."""
    from lerobot.configs import RGBEncoderConfig

    from stages.dataset.direct import _VideoStream

    class _FailingFlush(_VideoStream):
        def _encode(self, frame):
            if frame is None:
                raise OSError("flush failed")
            super()._encode(frame)

    enc = RGBEncoderConfig(vcodec="h264", pix_fmt="yuv420p", g=30, crf=23, preset="veryfast")
    stream = _FailingFlush(tmp_path / "v" / "c" / "e.mp4", 30, enc, 1, 48, 64, 8)
    stream.put(render_like_frames(1, 48, 64)[0])
    with pytest.raises(RuntimeError, match="flush failed"):
        stream.close()
    assert stream._thread is not None and not stream._thread.is_alive()
