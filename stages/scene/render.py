"""Contact sheets of scenes: one camera per room, rendered with Newton's ``SensorCamera`` on CPU.

For each scene the composed stage (layout + referenced assets, the selected look) is read with
usd-core: every visible mesh (purpose default/render; ceilings and roofs left out so the camera sees
in) with its world transform and a color: the bound material's constant diffuse color, or for a
textured material the mean color of its base color texture times the look's tint
(``inputs:scale``), else the mesh's displayColor. A camera stands in a corner of each populated room
at 1.9 m, looking at the room's center. Tiles are labelled with the scene and room.

    agentworld render-scenes WORK_DIR [--step scenes] [--n 12] [--out sheet.png] [--tile 320]
"""

from __future__ import annotations

import argparse
import json
import logging
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

SKIP = ("/Ceiling", "/Roof", "/colliders")


@lru_cache(maxsize=256)
def _texture_mean(path: str) -> tuple[float, float, float]:
    from PIL import Image

    a = np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255.0
    lin = np.where(a <= 0.04045, a / 12.92, ((a + 0.055) / 1.055) ** 2.4)
    return tuple(float(x) for x in lin.reshape(-1, 3).mean(axis=0))


def _material_color(material) -> tuple[float, float, float] | None:
    """Constant diffuse color of a UsdPreviewSurface material, or texture mean x scale."""
    from pxr import UsdShade

    if not material:
        return None
    out = material.GetSurfaceOutput()
    src = out.GetConnectedSources()[0] if out and out.HasConnectedSource() else []
    if not src:
        return None
    shader = UsdShade.Shader(src[0].source.GetPrim())
    inp = shader.GetInput("diffuseColor")
    if not inp:
        return None
    if inp.HasConnectedSource():
        tex = UsdShade.Shader(inp.GetConnectedSources()[0][0].source.GetPrim())
        f = tex.GetInput("file")
        asset = f.Get() if f else None
        path = asset.resolvedPath if asset is not None else ""
        if not path:
            return None
        scale = tex.GetInput("scale")
        s = np.asarray(scale.Get(), dtype=np.float64)[:3] if scale and scale.Get() is not None else np.ones(3)
        return tuple(float(x) for x in np.asarray(_texture_mean(path)) * s)
    v = inp.Get()
    return tuple(float(x) for x in v) if v is not None else None


def scene_meshes(scene_usd: Path) -> list[tuple[str, np.ndarray, np.ndarray, tuple[float, float, float]]]:
    """(prim path, world vertices (N, 3) [m], triangles (M, 3), linear RGB color) of the visible meshes."""
    from pxr import Usd, UsdGeom, UsdShade

    import usd_schemas  # noqa: F401

    stage = Usd.Stage.Open(str(scene_usd))
    cache = UsdGeom.XformCache()
    out = []
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Mesh):
            continue
        path = str(prim.GetPath())
        if any(s in path for s in SKIP):
            continue
        img = UsdGeom.Imageable(prim)
        if img.ComputePurpose() not in (UsdGeom.Tokens.default_, UsdGeom.Tokens.render):
            continue
        if img.ComputeVisibility() == UsdGeom.Tokens.invisible:
            continue
        mesh = UsdGeom.Mesh(prim)
        pts = np.asarray(mesh.GetPointsAttr().Get(), dtype=np.float64)
        counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get())
        idx = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(), dtype=np.int64)
        if len(pts) == 0 or len(counts) == 0:
            continue
        tris = _triangulate(counts, idx)
        m = np.asarray(cache.GetLocalToWorldTransform(prim), dtype=np.float64)
        world = pts @ m[:3, :3] + m[3, :3]
        mat, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
        color = _material_color(mat)
        if color is None:
            dc = mesh.GetDisplayColorPrimvar().Get()
            color = tuple(float(c) for c in dc[0]) if dc else (0.7, 0.7, 0.7)
        out.append((path, world, tris, color))
    return out


def _triangulate(counts: np.ndarray, idx: np.ndarray) -> np.ndarray:
    if np.all(counts == 3):
        return idx.reshape(-1, 3)
    tris, k = [], 0
    for c in counts:
        for j in range(1, c - 1):
            tris.append((idx[k], idx[k + j], idx[k + j + 1]))
        k += c
    return np.asarray(tris, dtype=np.int64)


def room_cameras(plan_path: Path, rooms: Sequence[str]) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(room id, eye (3,), target (3,)) per room: eye 0.35 m inside the corner farthest from the
    room's first door, 1.9 m above the floor; target the room center at 0.5 m."""
    from stages.layout.floorplan import load_floor_plan
    from stages.scene.room import room_interior

    plan = load_floor_plan(plan_path)
    out = []
    for rid in rooms:
        room = plan.room(rid)
        poly = room_interior(plan, room)
        z0 = plan.floors[room.floor].elevation
        c = poly.mean(axis=0)
        doors = [np.asarray(d.position) for d in plan.floors[room.floor].doors if rid in d.rooms]
        ref = doors[0] if doors else c
        corner = max(poly, key=lambda p: float(np.linalg.norm(p - ref)))
        eye2 = corner + (c - corner) / max(np.linalg.norm(c - corner), 1e-9) * 0.35
        out.append((rid, np.array([eye2[0], eye2[1], z0 + 1.9]), np.array([c[0], c[1], z0 + 0.5])))
    return out


def _look_at(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    f = (target - eye) / np.linalg.norm(target - eye)
    r = np.cross(f, [0.0, 0.0, 1.0])
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    return Rotation.from_matrix(np.stack([r, u, -f], axis=1)).as_quat()


def render_scene_views(scene_usd: Path, cameras: Sequence[tuple[str, np.ndarray, np.ndarray]], *,
                       width: int = 320, height: int = 240, fov: float = 1.2, device: str = "cpu") -> np.ndarray:
    """(len(cameras), height, width, 3) uint8 images of the scene from each camera."""
    import warp as wp

    import newton
    from newton.sensors import SensorCamera

    meshes = scene_meshes(scene_usd)
    b = newton.ModelBuilder()
    cfg = newton.ModelBuilder.ShapeConfig(has_shape_collision=False, has_particle_collision=False, density=0.0)
    for path, v, tris, col in meshes:
        flat = v[tris.reshape(-1)]
        mesh = newton.Mesh(flat.astype(np.float32), np.arange(len(flat), dtype=np.int32), compute_inertia=False)
        srgb = tuple(float(min(1.0, max(0.0, c)) ** (1 / 2.2)) for c in col)
        b.add_shape_mesh(-1, mesh=mesh, cfg=cfg, color=srgb, label=path)
    model = b.finalize(device=device)
    cam = SensorCamera(model, default_render_config=SensorCamera.RenderConfig(enable_shadows=False))
    d = np.array([0.5, 0.3, -0.8]) / np.linalg.norm([0.5, 0.3, -0.8])
    cam.create_default_light(enable_shadows=False, direction=wp.vec3f(*map(float, d)))
    cam.set_ambient_light((0.4, 0.4, 0.42), (0.18, 0.18, 0.18))
    xfs = [wp.transformf(wp.vec3f(*map(float, e)), wp.quatf(*map(float, _look_at(e, t)))) for _, e, t in cameras]
    tf = wp.array(xfs, dtype=wp.transformf, device=device)
    rays = SensorCamera.compute_camera_rays_pinhole(width, height, camera_fov=fov, device=device)
    img = cam.allocate_image_color(len(xfs), width, height)
    worlds = wp.array(np.zeros(len(xfs), dtype=np.int32), dtype=wp.int32, device=device)  # every view: world 0
    cam.update(model.state(), tf, rays, color_image=img, world_indices=worlds,
               clear_data=SensorCamera.ClearData(clear_color=0xFF302820))
    return img.numpy().view(np.uint8).reshape(len(xfs), height, width, 4)[..., :3].copy()


def contact_sheet(scenes: Sequence[Path], out_png: Path, *, tile: int = 320, max_rooms: int = 3, cols: int = 4,
                  device: str = "cpu") -> Path:
    """A PNG of tiles, ``cols`` per row: for each scene one tile per populated room (at most
    ``max_rooms``), labelled "<scene> <room> (<objects in it>)"."""
    from PIL import Image, ImageDraw

    h = tile * 3 // 4
    tiles = []
    for s in (Path(x).resolve() for x in scenes):  # relative references resolve from the real folder
        info = json.loads((s.parent / "scene.json").read_text(encoding="utf-8"))
        rooms = list(info["rooms"])[:max_rooms]
        views = render_scene_views(s, room_cameras(_plan_of(s), rooms), width=tile, height=h, device=device)
        for v, r in zip(views, rooms, strict=True):
            n = sum(1 for i in info["instances"] if i["room"] == r)
            tiles.append((v, f"{s.parent.name}  {r}  ({n} objects)"))
    rows = -(-len(tiles) // cols)
    sheet = Image.new("RGB", (tile * min(cols, len(tiles)), h * rows), (20, 20, 20))
    draw = ImageDraw.Draw(sheet)
    for k, (v, lab) in enumerate(tiles):
        x, y = (k % cols) * tile, (k // cols) * h
        sheet.paste(Image.fromarray(v), (x, y))
        draw.rectangle((x, y, x + 6 * len(lab) + 6, y + 13), fill=(0, 0, 0))
        draw.text((x + 3, y + 1), lab, fill=(255, 255, 255))
    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    sheet.save(out_png)
    return out_png


def _plan_of(scene_usd: Path) -> Path:
    """The floor plan beside the layout layer the scene references."""
    from pxr import Sdf

    layer = Sdf.Layer.FindOrOpen(str(scene_usd))
    world = layer.GetPrimAtPath("/World/Layout")
    ref = world.referenceList.GetAddedOrExplicitItems()[0].assetPath
    return (scene_usd.parent / ref).resolve().parent / "floorplan.json"


def find_scenes(work_dir: Path, step: str = "scenes") -> list[Path]:
    return sorted((Path(work_dir) / step).glob("*/scene.usda"))


def cli(argv: list[str]) -> int:
    """``agentworld render-scenes WORK_DIR [--step scenes] [--n 12] [--out PNG] [--tile 320] [--pick spread|first]``."""
    ap = argparse.ArgumentParser(prog="agentworld render-scenes", description=cli.__doc__)
    ap.add_argument("work_dir", type=Path, help="a scene job's work dir (or a folder of scene folders with --step .)")
    ap.add_argument("--step", default="scenes")
    ap.add_argument("--n", type=int, default=12)
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--tile", type=int, default=320)
    ap.add_argument("--pick", choices=["spread", "first"], default="spread")
    a = ap.parse_args(argv)
    scenes = find_scenes(a.work_dir, a.step)
    if not scenes:
        print(f"render-scenes: no scene.usda under {a.work_dir / a.step}")
        return 2
    if a.pick == "spread" and len(scenes) > a.n:
        scenes = [scenes[int(round(i))] for i in np.linspace(0, len(scenes) - 1, a.n)]
    scenes = scenes[:a.n]
    out = a.out or a.work_dir / "reports" / "scenes_contact_sheet.png"
    contact_sheet(scenes, out, tile=a.tile)
    print(f"wrote {out} ({len(scenes)} scenes)")
    return 0


__all__ = ["cli", "contact_sheet", "render_scene_views", "room_cameras", "scene_meshes"]
