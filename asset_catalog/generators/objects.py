"""Rigid interactables: vessels (bowl, plate, mug, cup, pitcher, bottle, can), food (apple, orange,
banana), paper and fabric things (book, box, crumpled paper, pillow, sponge), a clothes hanger, and two
open containers: a trash can and a dish rack.

Vessels have real open cavities; their colliders are convex wedges of the wall plus a base disc, so a
cavity stays a cavity in simulation. Near-convex objects are written as OBJ with a convex-hull collider.
Sizes are real sizes [m]; masses are real masses [kg] where density x volume would be wrong (full
cans and bottles, hollow boxes, foam, paper balls).
"""

from __future__ import annotations

import numpy as np

import asset_catalog.generators._geom as g
from asset_catalog.generators._builder import AssetBuilder
from asset_catalog.generators._parts import FABRICS, PLASTICS, pick_color

CERAMIC = 2400.0
CERAMICS = [(0.95, 0.95, 0.93), (0.85, 0.3, 0.25), (0.25, 0.45, 0.7), (0.9, 0.85, 0.6), (0.3, 0.55, 0.4),
            (0.15, 0.15, 0.17), (0.8, 0.65, 0.75)]


def _vessel_profile(r_foot: float, r_rim: float, h: float, wall: float, bottom: float, bulge: float,
                    k: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Outer and inner wall profiles (k, 2) of (r, z) [m], bottom to rim. ``bulge`` in [0, 1] bends the
    wall from straight (0) to a quarter ellipse (1)."""
    s = np.linspace(0.0, 1.0, k)
    curve = bulge * np.sin(s * np.pi / 2) + (1 - bulge) * s
    zc = bulge * (1 - np.cos(s * np.pi / 2)) + (1 - bulge) * s
    outer = np.column_stack([r_foot + (r_rim - r_foot) * curve, h * zc])
    inner = np.column_stack([np.maximum(outer[:, 0] - wall, 0.004), bottom + (h - bottom) * zc])
    inner[-1, 1] = h
    inner[:, 0] = np.minimum(inner[:, 0], outer[:, 0] - wall * 0.7)
    return outer, inner


def _vessel(b: AssetBuilder, mat: str, density: float, outer: np.ndarray, inner: np.ndarray, *,
            n: int = 40, wedges: int = 12, bands: int = 2) -> None:
    prof = [(0.0, 0.0), *map(tuple, outer), *map(tuple, inner[::-1]), (0.0, float(inner[0, 1]))]
    body = g.lathe(prof, n=n)
    pieces = g.revolved_wall_pieces(outer, inner, wedges, bands)
    pieces.append(g.cylinder(float(outer[0, 0]), float(inner[0, 1]), (0, 0, float(inner[0, 1]) / 2), n=24))
    b.add("base", body, mat, density=density, collision=pieces)


def bowl(b: AssetBuilder) -> None:
    m = b.material("ceramic", pick_color(b, CERAMICS), roughness=0.25)
    rim = b.param("rim_radius", 0.06, 0.1)
    h = b.param("height", 0.045, 0.085)
    wall = b.param("wall", 0.003, 0.005)
    outer, inner = _vessel_profile(rim * b.param("foot_ratio", 0.4, 0.55), rim, h, wall, 0.006,
                                   b.param("bulge", 0.6, 1.0))
    _vessel(b, m, CERAMIC, outer, inner, wedges=10)
    b.handle("base", (0.0, rim - wall / 2, h - 0.005), wall, 0.02, (1.0, 0.0, 0.0), kind="rim")
    return None


def plate(b: AssetBuilder) -> None:
    m = b.material("ceramic", pick_color(b, CERAMICS), roughness=0.2)
    r = b.param("radius", 0.1, 0.14)
    h = b.param("height", 0.015, 0.028)
    t = b.param("thickness", 0.004, 0.006)
    rf = r * b.param("well_ratio", 0.55, 0.7)
    prof = [(0, 0), (rf, 0), (rf + 0.01, 0.002), (r, h), (r - 0.004, h), (rf + 0.01, t + 0.002),
            (rf, t), (0, t)]
    b.add("base", g.lathe(prof, n=56), m, density=CERAMIC)
    return None


def _loop_handle(b: AssetBuilder, mat: str, density: float, *, r_body: float, z_lo: float, z_hi: float,
                 reach: float, rod: float) -> None:
    """A C-shaped handle on the +Y side of a vessel of radius r_body [m], from z_lo to z_hi [m]."""
    zm, rz = (z_lo + z_hi) / 2, (z_hi - z_lo) / 2
    a = np.linspace(-np.pi / 2, np.pi / 2, 9)
    pts = np.column_stack([np.zeros_like(a), r_body - rod + (reach + rod) * np.cos(a), zm + rz * np.sin(a)])
    segs = g.tube_path(pts, rod, n=10)
    b.add("base", g.union(segs), mat, density=density, collision=segs)
    b.handle("base", (0.0, r_body + reach, zm), 2 * rod, reach - rod, (0.0, 0.0, 1.0), kind="loop")


def mug(b: AssetBuilder) -> None:
    m = b.material("ceramic", pick_color(b, CERAMICS), roughness=0.2)
    r, h = b.param("radius", 0.035, 0.048), b.param("height", 0.08, 0.11)
    wall = b.param("wall", 0.0035, 0.005)
    outer = np.array([[r * 0.92, 0.0], [r, 0.006], [r, h]])
    inner = np.array([[r - wall, 0.008], [r - wall, 0.012], [r - wall, h]])
    _vessel(b, m, CERAMIC, outer, inner, bands=1)
    reach = b.param("handle_reach", 0.022, 0.032)
    _loop_handle(b, m, CERAMIC, r_body=r, z_lo=h * 0.22, z_hi=h * 0.82, reach=reach,
                 rod=b.param("handle_rod", 0.0045, 0.006))
    return None


def cup(b: AssetBuilder) -> None:
    m = b.material("cup", pick_color(b, PLASTICS + [(0.85, 0.9, 0.92)]), roughness=0.3)
    r, h = b.param("rim_radius", 0.032, 0.045), b.param("height", 0.08, 0.13)
    rb = r * b.param("taper", 0.65, 0.9)
    wall = b.param("wall", 0.002, 0.003)
    outer, inner = _vessel_profile(rb, r, h, wall, 0.005, 0.0, k=4)
    _vessel(b, m, 1100.0, outer, inner, bands=1)
    return None


def pitcher(b: AssetBuilder) -> None:
    m = b.material("pitcher", pick_color(b, CERAMICS + [(0.85, 0.9, 0.92)]), roughness=0.25)
    r, h = b.param("radius", 0.05, 0.07), b.param("height", 0.17, 0.25)
    wall = b.param("wall", 0.004, 0.006)
    outer, inner = _vessel_profile(r * 0.85, r, h, wall, 0.008, b.param("bulge", 0.0, 0.4), k=6)
    _vessel(b, m, CERAMIC, outer, inner, bands=1)
    ang = np.radians(np.array([250.0, 270.0, 290.0]))
    rim_pts = [(r * np.cos(a), r * np.sin(a), z) for a in ang for z in (h, h - 0.04)]
    tip = [(0.0, -(r + b.param("spout", 0.02, 0.035)), h + 0.008)]
    spout = g.hull_points(np.array(rim_pts + tip))
    b.add("base", spout, m, density=CERAMIC)
    reach = b.param("handle_reach", 0.032, 0.042)
    width, depth = b.param("handle_width", 0.011, 0.014), b.param("handle_depth", 0.018, 0.022)
    centre, normal = pitcher_handle_path(b.params)
    segs = g.strap_path(centre, normal, width, depth)
    b.add("base", g.union(segs), m, density=CERAMIC, collision=segs)
    b.handle("base", (0.0, r + reach, h * 0.575), width, reach - depth / 2, (0.0, 0.0, 1.0), kind="loop")
    return None


def pitcher_handle_path(params: dict, k: int = 11) -> tuple[np.ndarray, np.ndarray]:
    """The pitcher's strap handle (a C on the +Y side, from 0.3 to 0.85 of the height, in the YZ
    plane): its centre line (k, 3) [m] and the unit in-plane normal there (k, 3), outward. The strap's
    section is ``handle_width`` across (X, what a hand closes on) by ``handle_depth`` along the normal
    (a flat, deep section as moulded jug handles have: a parallel gripper's pads clamp its flat
    sides, so the pitcher cannot turn about the strap as it did about a round rod). The centre line
    is ``handle_reach`` out from the body at mid-height; its ends run into the body's wall (half the
    wall deep) along Y. ``params``: the generator's (radius, height, wall, bulge, handle_reach)."""
    r, h, wall = float(params["radius"]), float(params["height"]), float(params["wall"])
    outer, _ = _vessel_profile(r * 0.85, r, h, wall, 0.008, float(params["bulge"]), k=6)
    z_lo, z_hi = 0.3 * h, 0.85 * h
    zm, rz = (z_lo + z_hi) / 2, (z_hi - z_lo) / 2
    y_lo, y_hi = (float(np.interp(z, outer[:, 1], outer[:, 0])) - wall / 2 for z in (z_lo, z_hi))
    a = np.linspace(-np.pi / 2, np.pi / 2, k)
    base = y_lo + (y_hi - y_lo) * (np.sin(a) + 1) / 2
    y = base + (r + float(params["handle_reach"]) - base) * np.cos(a)
    z = zm + rz * np.sin(a)
    ty, tz = np.gradient(y, a), np.gradient(z, a)
    n = np.column_stack([np.zeros(k), tz, -ty]) / np.hypot(ty, tz)[:, None]
    return np.column_stack([np.zeros(k), y, z]), n


def bottle(b: AssetBuilder) -> float:
    glassy = b.choice("material", ["plastic", "glass"])
    body_c = pick_color(b, [(0.75, 0.9, 0.95), (0.3, 0.55, 0.3), (0.45, 0.3, 0.15), (0.9, 0.9, 0.92)])
    m = b.material("bottle", body_c, roughness=0.08 if glassy == "glass" else 0.3)
    cap = b.material("cap", pick_color(b, PLASTICS), roughness=0.4)
    r, h = b.param("radius", 0.03, 0.045), b.param("height", 0.18, 0.3)
    rn = b.param("neck_radius", 0.012, 0.016)
    hs = h * b.param("shoulder", 0.55, 0.7)
    prof = [(0, 0), (r - 0.003, 0), (r, 0.004), (r, hs)]
    for s in np.linspace(0.2, 1.0, 5):
        prof.append((rn + (r - rn) * np.cos(s * np.pi / 2), hs + (h * 0.88 - hs) * s))
    prof += [(rn, h - 0.02), (0, h - 0.02)]
    body = g.lathe(prof, n=36)
    b.add("base", body, m, density=1000.0)
    b.add("base", g.cylinder(rn + 0.002, 0.024, (0, 0, h - 0.012), n=24), cap, density=1000.0)
    return float(body.volume() * 1000.0 * 0.9 + (0.25 if glassy == "glass" else 0.03) * (h / 0.25))


def can(b: AssetBuilder) -> float:
    m = b.material("can", pick_color(b, PLASTICS, 0.08), roughness=0.3, metallic=0.8)
    lid = b.material("lid", (0.8, 0.8, 0.82), roughness=0.25, metallic=1.0)
    r, h = b.param("radius", 0.032, 0.042), b.param("height", 0.1, 0.135)
    body = g.lathe([(0, 0.004), (r - 0.006, 0), (r, 0.008), (r, h - 0.012), (r - 0.005, h - 0.004), (0, h - 0.004)],
                   n=40)
    b.add("base", body, m, density=1000.0)
    b.add("base", g.cylinder(r - 0.004, 0.005, (0, 0, h - 0.0035), n=40), lid, density=1000.0)
    return float(np.pi * r * r * h * 1000.0 * 0.92 + 0.015)


def apple(b: AssetBuilder) -> None:
    red = b.material("skin", pick_color(b, [(0.75, 0.1, 0.08), (0.55, 0.75, 0.2), (0.85, 0.7, 0.15)], 0.06),
                     roughness=0.45)
    stem = b.material("stem", (0.35, 0.22, 0.1), roughness=0.8)
    r = b.param("radius", 0.035, 0.046)
    hz = r * b.param("height_ratio", 0.85, 1.0)
    t = np.linspace(0.5, np.pi - 0.1, 18)     # from a flat base ring (it sits on it, it does not roll)
    rr = r * np.sin(t) * (1 + b.param("top_heavy", 0.04, 0.12) * -np.cos(t))
    zz = hz * (1 - np.cos(t))
    prof = [(0.0, 0.006), *zip(rr, zz, strict=True), (0.0, 2 * hz - 0.008)]
    body = g.lathe(prof, n=32)
    dz = -body.bounding_box()[2]
    b.add("base", body.translate((0, 0, dz)), red, density=850.0)
    stalk = g.cylinder(0.002, 0.02, (0.0, 0.0, 0.0), n=8).rotate((0, 12, 0))
    b.add("base", stalk.translate((0.0, 0.0, 2 * hz - 0.008 + dz + 0.008)), stem, density=850.0)
    return None


def orange(b: AssetBuilder) -> None:
    skin = b.material("skin", pick_color(b, [(0.95, 0.5, 0.05), (0.95, 0.65, 0.1), (0.9, 0.85, 0.2)], 0.04),
                      roughness=0.7)
    r = b.param("radius", 0.034, 0.046)
    rz = r * b.param("oblate", 0.85, 0.95)
    b.add("base", g.ellipsoid((r, r, rz), (0, 0, rz), n=32), skin, density=900.0)
    b.add("base", g.cylinder(0.005, 0.004, (0, 0, 2 * rz - 0.001), n=8), skin, density=900.0)
    return None


def banana(b: AssetBuilder) -> None:
    skin = b.material("skin", pick_color(b, [(0.95, 0.82, 0.2), (0.85, 0.85, 0.25), (0.9, 0.75, 0.15)], 0.03),
                      roughness=0.6)
    tip = b.material("tip", (0.25, 0.2, 0.1), roughness=0.8)
    rc = b.param("curve_radius", 0.12, 0.18)
    span = np.radians(b.param("span_deg", 55.0, 80.0))
    rmax = b.param("thickness_radius", 0.015, 0.019)
    k = 9
    a = np.linspace(-span / 2, span / 2, k)
    pts = np.column_stack([rc * np.cos(a) - rc, rc * np.sin(a), np.full(k, rmax)])
    radii = rmax * (0.35 + 0.65 * np.sin(np.linspace(0.08, np.pi - 0.08, k)) ** 0.6)
    segs = [g.hull([g.sphere(radii[i], pts[i], n=14), g.sphere(radii[i + 1], pts[i + 1],
                                                               n=14)]) for i in range(k - 1)]
    b.add("base", g.union(segs), skin, density=950.0, collision=segs)
    end = pts[-1] + np.array([0.0, 0.012, 0.0])
    b.add("base", g.hull([g.sphere(radii[-1] * 0.5, pts[-1], n=10), g.sphere(0.004, end, n=8)]), tip,
          density=950.0)
    return None


def book(b: AssetBuilder) -> None:
    cover = b.material("cover", pick_color(b, PLASTICS + FABRICS, 0.06), roughness=0.6)
    pages = b.material("pages", (0.96, 0.95, 0.9), roughness=0.9)
    w, length = b.param("width", 0.11, 0.19), b.param("length", 0.15, 0.26)
    t = b.param("thickness", 0.01, 0.05)
    board = 0.0025
    b.add("base", g.box((length, w, board), (0, 0, board / 2)), cover, density=700.0)
    b.add("base", g.box((length, w, board), (0, 0, t - board / 2)), cover, density=700.0)
    b.add("base", g.box((length, board * 1.5, t), (0, -w / 2 + board * 0.75, t / 2)), cover, density=700.0)
    b.add("base", g.box((length - 0.006, w - 0.004, t - 2 * board + 0.001), (0, -0.002 + 0.0005, t / 2)),
          pages,
          density=600.0)
    return None


def box(b: AssetBuilder) -> float:
    card = b.material("cardboard", pick_color(b, [(0.7, 0.55, 0.35), (0.78, 0.65, 0.45), (0.9, 0.9, 0.88)],
                                              0.03),
                      roughness=0.9)
    tape = b.material("tape", (0.8, 0.7, 0.5), roughness=0.4)
    sx, sy, sz = b.param("length", 0.15, 0.5), b.param("width", 0.12, 0.4), b.param("height", 0.08, 0.35)
    b.add("base", g.box((sx, sy, sz), (0, 0, sz / 2)), card, density=100.0)
    b.add("base", g.box((sx + 0.002, 0.05, 0.001), (0, 0, sz + 0.0003)), tape, density=100.0)
    area = 2 * (sx * sy + sy * sz + sx * sz)
    return float(area * 0.6 + b.param("contents", 0.0, 1.0) * sx * sy * sz * 40.0)


def crumpled_paper(b: AssetBuilder) -> float:
    paper = b.material("paper", pick_color(b, [(0.95, 0.95, 0.92), (0.92, 0.9, 0.8), (0.85, 0.88, 0.95)],
                                           0.02),
                       roughness=0.95)
    r = b.param("radius", 0.025, 0.045)
    dirs = b.rng.normal(size=(40, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    amps = b.rng.uniform(-0.22, 0.18, 40)

    def warp(p: np.ndarray) -> np.ndarray:
        n = p / np.maximum(np.linalg.norm(p, axis=1, keepdims=True), 1e-12)
        bump = (np.clip(n @ dirs.T, 0, None) ** 14) @ amps
        q = p * np.clip(1 + bump, 0.6, 1.4)[:, None]
        q[:, 2] = np.maximum(q[:, 2], -flat * r)   # a flat crushed side: it lies still, it does not roll
        return q

    flat = b.param("flat_bottom", 0.5, 0.65)

    ball = g.sphere(r, n=28).warp_batch(warp)
    lo = ball.bounding_box()[2]
    b.add("base", ball.translate((0, 0, -lo)), paper, density=600.0)
    return b.param("mass", 0.004, 0.02)


def pillow(b: AssetBuilder) -> float:
    fab = b.material("fabric", pick_color(b, FABRICS + [(0.95, 0.95, 0.93)], 0.05), roughness=0.95)
    sx, sy, sz = b.param("length", 0.4, 0.65), b.param("width", 0.3, 0.45), b.param("thickness", 0.09, 0.16)

    def squash(p: np.ndarray) -> np.ndarray:
        fx = 1 - 0.95 * np.abs(2 * p[:, 0] / sx) ** 2.5
        fy = 1 - 0.95 * np.abs(2 * p[:, 1] / sy) ** 2.5
        f = np.clip(fx * fy, 0.05, 1.0)
        q = p.copy()   # domed top, flattened bottom (it lies on a bed or sofa and does not rock)
        q[:, 2] = np.where(p[:, 2] > 0, p[:, 2] * f ** 0.8, p[:, 2] * np.clip(3.0 * f, 0.1, 1.0))
        return q

    cube = g.box((sx, sy, sz)).refine(16).warp_batch(squash)
    lo = cube.bounding_box()[2]
    b.add("base", cube.translate((0, 0, -lo)), fab, density=60.0)
    return b.param("mass", 0.3, 0.9)


def cushion(b: AssetBuilder) -> float:
    """A neck-roll cushion: a soft rounded bar lying across a bed, narrow enough (width 55-70 mm) for
    the Franka hand's 80 mm stroke to grasp across its middle (make the bed, issue 16); its flat
    underside keeps it from rolling."""
    fab = b.material("fabric", pick_color(b, FABRICS + [(0.95, 0.95, 0.93)], 0.05), roughness=0.95)
    w, length = b.param("width", 0.055, 0.07), b.param("length", 0.28, 0.4)
    h = b.param("height", 0.05, 0.065)
    b.add("base", g.rounded_box((w, length, h), min(0.018, 0.3 * w), (0, 0, h / 2), n=8), fab, density=60.0)
    return b.param("mass", 0.08, 0.2)


def sponge(b: AssetBuilder) -> float:
    foam = b.material("foam", pick_color(b, [(0.95, 0.85, 0.3), (0.9, 0.6, 0.7), (0.5, 0.75, 0.9)], 0.04),
                      roughness=1.0)
    scrub = b.material("scrub", pick_color(b, [(0.15, 0.5, 0.2), (0.2, 0.3, 0.6)], 0.04), roughness=1.0)
    sx, sy = b.param("length", 0.09, 0.13), b.param("width", 0.06, 0.08)
    tf, ts = b.param("foam_thickness", 0.02, 0.035), b.param("scrub_thickness", 0.004, 0.008)
    b.add("base", g.rounded_box((sx, sy, ts + 0.002), 0.0015, (0, 0, ts / 2 + 0.001), n=6), scrub,
          density=200.0)
    b.add("base", g.rounded_box((sx, sy, tf), 0.006, (0, 0, ts + tf / 2), n=8), foam, density=30.0)
    return b.param("mass", 0.008, 0.025)


HANGER_NECK = 0.075  # the hanger's straight neck under its hook [m]: the Franka fingers (~20 mm wide) pinch it
NECK_STOP = (0.012, 0.006)  # the boss at the neck's top end (under the hook), as plastic and wooden hangers have
                            # where the hook goes in: (length along the neck, radius beyond the rod) [m]; flush with
                            # the rods' underside, it stands up on the hanger's +Z side: a neck pinched just under
                            # it cannot slide down through the fingers (the boss rests on the +Z finger)


def hanger(b: AssetBuilder) -> float | None:
    """A clothes hanger (wire, plastic or wood) lying in its local XY plane: the shoulder bar along Y
    at x = 0, the apex at x = -shoulder_height, the neck (:data:`HANGER_NECK`) along -X with a round
    boss at its top end (:data:`NECK_STOP`, param ``neck_stop``: its length), the hook (inner radius
    ``hook_radius``, round ``rod`` [m]) curling from the neck's end towards -Y, over and its tip
    towards +Y."""
    wire = b.choice("kind", ["wire", "plastic", "wood"])
    color = {"wire": (0.75, 0.75, 0.78), "plastic": pick_color(b, PLASTICS), "wood": (0.6, 0.42, 0.25)}[wire]
    m = b.material("hanger", color, roughness=0.3, metallic=1.0 if wire == "wire" else 0.0)
    rod = {"wire": b.param("rod", 0.0018, 0.0025), "plastic": b.param("rod", 0.004, 0.006),
           "wood": b.param("rod", 0.007, 0.009)}[wire]
    b.params["rod"] = round(rod, 6)   # the kind's (all three are drawn: the other parameters stay as they were)
    b.params["neck"] = HANGER_NECK
    b.params["neck_stop"] = NECK_STOP[0]
    density = {"wire": 7800.0, "plastic": 1100.0, "wood": 700.0}[wire]
    w, hh = b.param("width", 0.38, 0.46), b.param("shoulder_height", 0.1, 0.15)
    z = rod
    pts = [np.array([[-hh, 0, z], [0, -w / 2, z]]), np.array([[0, -w / 2, z], [0, w / 2, z]]),
           np.array([[0, w / 2, z], [-hh, 0, z]])]
    hr = b.param("hook_radius", 0.018, 0.025) + rod   # the hook's inner radius 18-25 mm (a rail up to ~16 mm fits)
    neck = np.array([[-hh, 0, z], [-hh - HANGER_NECK, 0, z]])
    a = np.linspace(0, 1.35 * np.pi, 8)
    cx = -hh - HANGER_NECK - hr
    hook = np.column_stack([cx + hr * np.cos(a), -hr * np.sin(a), np.full(8, z)])
    pieces = []
    for seg in [*pts, neck, hook]:
        pieces += g.tube_path(seg, rod, n=8)
    sl, sr = NECK_STOP
    # flush with the rods' underside (the hanger lies flat on its rods), standing up on its +Z side
    pieces.append(g.cylinder(rod + sr, sl, (-hh - HANGER_NECK + sl / 2, 0.0, rod + sr), axis="x", n=12))
    b.add("base", g.union(pieces), m, density=density, collision=pieces)
    b.handle("base", (cx - hr, 0.0, z), 2 * rod, hr, (0.0, 1.0, 0.0), kind="loop")
    return None


def trash_can(b: AssetBuilder) -> float:
    """An open-top bin standing on the floor: round (a revolved wall, convex wedge colliders) or square
    (bottom + four wall boxes). The cavity stays open so objects dropped in stay inside."""
    shape = b.choice("shape", ["round", "square"])
    metal = b.choice("material", ["plastic", "metal"]) == "metal"
    m = b.material("bin", pick_color(b, [(0.75, 0.75, 0.77), (0.2, 0.2, 0.21)] if metal else PLASTICS, 0.04),
                   roughness=0.3 if metal else 0.5, metallic=1.0 if metal else 0.0)
    h = b.param("height", 0.26, 0.45)
    wall = b.param("wall", 0.004, 0.006)
    density = 1200.0 if metal else 950.0   # (steel sheet is thinner than the collider wall: a lower density)
    if shape == "round":
        r = b.param("rim_radius", 0.11, 0.18)
        outer, inner = _vessel_profile(r * b.param("taper", 0.82, 1.0), r, h, wall, 0.012, 0.0, k=4)
        _vessel(b, m, density, outer, inner, n=48, wedges=16, bands=1)
        rim_y = r
    else:
        sx, sy = b.param("depth", 0.2, 0.34), b.param("width", 0.22, 0.38)
        bottom = 0.012
        _open_box(b, m, density, sx, sy, bottom, wall, h)
        rim_y = sy / 2
    b.handle("base", (0.0, rim_y - wall / 2, h - 0.005), wall, 0.03, (1.0, 0.0, 0.0), kind="rim")
    return b.param("mass", 1.5, 4.0) if metal else b.param("mass", 0.5, 1.8)


def _open_box(b: AssetBuilder, m, density: float, sx: float, sy: float, bottom: float, wall: float,
              h: float) -> None:
    """An open-top box on link "base": a ``bottom`` [m] thick floor of ``sx`` x ``sy`` [m] and four
    ``wall`` [m] thick walls ``h`` [m] high, each its own box (convex collider)."""
    b.add("base", g.box((sx, sy, bottom), (0, 0, bottom / 2)), m, density=density)
    for s in (-1, 1):
        b.add("base", g.box_between((-sx / 2, s * sy / 2 - (wall if s > 0 else 0), 0.0),
                                    (sx / 2, s * sy / 2 + (wall if s < 0 else 0), h)), m, density=density)
        b.add("base", g.box_between((s * sx / 2 - (wall if s > 0 else 0), -sy / 2 + wall, 0.0),
                                    (s * sx / 2 + (wall if s < 0 else 0), sy / 2 - wall, h)), m,
              density=density)


def dish_rack(b: AssetBuilder) -> float:
    """A drying rack for plates: a shallow tray (bottom + four low walls) with two rows of upright tines
    along Y; a plate stands on its edge in a slot, its face across Y. Every part is a box (its own
    convex collider), so the slots stay open in simulation."""
    metal = b.choice("material", ["wire", "plastic"]) == "wire"
    colors = [(0.78, 0.78, 0.8), (0.15, 0.15, 0.16)] if metal else PLASTICS
    m = b.material("rack", pick_color(b, colors, 0.04),
                   roughness=0.25 if metal else 0.45, metallic=1.0 if metal else 0.0)
    density = 2500.0 if metal else 1000.0
    sx, sy = b.param("depth", 0.26, 0.34), b.param("width", 0.34, 0.44)
    tray_h, t = b.param("tray_height", 0.03, 0.05), 0.004
    tine_h = b.param("tine_height", 0.08, 0.12)
    # slot pitch > a plate's height (rim to foot, <= 28 mm); at most 9 tines a row (24 colliders a link)
    pitch = b.param("slot_pitch", 0.045, 0.055)
    tine = b.param("tine_width", 0.004, 0.006)
    _open_box(b, m, density, sx, sy, t, t, tray_h)
    n = int((sy - 2 * t - 0.03) // pitch) + 1
    ys = (np.arange(n) - (n - 1) / 2) * pitch
    rows = (-sx * 0.22, sx * 0.22)
    for x in rows:
        for y in ys:   # tines reach 1 mm into the bottom: one solid with the tray
            b.add("base", g.box((tine, tine, tine_h + 0.001), (x, y, t - 0.001 + (tine_h + 0.001) / 2)), m,
                  density=density)
    b.handle("base", (0.0, sy / 2 - t / 2, tray_h - 0.003), t, 0.02, (1.0, 0.0, 0.0), kind="rim")
    return b.param("mass", 0.6, 1.6) if metal else b.param("mass", 0.4, 1.0)
