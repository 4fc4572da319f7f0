"""Open composed scene USDs in Blender (the ``bpy`` module) and render one view of each.

Blender is not a project dependency (``bpy`` is a 374 MB wheel for Python 3.11 only), so this is a
standalone check run by hand, not by CI. Set-up once::

    python3.11 -m venv /tmp/bpyenv && /tmp/bpyenv/bin/pip install bpy==5.0.1

Run::

    /tmp/bpyenv/bin/python tests/benchmarks/blender_open.py out/scenes/scenes/*/scene.usda \
        --render 4 --out bench_results/blender

For every scene: Blender's USD importer (``bpy.ops.wm.usd_import``, references and payloads
resolved) must finish, and the counts of imported objects, meshes, lights, materials and textures
are recorded; the first ``--render`` scenes are also rendered with Cycles (CPU, 320x240, 16 samples)
from a camera in a corner of the scene's bounding box looking at its centre, lit only by the
scene's own UsdLux lights as authored (``light_intensity_scale`` 1, env ``BLENDER_LIGHT_SCALE``;
the lights carry the scene exposure, see ``stages.scene.lighting``, and ``blender_exposure.py``
checks the exposure). Writes ``<out>/blender.json`` and ``<out>/<scene>.png``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

LIGHT_SCALE = float(os.environ.get("BLENDER_LIGHT_SCALE", "1.0"))


def _bounds():
    """World-space bounding box (min xyz, max xyz) of every mesh object [m]."""
    import bpy
    from mathutils import Vector

    lo = Vector((math.inf,) * 3)
    hi = Vector((-math.inf,) * 3)
    for o in bpy.data.objects:
        if o.type != "MESH":
            continue
        for c in o.bound_box:
            w = o.matrix_world @ Vector(c)
            lo = Vector(map(min, lo, w))
            hi = Vector(map(max, hi, w))
    return lo, hi


def _render(png: Path) -> float:
    """Cycles render of the imported scene to ``png``; returns seconds."""
    import bpy
    from mathutils import Vector

    lo, hi = _bounds()
    centre = (lo + hi) / 2
    centre.z = min(centre.z, 0.8)
    eye = Vector((lo.x + 0.15 * (hi.x - lo.x), lo.y + 0.15 * (hi.y - lo.y), min(hi.z - 0.2, 2.2)))
    cam_data = bpy.data.cameras.new("CheckCamera")
    cam_data.lens = 14.0
    cam = bpy.data.objects.new("CheckCamera", cam_data)
    bpy.context.scene.collection.objects.link(cam)
    cam.location = eye
    cam.rotation_euler = (centre - eye).to_track_quat("-Z", "Y").to_euler()
    scene = bpy.context.scene
    scene.camera = cam
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 16
    scene.render.resolution_x, scene.render.resolution_y = 320, 240
    scene.render.filepath = str(png)
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return time.perf_counter() - t0


def check(usd: Path, png: Path | None) -> dict:
    """Import ``usd`` into an empty Blender scene; counts, import time and optional render."""
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.context.scene.world = bpy.data.worlds.new("World")  # the importer makes the dome light its background
    t0 = time.perf_counter()
    result = bpy.ops.wm.usd_import(filepath=str(usd), light_intensity_scale=LIGHT_SCALE)
    seconds = time.perf_counter() - t0
    objs = list(bpy.data.objects)
    rec = {
        "scene": str(usd),
        "result": sorted(result),
        "import_s": round(seconds, 3),
        "objects": len(objs),
        "meshes": sum(o.type == "MESH" for o in objs),
        "lights": sum(o.type == "LIGHT" for o in objs),
        "materials": len(bpy.data.materials),
        "images": len(bpy.data.images),
        "vertices": sum(len(o.data.vertices) for o in objs if o.type == "MESH"),
    }
    if png is not None:
        rec["render_s"] = round(_render(png), 2)
        rec["png"] = str(png)
    return rec


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scenes", nargs="+", type=Path)
    p.add_argument("--render", type=int, default=0, help="render the first N scenes")
    p.add_argument("--out", type=Path, default=Path("bench_results/blender"))
    a = p.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    records = []
    for i, usd in enumerate(a.scenes):
        png = a.out / f"{usd.parent.name}.png" if i < a.render else None
        rec = check(usd.resolve(), png.resolve() if png else None)
        print(json.dumps(rec), flush=True)
        records.append(rec)
    ok = [r for r in records if r["result"] == ["FINISHED"] and r["meshes"] > 0]
    import bpy

    summary = {"blender": bpy.app.version_string, "scenes": len(records), "opened": len(ok),
               "records": records}
    (a.out / "blender.json").write_text(json.dumps(summary, indent=2))
    print(f"opened {len(ok)}/{len(records)} scenes in Blender {summary['blender']}")
    return 0 if len(ok) == len(records) else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
