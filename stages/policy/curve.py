"""Training curve PNG from ``curve.csv`` (PIL, no plotting library): one panel per column against
the step; the columns are the loss, the policy's sub-losses present (ACT: l1_loss, kld_loss), the
gradient norm and the learning rate. Loss panels use a log scale when all values are positive."""

from __future__ import annotations

import csv
import math
from pathlib import Path

PANELS = ("loss", "l1_loss", "kld_loss", "grad_norm", "lr")
LOG_SCALE = ("loss", "l1_loss", "kld_loss", "grad_norm")


def plot_curve(csv_path: Path, png_path: Path, *, panels: tuple[str, ...] = PANELS) -> Path:
    """Write the curve of ``csv_path`` (columns ``step`` + ``panels`` present) to ``png_path``."""
    from PIL import Image, ImageDraw

    rows = list(csv.DictReader(Path(csv_path).open())) if Path(csv_path).is_file() else []
    cols = [c for c in panels if rows and rows[0].get(c) not in (None, "")] or ["loss"]
    w, h, pad = 900, 200, 56
    img = Image.new("RGB", (w, h * len(cols)), "white")
    draw = ImageDraw.Draw(img)
    for k, col in enumerate(cols):
        pts_raw = [(int(r["step"]), float(r[col])) for r in rows if r.get(col) not in (None, "", "nan")]
        top = k * h
        draw.rectangle([pad, top + 10, w - 10, top + h - 30], outline="black")
        if len(pts_raw) < 2:
            draw.text((pad + 4, top + 12), f"{col}: {len(pts_raw)} point(s)", fill="black")
            continue
        log = col in LOG_SCALE and all(y > 0 for _, y in pts_raw)
        xs = [x for x, _ in pts_raw]
        ys = [math.log10(y) if log else y for _, y in pts_raw]
        lo, hi = min(ys), max(ys)
        span = f"[{10 ** lo:.4g}, {10 ** hi:.4g}], log scale" if log else f"[{lo:.4g}, {hi:.4g}]"
        if hi <= lo:
            span, hi = f"constant {pts_raw[0][1]:.4g}", lo + 1.0
        x0, x1 = min(xs), max(xs) if max(xs) > min(xs) else min(xs) + 1
        pts = [(pad + (x - x0) / (x1 - x0) * (w - 10 - pad), top + h - 30 - (y - lo) / (hi - lo) * (h - 40))
               for x, y in zip(xs, ys, strict=True)]
        draw.line(pts, fill=(30, 90, 200), width=2)
        draw.text((pad + 4, top + 12), f"{col}  {span}", fill="black")
        draw.text((pad, top + h - 26), f"step {x0}", fill="black")
        draw.text((w - 140, top + h - 26), f"step {x1}", fill="black")
    png_path = Path(png_path)
    img.save(png_path)
    return png_path
