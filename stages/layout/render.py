"""Pictures of a layout: a top-down plan PNG (pillow) and a 3-D render PNG (Newton's SensorCamera,
ray traced on the CPU), plus the ``agentworld render-layout`` command.

The 3-D render shows the floors side by side (exploded view, ceilings and roof left out) so that
every room, the stairs and the stairwell openings are visible from one camera.
"""

from __future__ import annotations

import argparse
import logging
import math
from pathlib import Path

import numpy as np

from stages.layout.floorplan import FloorPlan, load_floor_plan

log = logging.getLogger(__name__)

ROOM_COLORS = {
    "living_room": (246, 214, 160),
    "kitchen": (196, 226, 170),
    "bedroom": (180, 204, 236),
    "bathroom": (170, 226, 226),
    "hallway": (226, 220, 208),
}
WALL = (40, 40, 44)
WINDOW = (40, 150, 230)
STAIR = (150, 110, 80)
RAIL = (200, 40, 40)


def _label_point(poly: list[tuple[float, float]]) -> tuple[float, float]:
    """A point well inside a polygon (grid search for the point farthest from the edges)."""
    xs, ys = [p[0] for p in poly], [p[1] for p in poly]
    best, best_d = (sum(xs) / len(xs), sum(ys) / len(ys)), -1.0
    edges = list(zip(poly, poly[1:] + poly[:1], strict=True))
    for gx in np.linspace(min(xs), max(xs), 15)[1:-1]:
        for gy in np.linspace(min(ys), max(ys), 15)[1:-1]:
            inside = False
            for (x0, y0), (x1, y1) in edges:
                if (y0 > gy) != (y1 > gy) and gx < x0 + (gy - y0) * (x1 - x0) / (y1 - y0):
                    inside = not inside
            if not inside:
                continue
            d = min(abs(gx - x0) if x0 == x1 else abs(gy - y0) for (x0, y0), (x1, y1) in edges
                    if (min(y0, y1) <= gy <= max(y0, y1) if x0 == x1 else min(x0, x1) <= gx <= max(x0, x1)))
            if d > best_d:
                best, best_d = (float(gx), float(gy)), d
    return best


def render_plan_png(plan: FloorPlan, out_path: Path, *, px_per_m: int = 60, grids: bool = True) -> Path:
    """Top-down plan, one panel per floor (rooms, walls, doors with swing arcs, windows, stairs,
    stairwell openings and rails, room labels, 1 m scale bar); with ``grids`` a second row shows
    each floor's occupancy grid (dark: occupied, grey: too close for the robot, white: free)."""
    from PIL import Image, ImageDraw

    x0, y0, x1, y1 = plan.footprint
    margin = 40
    pw, ph = int((x1 - x0) * px_per_m) + 2 * margin, int((y1 - y0) * px_per_m) + 2 * margin + 20
    n = len(plan.floors)
    rows = 2 if grids and plan.floors[0].grid is not None else 1
    img = Image.new("RGB", (pw * n, ph * rows), (255, 255, 255))
    draw = ImageDraw.Draw(img)
    for f, fl in enumerate(plan.floors):
        ox = f * pw + margin

        def P(x: float, y: float, ox: int = ox) -> tuple[int, int]:
            return (round(ox + (x - x0) * px_per_m), round(ph - margin - (y - y0) * px_per_m))

        def box(b, fill, ox: int = ox, outline=None) -> None:
            (ax, ay), (bx, by) = P(b[0], b[1], ox), P(b[2], b[3], ox)
            draw.rectangle([min(ax, bx), min(ay, by), max(ax, bx), max(ay, by)], fill=fill, outline=outline)

        draw.text((f * pw + margin, 8), f"floor {f}  (z = {fl.elevation:.2f} m)", fill=(0, 0, 0))
        for r in fl.rooms:
            draw.polygon([P(*p) for p in r.polygon], fill=ROOM_COLORS.get(r.type.value, (230, 230, 230)))
        for s in plan.stairs:
            if s.floor_from == f:
                for b in s.footprint:
                    box(b, (214, 190, 160), outline=STAIR)
                    long_x = (b[2] - b[0]) > (b[3] - b[1])
                    lo, hi = (b[0], b[2]) if long_x else (b[1], b[3])
                    t = lo
                    while t < hi - 1e-6:
                        ends = ((t, b[1]), (t, b[3])) if long_x else ((b[0], t), (b[2], t))
                        draw.line([P(*ends[0]), P(*ends[1])], fill=STAIR, width=1)
                        t += s.run
                bx, by = P(*s.bottom)
                draw.ellipse([bx - 4, by - 4, bx + 4, by + 4], fill=(0, 120, 0))
            if s.floor_to == f:
                for b in s.opening:
                    box(b, (120, 120, 120))
                tx, ty = P(*s.top)
                draw.ellipse([tx - 4, ty - 4, tx + 4, ty + 4], fill=(200, 0, 0))
        for w in fl.walls:
            box(w.box, WALL)
        for d in fl.doors:
            wall = next(w for w in fl.walls if w.id == d.wall)
            horiz = abs(wall.end[1] - wall.start[1]) < 1e-9
            px, py = d.position
            hw = d.width / 2
            b = (px - hw, wall.box[1], px + hw, wall.box[3]) if horiz else (wall.box[0], py - hw, wall.box[2], py + hw)
            room = next((r for r in fl.rooms if r.id == d.rooms[0]), None)
            box(b, ROOM_COLORS.get(room.type.value, (255, 255, 255)) if room else (255, 255, 255))
            # swing arc into rooms[1] (or into the room for the entrance), hinge at one jamb
            nx, ny = d.normal if not d.exterior else (-d.normal[0], -d.normal[1])
            hinge = (px - hw, py) if horiz else (px, py - hw)
            r = d.width * px_per_m
            hx, hy = P(*hinge)
            closed = 0.0 if horiz else 270.0           # PIL angles: clockwise from +x, image y down
            opened = math.degrees(math.atan2(-ny, nx)) % 360
            a0, a1 = (opened, closed) if (closed - opened) % 360 == 90 else (closed, opened)
            draw.arc([hx - r, hy - r, hx + r, hy + r], a0, a1 if a1 > a0 else a1 + 360, fill=(90, 90, 90))
            leaf = P(hinge[0] + nx * d.width, hinge[1] + ny * d.width)
            draw.line([(hx, hy), leaf], fill=(90, 90, 90), width=2)
        for wdw in fl.windows:
            wall = next(w for w in fl.walls if w.id == wdw.wall)
            horiz = abs(wall.end[1] - wall.start[1]) < 1e-9
            px, py = wdw.position
            hw = wdw.width / 2
            b = (px - hw, wall.box[1], px + hw, wall.box[3]) if horiz else (wall.box[0], py - hw, wall.box[2], py + hw)
            box(b, WINDOW)
        for r in fl.rooms:
            lx, ly = P(*_label_point(list(r.polygon)))
            text = f"{r.type.value.replace('_', ' ')}\n{r.area:.1f} m2"
            draw.multiline_text((lx, ly), text, fill=(0, 0, 0), anchor="mm", align="center")
        sx, sy = P(x0, y0)
        draw.line([(sx, sy + 14), (sx + px_per_m, sy + 14)], fill=(0, 0, 0), width=3)
        draw.text((sx + px_per_m + 6, sy + 8), "1 m", fill=(0, 0, 0))
        if rows == 2:
            occ = plan.occupancy(f) if plan._base is not None else None
            if occ is not None:
                im = Image.fromarray(occ.to_image()[::-1]).convert("RGB")
                size = (int((x1 - x0) * px_per_m), int((y1 - y0) * px_per_m))
                img.paste(im.resize(size, Image.NEAREST), (f * pw + margin, ph + margin))
                draw.text((f * pw + margin, ph + 8), f"floor {f} occupancy, robot radius {occ.robot_radius} m",
                          fill=(0, 0, 0))
    out_path = Path(out_path)
    img.save(out_path)
    return out_path


# ----------------------------------------------------------------------------------------------
# 3-D


def _visual_meshes(usd_path: Path) -> list[tuple[str, int | None, np.ndarray, np.ndarray, tuple, float]]:
    """(prim path, floor or None, vertices (N, 3), triangles (M, 3), color, opacity) of every visual mesh."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(usd_path))
    errs = stage.GetCompositionErrors()
    if errs:
        raise ValueError(f"{usd_path}: composition errors: {errs[0]}")
    cache = UsdGeom.XformCache()
    out = []
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Mesh):
            continue
        mesh = UsdGeom.Mesh(prim)
        pts = np.asarray(mesh.GetPointsAttr().Get(), dtype=np.float64)
        m = np.asarray(cache.GetLocalToWorldTransform(prim), dtype=np.float64)
        pts = pts @ m[:3, :3] + m[3, :3]
        counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get())
        if not np.all(counts == 3):
            raise ValueError(f"{usd_path}: {prim.GetPath()} is not triangulated")
        tris = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(), dtype=np.int32).reshape(-1, 3)
        col = mesh.GetDisplayColorPrimvar().Get()
        op = mesh.GetDisplayOpacityPrimvar().Get()
        parts = str(prim.GetPath()).split("/")
        floor = int(parts[2].split("_")[1]) if len(parts) > 2 and parts[2].startswith("Floor_") else None
        out.append((str(prim.GetPath()), floor, pts, tris, tuple(col[0]) if col else (0.7, 0.7, 0.7),
                    float(op[0]) if op else 1.0))
    return out


def _look_at(eye: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(position, quaternion xyzw) of a camera at eye looking at target (camera looks along -Z, +Y up)."""
    from scipy.spatial.transform import Rotation

    f = target - eye
    f /= np.linalg.norm(f)
    r = np.cross(f, [0.0, 0.0, 1.0])
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    rot = np.stack([r, u, -f], axis=1)
    return eye, Rotation.from_matrix(rot).as_quat()


def render_3d_png(usd_path: Path, out_path: Path, *, width: int = 1280, height: int = 800, gap: float = 2.0,
                  device: str = "cpu") -> Path:
    """Exploded 3-D view of a layout USD: floors side by side, ceilings and roof left out."""
    import warp as wp
    from PIL import Image

    import newton
    from newton.sensors import SensorCamera

    meshes = [m for m in _visual_meshes(usd_path)
              if m[1] is not None and "/Ceiling/" not in m[0]]
    if not meshes:
        raise ValueError(f"{usd_path}: no visual meshes on any floor")
    lo = np.min([m[2].min(axis=0) for m in meshes], axis=0)
    hi = np.max([m[2].max(axis=0) for m in meshes], axis=0)
    floors = sorted({m[1] for m in meshes})
    z_shift = {f: min(m[2][:, 2].min() for m in meshes if m[1] == f and "/Walls/" in m[0]) for f in floors}
    span = hi[0] - lo[0] + gap
    b = newton.ModelBuilder()
    cfg = newton.ModelBuilder.ShapeConfig(has_shape_collision=False, has_particle_collision=False, density=0.0)
    for path, f, pts, tris, col, _op in meshes:
        v = pts[tris.reshape(-1)] + np.array([f * span, 0.0, -z_shift[f]])   # flat shading: unshared vertices
        idx = np.arange(len(v), dtype=np.int32)
        mesh = newton.Mesh(v.astype(np.float32), idx, compute_inertia=False)
        b.add_shape_mesh(-1, mesh=mesh, cfg=cfg, color=col, label=path)
    model = b.finalize(device=device)
    state = model.state()
    cam = SensorCamera(model, default_render_config=SensorCamera.RenderConfig(enable_shadows=True))
    cam.create_default_light(enable_shadows=True, direction=wp.vec3f(*(np.array([0.4, 0.7, -1.0]) /
                                                                        np.linalg.norm([0.4, 0.7, -1.0]))))
    cam.set_ambient_light((0.45, 0.45, 0.5), (0.15, 0.15, 0.15))
    total_w = len(floors) * span - gap
    center = np.array([lo[0] + total_w / 2, (lo[1] + hi[1]) / 2, 0.5])
    fov = 0.7
    dist = 0.62 * max(total_w * height / width, hi[1] - lo[1]) / math.tan(fov / 2) + 2.0
    eye = center + np.array([0.0, -0.75, 0.95]) / np.linalg.norm([0.0, -0.75, 0.95]) * dist
    pos, q = _look_at(eye, center)
    xf = wp.array([wp.transformf(wp.vec3f(*map(float, pos)), wp.quatf(*map(float, q)))], dtype=wp.transformf,
                  device=device)
    rays = SensorCamera.compute_camera_rays_pinhole(width, height, camera_fov=fov, device=device)
    color = cam.allocate_image_color(1, width, height)
    clear = SensorCamera.ClearData(clear_color=0xFFF0E8E0)
    cam.update(state, xf, rays, color_image=color, clear_data=clear)
    rgba = color.numpy()[0].view(np.uint8).reshape(height, width, 4)
    out_path = Path(out_path)
    Image.fromarray(np.ascontiguousarray(rgba[:, :, :3])).save(out_path)
    return out_path


# ----------------------------------------------------------------------------------------------
# command


def _parse_rooms(text: str) -> dict[str, int]:
    out = {}
    for part in text.split(","):
        name, _, n = part.partition("=")
        out[name.strip()] = int(n or 1)
    return out


def cli(argv: list[str]) -> int:
    """``agentworld render-layout OUT [--rooms living_room=1,kitchen=1,bedroom=2] [--floors 2]
    [--seed 0] [--stairs any|straight|l_shaped] [--existing]``: generate a layout into OUT (or use
    the one already there with --existing) and write OUT/plan.png and OUT/render.png."""
    from stages.layout.build import PLAN_NAME, USD_NAME, generate_layout
    from stages.layout.spec import LayoutSpec

    ap = argparse.ArgumentParser(prog="agentworld render-layout", description=cli.__doc__)
    ap.add_argument("out", type=Path)
    ap.add_argument("--rooms", default="living_room=1,kitchen=1,bedroom=2,bathroom=1")
    ap.add_argument("--floors", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--stairs", default="any", choices=["any", "straight", "l_shaped"])
    ap.add_argument("--existing", action="store_true", help="render the layout already in OUT")
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=800)
    a = ap.parse_args(argv)
    if not a.existing:
        try:
            spec = LayoutSpec(rooms=_parse_rooms(a.rooms), floors=a.floors, stair_shape=a.stairs)
        except ValueError as e:
            print(f"render-layout: bad spec: {e}")
            return 2
        generate_layout(spec, a.seed, a.out)
    plan = load_floor_plan(a.out / PLAN_NAME)
    p1 = render_plan_png(plan, a.out / "plan.png")
    p2 = render_3d_png(a.out / USD_NAME, a.out / "render.png", width=a.width, height=a.height)
    print(f"wrote {p1}\nwrote {p2}")
    return 0
