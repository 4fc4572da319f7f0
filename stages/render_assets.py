"""Contact sheets: one PNG per category, a grid of its variants rendered with Newton's SensorCamera
(ray traced, runs on the CPU), so a person can look at the assets.

Row 1 shows each variant at its zero joint configuration; articulated categories get a second row with
every joint at its upper limit (labelled "open": doors open, drawers out, buttons pressed).

    agentworld render-assets --out DIR [--variants 5] [--seed 0] [--categories a,b] [--tile 256]
    agentworld render-assets --out DIR --catalog CATALOG_DIR      # render any catalog folder's sources
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from asset_catalog.asset_model import AssetModel, JointType

log = logging.getLogger(__name__)

BACKGROUND = (236, 236, 232)
VIEW_DIR = np.array([1.0, 0.75, 0.6])   # camera direction from the asset centre (front-right-above)
FOV = 0.55                              # vertical field of view [rad]


def link_transforms(model: AssetModel, q: dict[str, float] | None = None) -> dict[str, np.ndarray]:
    """4x4 root-frame transform of every link with joint values ``q`` ({joint name: [rad] or [m]},
    missing joints at 0)."""
    from scipy.spatial.transform import Rotation

    q = q or {}
    out = {model.links[0].name: model.links[0].pose.matrix()}
    pending = list(model.joints)
    while pending:
        rest = []
        for j in pending:
            if j.parent not in out:
                rest.append(j)
                continue
            t = j.frame.matrix()
            m = np.eye(4)
            val = float(q.get(j.name, 0.0))
            if j.type == JointType.REVOLUTE:
                m[:3, :3] = Rotation.from_rotvec(np.asarray(j.axis) * val).as_matrix()
            elif j.type == JointType.PRISMATIC:
                m[:3, 3] = np.asarray(j.axis) * val
            out[j.child] = out[j.parent] @ t @ m
        if len(rest) == len(pending):
            raise ValueError(f"{model.name}: joints {[j.name for j in rest]} do not connect to the root link")
        pending = rest
    return out


def upper_limits(model: AssetModel) -> dict[str, float]:
    return {j.name: float(j.upper) for j in model.joints if j.upper is not None}


def render_views(views: Sequence[tuple[AssetModel, dict[str, float]]], *, tile: int = 256,
                 device: str = "cpu") -> np.ndarray:
    """Render each (model, joint values) in its own Newton world; returns (V, tile, tile, 3) uint8 sRGB."""
    import warp as wp

    import newton
    from newton.sensors import SensorCamera

    builder = newton.ModelBuilder()
    cfg = newton.ModelBuilder.ShapeConfig(has_shape_collision=False, has_particle_collision=False,
                                          density=0.0)
    cams = []
    for model, q in views:
        tfs = link_transforms(model, q)
        builder.begin_world(label=model.name)
        pts = []
        for lk in model.links:
            m = tfs[lk.name]
            for p in lk.visuals:
                v = p.vertices @ m[:3, :3].T + m[:3, 3]
                n = None if p.normals is None else p.normals @ m[:3, :3].T
                pts.append(v)
                mesh = newton.Mesh(v.astype(np.float32), p.faces.astype(np.int32).ravel(),
                                   normals=None if n is None else n.astype(np.float32), compute_inertia=False)
                mat = model.materials.get(p.material) if p.material else None
                color = tuple(float(c) for c in (mat.base_color if mat else (0.7, 0.7, 0.7)))
                builder.add_shape_mesh(body=-1, mesh=mesh, cfg=cfg, color=color)
        builder.end_world()
        allp = np.vstack(pts)
        cams.append(_look_at(allp.min(0), allp.max(0)))
    sim = builder.finalize(device=device)
    clear = SensorCamera.ClearData(clear_color=_pack(BACKGROUND))
    cam = SensorCamera(sim, default_clear_data=clear)
    cam.create_default_light(enable_shadows=False, direction=wp.vec3f(-0.45, -0.25, -1.0))
    rays = SensorCamera.compute_camera_rays_pinhole(tile, tile, camera_fov=FOV, device=device)
    tf = wp.array([wp.transformf(wp.vec3f(*e), wp.quatf(*qq)) for e, qq in cams], dtype=wp.transformf,
                  device=device)
    worlds = wp.array(np.arange(len(cams), dtype=np.int32), dtype=wp.int32, device=device)
    img = cam.allocate_image_color(len(cams), tile, tile)
    cam.update(sim.state(), tf, rays, color_image=img, world_indices=worlds)
    return img.numpy().view(np.uint8).reshape(len(cams), tile, tile, 4)[..., :3].copy()


def _look_at(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Camera position (3,) and orientation quaternion (x, y, z, w) framing the box lo..hi [m]; the
    camera looks along its local -Z with +Y up."""
    from scipy.spatial.transform import Rotation

    c = (lo + hi) / 2
    r = max(float(np.linalg.norm(hi - lo)) / 2, 0.02)
    d = VIEW_DIR / np.linalg.norm(VIEW_DIR)
    eye = c + d * r / np.sin(FOV / 2) * 1.02
    f = (c - eye) / np.linalg.norm(c - eye)
    right = np.cross(f, (0.0, 0.0, 1.0))
    right /= np.linalg.norm(right)
    up = np.cross(right, f)
    return eye, Rotation.from_matrix(np.column_stack([right, up, -f])).as_quat()


def _pack(rgb) -> int:
    r, g, b = rgb
    return int(r) | (int(g) << 8) | (int(b) << 16) | (255 << 24)


def contact_sheets(models: Sequence[AssetModel], out_dir: Path, *, tile: int = 256,
                   device: str = "cpu") -> list[Path]:
    """Write ``<out_dir>/<category>.png`` for every category among ``models``; returns the paths."""
    from PIL import Image, ImageDraw

    out_dir.mkdir(parents=True, exist_ok=True)
    by_cat: dict[str, list[AssetModel]] = {}
    for m in models:
        by_cat.setdefault(m.annotation.category, []).append(m)
    views, index = [], {}
    for cat, ms in by_cat.items():
        for m in ms:
            index[(m.name, 0)] = len(views)
            views.append((m, {}))
            if m.joints:
                index[(m.name, 1)] = len(views)
                views.append((m, upper_limits(m)))
    imgs = render_views(views, tile=tile, device=device)
    label_h = 18
    paths = []
    for cat, ms in by_cat.items():
        rows = 2 if any(m.joints for m in ms) else 1
        sheet = Image.new("RGB", (tile * len(ms), (tile + label_h) * rows), BACKGROUND)
        draw = ImageDraw.Draw(sheet)
        for c, m in enumerate(ms):
            for r in range(rows):
                if (m.name, r) not in index:
                    continue
                sheet.paste(Image.fromarray(imgs[index[(m.name, r)]]), (c * tile, r * (tile + label_h)))
                label = m.name + (" open" if r == 1 else "")
                draw.text((c * tile + 4, r * (tile + label_h) + tile + 3), label, fill=(30, 30, 30))
        path = out_dir / f"{cat}.png"
        sheet.save(path)
        paths.append(path)
    log.info("contact sheets: %d categories, %d views -> %s", len(paths), len(views), out_dir)
    return paths


def load_catalog_models(catalog_dir: Path) -> list[AssetModel]:
    """Every valid asset of a catalog folder, read with the project's loaders (invalid ones are logged)."""
    from asset_catalog.annotations import load_annotations, resolve_source
    from stages.loaders import load_source

    cat = load_annotations(catalog_dir)
    for bad in cat.invalid:
        log.warning("%s", bad.reason)
    return [load_source(resolve_source(catalog_dir, a.source), a) for a in cat.assets]


def main(argv: list[str]) -> int:
    import argparse

    p = argparse.ArgumentParser(prog="agentworld render-assets",
                                description="Render a contact-sheet PNG per category (Newton SensorCamera, CPU).")
    p.add_argument("--out", type=Path, required=True, help="folder for <category>.png")
    p.add_argument("--catalog", type=Path, default=None,
                   help="render this catalog folder's sources (default: the built-in generators)")
    p.add_argument("--variants", type=int, default=5)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--categories", default=None, help="comma-separated subset")
    p.add_argument("--tile", type=int, default=256, help="tile size [px]")
    p.add_argument("--device", default="cpu")
    a = p.parse_args(argv)
    cats = [c.strip() for c in a.categories.split(",") if c.strip()] if a.categories else None
    if a.catalog is not None:
        models = [m for m in load_catalog_models(a.catalog) if cats is None or m.annotation.category in cats]
    else:
        from asset_catalog.default_catalog import generate_default_assets

        try:
            models = [g.model for g in generate_default_assets(variants_per_category=a.variants, seed=a.seed,
                                                                 categories=cats)]
        except ValueError as e:
            p.error(str(e))
    if not models:
        p.error("nothing to render")
    paths = contact_sheets(models, a.out, tile=a.tile, device=a.device)
    print(f"wrote {len(paths)} contact sheets to {a.out}")
    return 0
