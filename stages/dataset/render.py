"""Contact sheet of a dataset: evenly spaced frames of a few episodes, RGB and depth of every camera.

Command: ``agentworld render-dataset DATASET [--out sheet.png] [--episodes 0,3] [--frames 6]``.
Frames are read back through ``LeRobotDataset`` (what a trainer sees); a multistage dataset's
frames name their stage (``subtask_index`` + 1) in the episode's header. Depth is shown with a
colour map over the 2nd-98th percentile of the valid (non-zero) depths of each image; 0 is black.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

logger = logging.getLogger(__name__)

THUMB_W = 160
LABEL_W = 150
HEADER_H = 18


def _to_uint8_rgb(t) -> np.ndarray:
    """(3, H, W) float in [0, 1] -> (H, W, 3) uint8."""
    return (t.permute(1, 2, 0).numpy() * 255.0).clip(0, 255).round().astype(np.uint8)


def colorize_depth(depth_mm: np.ndarray) -> np.ndarray:
    """(H, W) depth [mm] -> (H, W, 3) uint8 (turbo colour map over the valid range, 0 black)."""
    import cv2

    valid = depth_mm > 0
    out = np.zeros((*depth_mm.shape, 3), np.uint8)
    if not valid.any():
        return out
    lo, hi = np.percentile(depth_mm[valid], [2, 98])
    norm = ((depth_mm - lo) / max(hi - lo, 1.0)).clip(0, 1)
    colored = cv2.applyColorMap((norm * 255).astype(np.uint8), cv2.COLORMAP_TURBO)[..., ::-1]
    out[valid] = colored[valid]
    return out


def _thumb(img: np.ndarray):
    from PIL import Image

    im = Image.fromarray(img)
    h = max(1, round(im.height * THUMB_W / im.width))
    return im.resize((THUMB_W, h), Image.Resampling.BILINEAR)


def render_contact_sheet(root: Path, out: Path, *, episodes: list[int] | None = None, frames: int = 6,
                         max_episodes: int = 6) -> Path:  # fmt: skip
    """Write a PNG contact sheet of ``root`` to ``out``; returns ``out``.

    episodes: episode indices (default: up to ``max_episodes`` spread over the dataset);
    frames: frames per episode, evenly spaced from first to last."""
    from PIL import Image, ImageDraw

    from .depth import decode_depth, depth_keys_of
    from .merge import load_dataset
    from .schema import SUBTASK_KEY

    ds = load_dataset(Path(root))
    n_eps = ds.meta.total_episodes
    if episodes is None:
        spread = np.linspace(0, n_eps - 1, min(max_episodes, n_eps)).round().astype(int)
        episodes = sorted(set(spread.tolist()))
    bad = [e for e in episodes if not 0 <= e < n_eps]
    if bad:
        raise ValueError(f"{root}: episodes {bad} out of range (dataset has {n_eps})")
    depth_keys = depth_keys_of(ds.meta.features)
    cams = [*ds.meta.camera_keys, *depth_keys]
    rows: list[tuple[str, list]] = []  # (label, thumbnails)
    headers: list[tuple[int, str]] = []  # (row index, text)
    for ep in episodes:
        meta = ds.meta.episodes[ep]
        start, stop = int(meta["dataset_from_index"]), int(meta["dataset_to_index"])
        picks = np.linspace(start, stop - 1, min(frames, stop - start)).round().astype(int)
        items = [ds[int(i)] for i in picks]
        # a multistage episode's frames show their stage (1-based): "139 (s2)"
        shown = ", ".join(str(int(it["frame_index"])) + (f" (s{int(it[SUBTASK_KEY]) + 1})" if SUBTASK_KEY in it else "")
                          for it in items)
        text = f"episode {ep}: {items[0]['task']}  ({stop - start} frames; frames {shown})"
        headers.append((len(rows), text))
        for key in cams:
            if key in depth_keys:
                thumbs = [_thumb(colorize_depth(decode_depth(it[key]))) for it in items]
                label = key.removeprefix("depth.") + " depth"
            else:
                thumbs = [_thumb(_to_uint8_rgb(it[key])) for it in items]
                label = key.removeprefix("observation.images.")
            rows.append((label, thumbs))
    row_h = [max(t.height for t in thumbs) for _, thumbs in rows]
    header_rows = {r for r, _ in headers}
    width = LABEL_W + frames * (THUMB_W + 2)
    height = sum(row_h) + 2 * len(rows) + HEADER_H * len(headers)
    sheet = Image.new("RGB", (width, height), (30, 30, 30))
    draw = ImageDraw.Draw(sheet)
    y = 0
    header_text = dict(headers)
    for r, (label, thumbs) in enumerate(rows):
        if r in header_rows:
            draw.text((4, y + 3), header_text[r], fill=(255, 220, 120))
            y += HEADER_H
        draw.text((4, y + row_h[r] // 2 - 6), label, fill=(230, 230, 230))
        for j, t in enumerate(thumbs):
            sheet.paste(t, (LABEL_W + j * (THUMB_W + 2), y))
        y += row_h[r] + 2
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(out)
    logger.info("%s: contact sheet of %d episodes written to %s", root, len(episodes), out)
    return out


def cli(argv: list[str]) -> int:
    """``agentworld render-dataset``: parse ``argv``, write the sheet, print its path; exit status."""
    p = argparse.ArgumentParser(prog="agentworld render-dataset", description=__doc__.splitlines()[0])
    p.add_argument("dataset", type=Path, help="a LeRobot dataset folder (a shard or a merged dataset)")
    p.add_argument("--out", type=Path, default=None, help="PNG path (default: <dataset>.contact_sheet.png)")
    p.add_argument("--episodes", default=None, help="comma-separated episode indices (default: spread)")
    p.add_argument("--frames", type=int, default=6, help="frames per episode (default 6)")
    a = p.parse_args(argv)
    episodes = [int(x) for x in a.episodes.split(",")] if a.episodes else None
    try:
        out_png = a.out or a.dataset.with_name(a.dataset.name + ".contact_sheet.png")
        out = render_contact_sheet(a.dataset, out_png, episodes=episodes, frames=a.frames)
    except (FileNotFoundError, ValueError) as e:
        print(f"error: {e}")
        return 2
    print(out)
    return 0
