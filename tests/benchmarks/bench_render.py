"""Benchmark: the engine's camera render over world counts and renderer settings.

For each world count N a :class:`~stages.engine.BatchEngine` of N worlds of one default-catalog
kitchen (3 cameras, RGB + depth, the given size) runs its scripted experts for a few frames so
that robots and objects are where recording finds them; then every renderer setting in
``--variants`` renders all cameras of all worlds (Newton ``SensorCamera.update``, the same
outputs the engine records: colour, forward depth, shape index) and the benchmark prints the
median device time per frame [s] and the rate as recorded timesteps/s (N / time), with each
setting's first-call time (kernel compilation) apart.

Settings (comma-separated ``--variants``):

- ``pixel``: Newton's default traversal order (the same pixel of every world in neighbouring
  threads), what the engine used up to now;
- ``view``: whole views in order (neighbouring threads: neighbouring pixels of one view);
- ``tiled16x8``, ``tiled8x8``, ``tiled32x4``: tiles of neighbouring pixels of one view;
- ``noshadow``, ``notex``, ``noseg``: ``tiled16x8`` without shadow rays, without textures, without
  the shape index output.

Images do not depend on the traversal order (checked: every order's colour and depth equal the
``pixel`` ones bit for bit). Writes ``bench_results/render.json``. Run on the GPU machine::

    python tests/benchmarks/bench_render.py --device cuda --worlds 64 256 1024 --catalog DIR
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

VARIANTS = ("pixel", "view", "tiled16x8", "tiled8x8", "tiled32x4", "noshadow", "notex", "noseg")


def _config(base, name: str):
    from newton.sensors import SensorCamera

    RenderOrder = SensorCamera.RenderOrder

    tiled = dict(render_order=RenderOrder.TILED, tile_width=16, tile_height=8)
    table = {
        "pixel": dict(render_order=RenderOrder.PIXEL_PRIORITY),
        "view": dict(render_order=RenderOrder.VIEW_PRIORITY),
        "tiled16x8": tiled,
        "tiled8x8": dict(tiled, tile_width=8, tile_height=8),
        "tiled32x4": dict(tiled, tile_width=32, tile_height=4),
        "noshadow": dict(tiled, enable_shadows=False),
        "notex": dict(tiled, enable_textures=False),
        "noseg": tiled,
    }
    if name not in table:
        raise ValueError(f"unknown render variant {name!r} (known: {', '.join(VARIANTS)})")
    return dataclasses.replace(base, **table[name])


def bench_render(eng, names, reps: int) -> dict:
    """Median seconds per frame (all worlds, all cameras, synchronised) per setting."""
    import warp as wp

    bank = eng.banks[0]
    rig, sim = bank.rig, bank.sim
    dev = sim.model.device
    state = sim.state_0
    base = rig._sensor.default_render_config
    poses = {c.name: rig._transforms(c)[0] for c in rig.cameras}
    out, ref = {}, None
    for name in names:
        cfg = _config(base, name)

        def frame(cfg=cfg, seg=(name != "noseg")):
            sim.model.bvh_refit_shapes(state)
            for c in rig.cameras:
                img = rig._images[c.name]
                rig._sensor.update(state, poses[c.name], rig._rays[c.name], color_image=img["color"],
                                   forward_depth_image=img["depth"],
                                   shape_index_image=img["shape"] if seg else None,
                                   world_indices=rig._world_ids, render_config=cfg)

        t = time.perf_counter()
        frame()
        wp.synchronize_device(dev)
        first = time.perf_counter() - t
        times = []
        for _ in range(reps):
            t = time.perf_counter()
            frame()
            wp.synchronize_device(dev)
            times.append(time.perf_counter() - t)
        med = statistics.median(times)
        imgs = {c.name: (rig._images[c.name]["color"].numpy().copy(), rig._images[c.name]["depth"].numpy().copy())
                for c in rig.cameras}
        same = None
        if name in ("pixel", "view") or name.startswith("tiled"):
            if ref is None:
                ref = imgs
            same = all(np.array_equal(imgs[k][0], ref[k][0]) and np.array_equal(imgs[k][1], ref[k][1]) for k in ref)
        out[name] = {"seconds_per_frame": round(med, 5), "timesteps_per_second": round(sim.world_count / med, 1),
                     "first_call_seconds": round(first, 2), "same_images_as_first_order": same}
        print(f"  {name:10s} {med * 1e3:8.2f} ms/frame {sim.world_count / med:9.1f} ts/s "
              f"(first call {first:.1f} s){'' if same is None else ' same images' if same else ' IMAGES DIFFER'}",
              flush=True)
    return out


def compact_equals_render(eng) -> bool:
    """The engine's recording render (``render_compact_async``: on CUDA its own stream and a copy of
    the body poses, or the simulation's stream: both are checked) gives the images of
    ``CameraRig.render``, RGB and depth in millimetres, with physics steps enqueued right after the
    launch (on the simulation's stream they run after the render)."""
    from stages.dataset.schema import depth_m_to_mm
    from stages.simulate import compact

    bank = eng.banks[0]
    rig, sim = bank.rig, bank.sim
    same = True
    default = compact.OWN_STREAM
    try:
        for own in (True, False):
            compact.OWN_STREAM = own
            ref = {k: (f.rgb.copy(), depth_m_to_mm(f.depth)) for k, f in rig.render().items()}
            pending = rig.render_compact_async()
            sim.step(5)  # must not change what the launched render sees
            got = pending.wait()
            same &= all(np.array_equal(got[k][0], ref[k][0]) and np.array_equal(got[k][1], ref[k][1])
                        for k in ref)
    finally:
        compact.OWN_STREAM = default
    return bool(same)


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--device", default=os.environ.get("AGENTWORLD_BENCH_DEVICE", "cpu"))
    p.add_argument("--worlds", type=int, nargs="+", default=[2])
    p.add_argument("--width", type=int, default=320)
    p.add_argument("--height", type=int, default=240)
    p.add_argument("--variants", default="pixel,tiled16x8")
    p.add_argument("--reps", type=int, default=5)
    p.add_argument("--warm-frames", type=int, default=10, help="recorded frames run before rendering")
    p.add_argument("--catalog", type=Path, default=None)
    p.add_argument("--panda-root", type=Path, default=None)
    p.add_argument("--work", type=Path, default=REPO / "bench_results" / "render_work")
    p.add_argument("--out", type=Path, default=REPO / "bench_results" / "render.json")
    args = p.parse_args(argv)
    import usd_schemas  # noqa: F401
    from bench_engine import _catalog  # the engine benchmark's kitchen catalog

    from stages.demos.kitchen import AssetLibrary, write_kitchen
    from stages.demos.tasks import BASIC_TASKS
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import RoundRobin

    names = [v.strip() for v in args.variants.split(",") if v.strip()]
    args.work.mkdir(parents=True, exist_ok=True)
    cat = (args.catalog or _catalog(args.work)).resolve()
    lib = AssetLibrary.from_folder(cat / "assets", cat / "catalog" / "default" / "generated.json")
    room = write_kitchen(args.work / "kitchen", lib, scene_id="kitchen_bench", rng=np.random.default_rng(5))
    results = []
    for n in args.worlds:
        print(f"worlds {n}:", flush=True)
        try:
            eng = BatchEngine(room, panda_root=args.panda_root.resolve() if args.panda_root else None,
                              work_dir=args.work.resolve(),
                              config=EngineConfig(worlds=n, device=args.device, width=args.width,
                                                  height=args.height))
            eng.run(RoundRobin(room, sorted(BASIC_TASKS), 0), begin=lambda w, inst: (lambda frame: None),
                    end=lambda w, inst, res: None, max_steps=args.warm_frames * eng.sync_period)
            results.append({"worlds": n, "variants": bench_render(eng, names, args.reps),
                            "compact_equals_render": compact_equals_render(eng)})
            print(f"  compact render (own stream) equals the main-stream render: "
                  f"{results[-1]['compact_equals_render']}", flush=True)
            del eng
        except Exception as e:  # noqa: BLE001 (out of memory at large N: report and go on)
            print(f"worlds {n}: failed: {e!r}", flush=True)
            results.append({"worlds": n, "error": repr(e)})
    doc = {"device": args.device, "size": [args.height, args.width], "cameras": 3, "results": results}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(doc, indent=1))
    return doc


@pytest.mark.benchmark
def test_bench_render():
    doc = main(["--worlds", "2", "--width", "64", "--height", "48", "--reps", "1", "--warm-frames", "2",
                "--variants", "pixel,tiled16x8"])
    for r in doc["results"]:
        assert r["variants"]["tiled16x8"]["same_images_as_first_order"] is True
        assert r["compact_equals_render"] is True


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    main()
