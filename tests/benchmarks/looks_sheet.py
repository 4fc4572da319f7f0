"""A contact sheet of kitchen looks: a few demonstration kitchens (different world seeds) rendered
from the demos' third-person camera, side by side in one PNG.

Run by hand (not by CI)::

    .venv/bin/python tests/benchmarks/looks_sheet.py --out /work/notes/looks_sheet.png \
        --seeds 5 6 7 8 --width 320 --height 240 [--catalog out/main] [--device cpu]

``--catalog``: a work directory holding ``assets/<id>/<id>.usda`` and
``catalog/default/generated.json`` (an ingest run of the default catalog); without it the kitchen
categories are generated and ingested into a temporary folder first (a few seconds). Each kitchen is
written with ``write_kitchen(..., rng=default_rng(seed))`` and loaded exactly as the demos load it
(:class:`stages.demos.session.DemoWorld`: the robot at the spawn pose, the scene's UsdLux lights
mapped onto Newton's SensorCamera); under each image: the seed, the ceiling light and the appliance
finish (the mean over the pixels that see the room). Writes the PNG and ``<out>.txt`` with :func:`stages.demos.looks.describe` of every look and
the timings.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
KITCHEN = ("kitchen_counter", "microwave", "fridge", "oven", "door", "dining_table", "mug", "bowl", "can")
PACKAGES = ("kitchen_counter_00", "microwave_00", "fridge_00", "oven_00", "door_00", "dining_table_00",
            "mug_04", "bowl_00", "can_00")


def _ingest(out: Path) -> Path:
    from pipeline import build_job, run_job

    job = {"job": {"name": "looks_catalog", "seed": 0, "out": str(out), "executor": "inline", "workers": 1},
           "step": [{"name": "catalog", "kind": "default_catalog",
                     "config": {"variants": 5, "categories": list(KITCHEN)}},
                    {"name": "assets", "kind": "ingest", "config": {"catalog_step": "catalog", "only": list(PACKAGES)}}]}
    summary = run_job(build_job(job, source="<looks_sheet>", base_dir=out.parent), progress=False)
    if any(s.failed for s in summary.steps):
        raise SystemExit(f"catalog/ingest failed: {summary}")
    return out


def _caption(img: np.ndarray, lines: list[str]) -> np.ndarray:
    from PIL import Image, ImageDraw

    h = 14 * len(lines) + 6
    pil = Image.new("RGB", (img.shape[1], img.shape[0] + h), (255, 255, 255))
    pil.paste(Image.fromarray(img), (0, 0))
    d = ImageDraw.Draw(pil)
    for i, s in enumerate(lines):
        d.text((4, img.shape[0] + 3 + 14 * i), s, fill=(0, 0, 0))
    return np.asarray(pil)


def main(argv: list[str] | None = None) -> None:
    sys.path.insert(0, str(ROOT))
    from PIL import Image

    from stages.demos.kitchen import AssetLibrary, write_kitchen
    from stages.demos.looks import describe
    from stages.demos.session import DemoSettings, DemoWorld

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--seeds", type=int, nargs="+", default=[5, 6, 7, 8])
    ap.add_argument("--width", type=int, default=320)
    ap.add_argument("--height", type=int, default=240)
    ap.add_argument("--catalog", type=Path, default=None)
    ap.add_argument("--device", default="cpu")
    a = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="looks_sheet_"))
    cat = a.catalog or _ingest(tmp / "catalog" / "out")
    lib = AssetLibrary.from_folder(cat / "assets", cat / "catalog" / "default" / "generated.json")
    settings = DemoSettings(width=a.width, height=a.height, device=a.device)
    tiles, notes = [], []
    for seed in a.seeds:
        t0 = time.perf_counter()
        room = write_kitchen(tmp / f"w{seed}", lib, scene_id=f"looks_{seed}", rng=np.random.default_rng(seed))
        world = DemoWorld(room, panda_root=None, work_dir=tmp / f"w{seed}", settings=settings)
        t1 = time.perf_counter()
        frame = world.rig.render()["third_person"]
        rgb, hit = frame.rgb[0], frame.depth[0] > 0
        t2 = time.perf_counter()
        lit = rgb[hit]  # pixels that see the room (the open top shows no sky: black)
        sat, dark = float((lit.max(-1) >= 254).mean()), float((lit.max(-1) <= 10).mean())
        lt = room.look.lights
        fridge = room.look.override("fridge", "body")
        tiles.append(_caption(rgb, [f"seed {seed}: ceiling {lt.ceiling_lux:.0f} lux {lt.ceiling_kelvin:.0f} K",
                                    f"sun {lt.sun_lux:.0f} lux, sky {lt.dome_lux:.0f} lux, mean {lit.mean():.0f}/255",
                                    f"fridge {fridge.rule if fridge else 'as packaged'}"]))
        notes.append(f"== seed {seed}: build {t1 - t0:.1f} s, render {t2 - t1:.2f} s, room pixels: mean rgb "
                     f"{lit.mean(0).round(1).tolist()}, saturated {100 * sat:.2f}%, black {100 * dark:.2f}%\n"
                     f"{describe(room.look)}")
        print(notes[-1], flush=True)
    gap = np.full((tiles[0].shape[0], 6, 3), 255, np.uint8)
    sheet = np.concatenate([x for t in tiles for x in (t, gap)][:-1], axis=1)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(sheet).save(a.out)
    a.out.with_suffix(".txt").write_text("\n".join(notes) + "\n")
    print(f"wrote {a.out} ({sheet.shape[1]}x{sheet.shape[0]})")


if __name__ == "__main__":
    main()
