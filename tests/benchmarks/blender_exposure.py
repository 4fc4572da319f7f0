"""Render a scene USD in Blender (Cycles, CPU) lit only by its own UsdLux lights, as Blender's USD
importer reads them (``light_intensity_scale`` 1, no tweaks), and print its exposure histogram.

Runs in a Python that has ``bpy`` (Blender is not a project dependency: ``bpy`` is a ~370 MB
wheel for Python 3.11 only); ``bench_blender_lights.py`` launches it as a subprocess. Set-up once::

    python3.11 -m venv /tmp/bpyenv && /tmp/bpyenv/bin/pip install bpy==5.0.1

Run::

    /tmp/bpyenv/bin/python tests/benchmarks/blender_exposure.py SCENE.usda --out DIR [--samples 16]

The camera stands 15% inside a corner of the meshes' bounding box, 1.6 m above the floor (under
the ceiling), looking at the box's centre 0.8 m above the floor, 14 mm lens. The render is written
linear (OpenEXR, ``DIR/<name>.exr``) and as ``DIR/<name>.png`` (Standard view transform, what
is clipped there is white). Printed as one JSON line: Blender's version, each imported light's
type, power [W] (``energy``), exposure [stops], normalize flag and its power as Blender emits it,
``energy * 2^exposure``, times the sphere's area ``4 pi r^2`` for an unnormalized point or
spot light (measured: Cycles' unnormalized point light emits that much less or more) [W], the
world background's strength (the imported dome light); and the image's
luminance statistics: ``clipped`` (fraction of pixels with a linear channel >= 1), ``median``,
``p05``, ``p95`` (linear Rec. 709 luminance).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path


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


def _world_strength() -> float | None:
    """Strength of the world's background shader (the imported dome light), or None."""
    import bpy

    w = bpy.context.scene.world
    nodes = w.node_tree.nodes if w is not None and w.node_tree is not None else []
    bg = [n for n in nodes if n.bl_idname == "ShaderNodeBackground"]
    return float(bg[0].inputs["Strength"].default_value) if bg else None


def light_records() -> list[dict]:
    """Every imported light: name, type, energy [W], exposure [stops], normalize, emitted [W]."""
    import bpy

    out = []
    for o in bpy.data.objects:
        if o.type != "LIGHT":
            continue
        lt = o.data
        scale = lt.energy * 2.0 ** lt.exposure
        if lt.type in ("POINT", "SPOT") and not lt.normalize:
            scale *= 4.0 * math.pi * lt.shadow_soft_size**2  # measured: Cycles emits energy x sphere area
        out.append({"name": o.name, "type": lt.type, "energy": round(lt.energy, 4),
                    "exposure": round(lt.exposure, 4), "normalize": bool(lt.normalize),
                    "emitted_w": round(scale, 4)})
    return out


def render(usd: Path, out: Path, samples: int, width: int, height: int, light_scale: float = 1.0) -> dict:
    """Import ``usd`` into an empty scene, render it, return the lights and image statistics."""
    import bpy
    import numpy as np
    from mathutils import Vector

    bpy.ops.wm.read_factory_settings(use_empty=True)
    # a world, as Blender's default scene has: the importer turns the dome light into its background
    # (and skips the dome without one)
    bpy.context.scene.world = bpy.data.worlds.new("World")
    bpy.ops.wm.usd_import(filepath=str(usd), light_intensity_scale=light_scale)
    lo, hi = _bounds()
    centre = (lo + hi) / 2
    centre.z = lo.z + 0.8
    eye = Vector((lo.x + 0.15 * (hi.x - lo.x), lo.y + 0.15 * (hi.y - lo.y), lo.z + 1.6))
    cam_data = bpy.data.cameras.new("CheckCamera")
    cam_data.lens = 14.0
    cam = bpy.data.objects.new("CheckCamera", cam_data)
    scene = bpy.context.scene
    scene.collection.objects.link(cam)
    cam.location = eye
    cam.rotation_euler = (centre - eye).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = True  # OpenImageDenoise: 16 samples leave fireflies that read as clipped
    scene.cycles.denoiser = "OPENIMAGEDENOISE"
    scene.render.threads_mode = "FIXED"
    scene.render.threads = 2
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = "Standard"
    out.mkdir(parents=True, exist_ok=True)
    stem = usd.parent.name if usd.stem == "scene" else usd.stem
    exr = out / f"{stem}.exr"
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(exr)
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    seconds = time.perf_counter() - t0
    img = bpy.data.images.load(str(exr))
    rgb = np.asarray(img.pixels[:], dtype=np.float64).reshape(-1, 4)[:, :3]
    scene.render.image_settings.file_format = "PNG"
    img.save_render(str(out / f"{stem}.png"), scene=scene)  # Standard view transform, 8-bit sRGB
    lum = rgb @ np.array([0.2126, 0.7152, 0.0722])
    return {
        "scene": str(usd),
        "blender": bpy.app.version_string,
        "lights": light_records(),
        "world_strength": _world_strength(),
        "light_scale": light_scale,
        "render_s": round(seconds, 2),
        "clipped": float((rgb.max(axis=1) >= 1.0).mean()),
        "median": float(np.median(lum)),
        "p05": float(np.percentile(lum, 5)),
        "p95": float(np.percentile(lum, 95)),
        "exr": str(exr),
    }


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scene", type=Path)
    p.add_argument("--out", type=Path, default=Path("bench_results/blender"))
    p.add_argument("--samples", type=int, default=16)
    p.add_argument("--light-scale", type=float, default=1.0,
                   help="Blender's light_intensity_scale (1: as authored)")
    p.add_argument("--size", type=int, nargs=2, default=(160, 120), metavar=("W", "H"))
    a = p.parse_args(argv)
    rec = render(a.scene.resolve(), a.out.resolve(), a.samples, *a.size, a.light_scale)
    print("BLENDER_EXPOSURE " + json.dumps(rec), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
