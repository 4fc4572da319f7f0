"""Encoding throughput and quality: RGB video codecs in a pool of processes, and JPEG on CPU / GPU.

Run: ``.venv/bin/python -m pytest -q -m benchmark tests/benchmarks/bench_encode.py -s`` (CPU, short)
or ``python tests/benchmarks/bench_encode.py --device cuda --procs 16 --frames 240`` on the GPU host.
Prints a table and writes ``bench_results/encode.json``.

Content: synthetic render-like frames (uint8 (H, W, 3), 240x320 and 480x640): a textured floor and
wall panning with the camera, textured moving shapes with shading and shadows, and per-pixel noise
(sigma 3 levels), different in every frame. Each of ``procs`` processes encodes the same
``frames``-frame sequence (precomputed before the clock starts) with PyAV, one encoder thread each
(lerobot's ``encoder_threads`` = 1), into an in-memory mp4; frames/s = procs x frames / wall time
from a common start to the last finish. Quality: the stream of process 0 decoded back, against the
raw frames: PSNR [dB] over RGB and SSIM (Gaussian window, sigma 1.5, on luma).

Encoders (the ``VideoCodecSpec`` of ``stages.dataset.schema.CODEC_PRESETS``): x264 ultrafast and
veryfast (crf 23, GOP 30), libsvtav1 preset 10 and 12 with lerobot 0.6's defaults (crf 30, GOP 2;
preset 12 is lerobot's default). JPEG (quality 90) with ``torchvision.io.encode_jpeg``: on the CPU in
the same process pool, and on CUDA tensors (nvJPEG, batches of ``procs`` frames, time including the
copy of the bytes to the host; skipped without CUDA). Timings are medians of REPEATS runs.
"""

from __future__ import annotations

import argparse
import io
import json
import multiprocessing as mp
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import pytest

os.environ.setdefault("SVT_LOG", "1")  # SVT-AV1: errors only (its banner goes to stdout per stream)
REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from stages.dataset.schema import CODEC_PRESETS, VideoCodecSpec  # noqa: E402

SIZES = ((240, 320), (480, 640))
JPEG_QUALITY = 90
REPEATS = 3


# -- content ------------------------------------------------------------------------------------


def render_like_frames(n: int, h: int, w: int, seed: int = 0) -> np.ndarray:
    """uint8 (n, h, w, 3): a panning textured room with moving textured shapes and sensor noise."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    s = w / 320.0  # features scale with the image
    # a tileable texture (wood-like grain + tiles) sampled with an offset that pans with the camera
    tex_n = 512
    ty, tx = np.mgrid[0:tex_n, 0:tex_n].astype(np.float32)
    grain = np.sin(tx / 7.0 + 3 * np.sin(ty / 23.0)) * 0.5 + 0.5
    tiles = ((tx // 64 + ty // 64) % 2) * 0.25
    tex = np.stack([0.55 + 0.3 * grain - tiles, 0.4 + 0.25 * grain - tiles, 0.3 + 0.1 * grain], -1)
    tex += rng.normal(0, 0.04, tex.shape).astype(np.float32)  # fine texture detail
    shapes = [(rng.uniform(0, w), rng.uniform(0, h), rng.uniform(-3, 3) * s, rng.uniform(-2, 2) * s,
               rng.uniform(12, 40) * s, rng.uniform(0, 1, 3)) for _ in range(6)]
    horizon = 0.45 * h
    out = np.empty((n, h, w, 3), np.uint8)
    for i in range(n):
        ox, oy = int(2.0 * i * s), int(0.7 * i * s)
        floor = yy > horizon + 6 * np.sin(i / 20.0)
        u = ((xx + ox) * (1 + floor * 0.5)).astype(np.int32) % tex_n
        v = ((yy + oy) * (1 + floor)).astype(np.int32) % tex_n
        img = tex[v, u] * np.where(floor, 0.9, 0.7)[..., None]
        img *= (0.75 + 0.25 * np.cos((xx - w / 2) / w * 2.0))[..., None]  # vignette-like lighting
        for cx, cy, vx, vy, r, col in shapes:
            px, py = (cx + vx * i) % w, (cy + vy * i) % h
            d2 = (xx - px) ** 2 + (yy - py) ** 2
            shadow = ((xx - px - 0.4 * r) ** 2 + (yy - py - 0.6 * r) ** 2) < r * r
            img[shadow] *= 0.6
            inside = d2 < r * r
            stripes = 0.8 + 0.2 * np.sin((xx + yy) / (3 * s) + i / 5.0)
            shade = np.clip(1.0 - np.sqrt(d2) / (1.6 * r), 0.3, 1.0) * stripes
            img[inside] = (col[None, :] * shade[inside][:, None]).astype(np.float32)
        img = img * 255.0 + rng.normal(0, 3.0, img.shape)
        out[i] = np.clip(img, 0, 255).astype(np.uint8)
    return out


# -- quality ------------------------------------------------------------------------------------


def psnr(ref: np.ndarray, test: np.ndarray) -> float:
    """PSNR [dB] of uint8 arrays of the same shape."""
    mse = np.mean((ref.astype(np.float64) - test.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else float(10 * np.log10(255.0**2 / mse))


def ssim(ref: np.ndarray, test: np.ndarray) -> float:
    """Mean SSIM (Wang et al. 2004; Gaussian window sigma 1.5, K1 0.01, K2 0.03) of the luma of
    uint8 RGB frames (N, H, W, 3)."""
    from scipy.ndimage import gaussian_filter

    wts = np.array([0.299, 0.587, 0.114])
    c1, c2 = (0.01 * 255) ** 2, (0.03 * 255) ** 2
    vals = []
    for a, b in zip(ref, test, strict=True):
        x, y = a.astype(np.float64) @ wts, b.astype(np.float64) @ wts
        f = lambda z: gaussian_filter(z, 1.5, truncate=3.5)  # noqa: E731
        mx, my = f(x), f(y)
        sxx, syy, sxy = f(x * x) - mx * mx, f(y * y) - my * my, f(x * y) - mx * my
        m = ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx * mx + my * my + c1) * (sxx + syy + c2))
        vals.append(m.mean())
    return float(np.mean(vals))


# -- encoders -----------------------------------------------------------------------------------


def codec_options(spec: VideoCodecSpec, threads: int = 1) -> dict[str, str]:
    """PyAV stream options for ``spec`` as lerobot 0.6's ``get_codec_options`` builds them."""
    opts = {} if spec.gop is None else {"g": str(spec.gop)}
    opts["crf"] = str(spec.crf)
    if spec.preset is not None:
        opts["preset"] = str(spec.preset)
    if spec.codec == "libsvtav1":
        opts["svtav1-params"] = f"fast-decode=0:lp={threads}"
    else:
        opts["threads"] = str(threads)
    return opts


def encode_video(frames: np.ndarray, spec: VideoCodecSpec, fps: int = 30) -> bytes:
    """An mp4 of ``frames`` (N, H, W, 3) uint8 encoded with ``spec`` (one thread)."""
    import av

    buf = io.BytesIO()
    with av.open(buf, "w", format="mp4") as c:
        st = c.add_stream("libx264" if spec.codec == "h264" else spec.codec, fps, options=codec_options(spec))
        st.width, st.height, st.pix_fmt = frames.shape[2], frames.shape[1], spec.pix_fmt
        for f in frames:
            for p in st.encode(av.VideoFrame.from_ndarray(f, format="rgb24")):
                c.mux(p)
        for p in st.encode():
            c.mux(p)
    return buf.getvalue()


def decode_video(data: bytes) -> np.ndarray:
    import av

    with av.open(io.BytesIO(data)) as c:
        return np.stack([f.to_ndarray(format="rgb24") for f in c.decode(video=0)])


def encode_jpeg_cpu(frames: np.ndarray) -> list[bytes]:
    import torch
    from torchvision.io import encode_jpeg

    torch.set_num_threads(1)
    return [encode_jpeg(torch.from_numpy(f).permute(2, 0, 1).contiguous(), quality=JPEG_QUALITY).numpy().tobytes()
            for f in frames]


def decode_jpegs(blobs: list[bytes]) -> np.ndarray:
    import torch
    from torchvision.io import decode_jpeg

    return np.stack([decode_jpeg(torch.frombuffer(bytearray(b), dtype=torch.uint8)).permute(1, 2, 0).numpy()
                     for b in blobs])


def _worker(name: str, h: int, w: int, n: int, barrier, results) -> None:
    frames = render_like_frames(n, h, w)
    # imports and library set-up before the clock starts
    encode_jpeg_cpu(frames[:1]) if name == "jpeg_cpu" else encode_video(frames[:2], CODEC_PRESETS[name])
    barrier.wait()
    t0 = time.time()
    if name == "jpeg_cpu":
        blobs = encode_jpeg_cpu(frames)
        nbytes = sum(len(b) for b in blobs)
    else:
        blobs = encode_video(frames, CODEC_PRESETS[name])
        nbytes = len(blobs)
    results.put((t0, time.time(), nbytes))


def pool_fps(name: str, h: int, w: int, frames: int, procs: int) -> tuple[float, float]:
    """(frames/s of ``procs`` processes together, KB per frame) for one run."""
    ctx = mp.get_context("spawn")
    barrier, results = ctx.Barrier(procs), ctx.Queue()
    ps = [ctx.Process(target=_worker, args=(name, h, w, frames, barrier, results)) for _ in range(procs)]
    for p in ps:
        p.start()
    got = [results.get(timeout=1800) for _ in ps]
    for p in ps:
        p.join()
    wall = max(g[1] for g in got) - min(g[0] for g in got)
    return procs * frames / wall, got[0][2] / frames / 1024


def quality(name: str, h: int, w: int, frames: int) -> tuple[float, float]:
    raw = render_like_frames(frames, h, w)
    dec = decode_jpegs(encode_jpeg_cpu(raw)) if name == "jpeg_cpu" else decode_video(encode_video(raw, CODEC_PRESETS[name]))
    assert dec.shape == raw.shape, (dec.shape, raw.shape)
    return psnr(raw, dec), ssim(raw, dec)


def jpeg_cuda(h: int, w: int, frames: int, batch: int) -> dict | None:
    """nvJPEG via torchvision on CUDA tensors: frames/s (bytes copied to host), KB/frame, PSNR, SSIM."""
    import torch

    if not torch.cuda.is_available():
        return None
    from torchvision.io import encode_jpeg

    raw = render_like_frames(frames, h, w)
    gpu = torch.from_numpy(raw).cuda().permute(0, 3, 1, 2).contiguous()
    batches = [list(gpu[i:i + batch]) for i in range(0, frames, batch)]
    encode_jpeg(batches[0], quality=JPEG_QUALITY)  # warm-up (nvJPEG handle)
    torch.cuda.synchronize()
    times = []
    for _ in range(REPEATS):
        t = time.perf_counter()
        blobs = [b.cpu().numpy().tobytes() for bt in batches for b in encode_jpeg(bt, quality=JPEG_QUALITY)]
        torch.cuda.synchronize()
        times.append(time.perf_counter() - t)
    dec = decode_jpegs(blobs)
    return {"fps": frames / statistics.median(times), "kb_per_frame": sum(map(len, blobs)) / frames / 1024,
            "psnr": psnr(raw, dec), "ssim": ssim(raw, dec), "procs": 1, "batch": batch}


def run(device: str, procs: int, frames: int, sizes=SIZES, names=None, repeats: int = REPEATS) -> dict:
    names = names or [*CODEC_PRESETS, "jpeg_cpu"]
    out: dict = {"procs": procs, "frames_per_proc": frames, "repeats": repeats, "cpu_count": os.cpu_count(),
                 "jpeg_quality": JPEG_QUALITY, "settings": {k: vars(v) for k, v in CODEC_PRESETS.items()},
                 "results": {}}
    for h, w in sizes:
        res = out["results"][f"{h}x{w}"] = {}
        for name in names:
            runs = [pool_fps(name, h, w, frames, procs) for _ in range(repeats)]
            p, s = quality(name, h, w, min(frames, 60))
            res[name] = {"fps": statistics.median(r[0] for r in runs), "kb_per_frame": runs[0][1],
                         "psnr": p, "ssim": s, "procs": procs}
            print(f"  {h}x{w} {name:16s} {res[name]['fps']:9.1f} frames/s ({procs} procs) "
                  f"{res[name]['kb_per_frame']:6.1f} KB/frame  PSNR {p:5.2f} dB  SSIM {s:.4f}", flush=True)
        if device.startswith("cuda"):
            r = jpeg_cuda(h, w, frames, batch=max(procs, 16))
            if r is None:
                print(f"  {h}x{w} jpeg_cuda        skipped (no CUDA)")
            else:
                res["jpeg_cuda"] = r
                print(f"  {h}x{w} {'jpeg_cuda':16s} {r['fps']:9.1f} frames/s (1 GPU)   "
                      f"{r['kb_per_frame']:6.1f} KB/frame  PSNR {r['psnr']:5.2f} dB  SSIM {r['ssim']:.4f}")
    dest = REPO / "bench_results" / "encode.json"
    dest.parent.mkdir(exist_ok=True)
    dest.write_text(json.dumps(out, indent=2))
    return out


def test_render_like_content_moves_and_the_metrics_rank_distortion():
    f = render_like_frames(3, 120, 160)
    assert f.shape == (3, 120, 160, 3) and f.std() > 20
    assert np.abs(f[2].astype(int) - f[0]).mean() > 8  # more than the noise (sigma 3): the content moves
    noisy = np.clip(f + np.random.default_rng(1).normal(0, 8, f.shape), 0, 255).astype(np.uint8)
    assert psnr(f, f) == float("inf") and abs(ssim(f, f) - 1.0) < 1e-9
    assert 25 < psnr(f, noisy) < 35 and ssim(f, noisy) < 0.99


@pytest.mark.benchmark
def test_bench_encode():
    procs = min(2, os.cpu_count() or 1)
    out = run("cuda", procs, frames=60, sizes=((240, 320),), repeats=1)
    r = out["results"]["240x320"]
    assert all(v["fps"] > 0 for v in r.values())
    assert r["x264_ultrafast"]["fps"] > r["av1_p12_lerobot"]["fps"] * 0.5
    assert all(v["psnr"] > 28 and v["ssim"] > 0.8 for v in r.values()), r


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--device", default="cpu", help="cpu or cuda (cuda adds nvJPEG)")
    ap.add_argument("--procs", type=int, default=os.cpu_count())
    ap.add_argument("--frames", type=int, default=120, help="frames per process")
    ap.add_argument("--sizes", nargs="*", default=[f"{h}x{w}" for h, w in SIZES], help="HxW, e.g. 240x320")
    ap.add_argument("--encoders", nargs="*", default=None, help=f"of {[*CODEC_PRESETS, 'jpeg_cpu']}")
    ap.add_argument("--repeats", type=int, default=REPEATS)
    a = ap.parse_args()
    sizes = [tuple(int(x) for x in s.split("x")) for s in a.sizes]
    run(a.device, a.procs, a.frames, sizes=sizes, names=a.encoders, repeats=a.repeats)
