"""Basic furniture: seating, tables, beds, storage, rug, lamp, kitchen counter run with sink.

Each generator draws one seeded variant into an ``AssetBuilder`` (root frame: origin at the floor
centre of the footprint, Z up, +X front) and returns a target total mass [kg] (real furniture weights;
upholstery and hollow panels make density x volume wrong) or None to keep density x volume.
"""

from __future__ import annotations

import numpy as np

import asset_catalog.generators._geom as g
from asset_catalog.generators._builder import AssetBuilder
from asset_catalog.generators._parts import (
    FABRICS, METALS, WOODS, carcass, drawer, hinged_door, legs, panel, pick_color)

WOOD = 700.0
FOAM = 60.0
STEEL = 7800.0


def _upholstered(b: AssetBuilder, seats: int, width: tuple[float, float]) -> float:
    fab = b.material("fabric", pick_color(b, FABRICS), roughness=0.9)
    leg_m = b.material("legs", pick_color(b, WOODS + METALS[1:2]), roughness=0.5)
    w = b.param("width", *width)
    d = b.param("depth", 0.78, 0.98)
    seat_h = b.param("seat_height", 0.42, 0.48)
    back_h = b.param("back_height", 0.74, 0.92)
    arm_h = b.param("arm_height", 0.55, 0.68)
    arm_w = b.param("arm_width", 0.10, 0.22)
    leg_h = b.param("leg_height", 0.05, 0.15)
    back_t = b.param("back_thickness", 0.15, 0.25)
    cush_t = 0.12
    base_top = seat_h - cush_t
    x0, x1 = -d / 2, d / 2
    panel(b, "base", (x0, -w / 2 + arm_w, leg_h), (x1 - 0.02, w / 2 - arm_w, base_top), fab, FOAM)
    for s in (-1, 1):
        lo = (x0, s * w / 2 - (arm_w if s > 0 else 0), leg_h)
        hi = (x1, s * w / 2 + (0 if s > 0 else arm_w), arm_h)
        arm = g.rounded_box(np.subtract(hi, lo), min(0.05, arm_w / 2.5), (np.add(lo, hi) / 2), n=10)
        b.add("base", arm, fab, density=FOAM)
    back = g.rounded_box((back_t, w - 2 * arm_w + 0.02, back_h - leg_h), 0.04,
                         (x0 + back_t / 2, 0, (leg_h + back_h) / 2), n=10)
    b.add("base", back, fab, density=FOAM)
    inner = w - 2 * arm_w
    cw = inner / seats
    for i in range(seats):
        cy = -inner / 2 + cw * (i + 0.5)
        cush = g.rounded_box((d - back_t - 0.02, cw - 0.01, cush_t + 0.01), 0.035,
                             (x0 + back_t + (d - back_t - 0.02) / 2, cy, base_top + cush_t / 2), n=10)
        b.add("base", cush, fab, density=FOAM)
    b.surface(base_top + cush_t + 0.005, (x0 + back_t + 0.03, -inner / 2 + 0.03), (x1 - 0.05, inner / 2 - 0.03))
    inset = 0.06
    legs(b, "base", leg_m, WOOD, xs=(x0 + inset, x1 - inset), ys=(-w / 2 + inset, w / 2 - inset),
         z0=0.0, z1=leg_h + 0.01, r=0.022, square=bool(b.rng.integers(2)))
    return float(b.param("mass", 18.0, 26.0) * (w / 0.9) ** 0.8)


def sofa(b: AssetBuilder) -> float:
    seats = int(b.choice("seats", [2, 3, 3, 4]))
    return _upholstered(b, seats, (0.65 * seats + 0.3, 0.65 * seats + 0.6))


def armchair(b: AssetBuilder) -> float:
    return _upholstered(b, 1, (0.72, 0.98))


def coffee_table(b: AssetBuilder) -> float:
    wood = b.material("wood", pick_color(b, WOODS), roughness=0.55)
    frame = b.material("frame", pick_color(b, WOODS + METALS), roughness=0.4)
    length = b.param("length", 0.85, 1.3)
    width = b.param("width", 0.5, 0.75)
    h = b.param("height", 0.36, 0.48)
    top_t = b.param("top_thickness", 0.02, 0.05)
    round_top = b.choice("round", [False, False, True])
    if round_top:
        top = g.cylinder(0.5, top_t, (0, 0, h - top_t / 2), n=48).scale((length, width, 1.0))
        b.add("base", top, wood, density=WOOD)
        legs(b, "base", frame, WOOD, xs=(-length * 0.3, length * 0.3), ys=(-width * 0.25, width * 0.25),
             z0=0.0, z1=h - top_t + 0.002, r=0.022)
    else:
        panel(b, "base", (-length / 2, -width / 2, h - top_t), (length / 2, width / 2, h), wood, WOOD)
        r = 0.025
        legs(b, "base", frame, WOOD, xs=(-length / 2 + 0.05, length / 2 - 0.05),
             ys=(-width / 2 + 0.05, width / 2 - 0.05), z0=0.0, z1=h - top_t + 0.002, r=r, square=True)
    k = 0.35 if round_top else 0.5
    b.surface(h, (-length * k, -width * k), (length * k, width * k))
    if b.choice("shelf", [False, True]):
        st = 0.018
        zs = b.param("shelf_height", 0.08, 0.15)
        sx, sy = (length * 0.3, width * 0.25) if round_top else (length / 2 - 0.05, width / 2 - 0.05)
        panel(b, "base", (-sx, -sy, zs), (sx, sy, zs + st), wood, WOOD)
        b.surface(zs + st, (-sx, -sy), (sx, sy), inside=True, clear_height=h - top_t - zs - st)
    return None


def tv_stand(b: AssetBuilder) -> float:
    wood = b.material("wood", pick_color(b, WOODS), roughness=0.55)
    tv_m = b.material("tv_body", (0.05, 0.05, 0.06), roughness=0.3)
    screen = b.material("screen", (0.01, 0.01, 0.015), roughness=0.05)
    w = b.param("width", 1.2, 1.8)
    d = b.param("depth", 0.35, 0.45)
    h = b.param("height", 0.42, 0.6)
    t = 0.02
    carcass(b, "base", wood, WOOD, w=w, d=d, z0=0.05, z1=h, t=t)
    panel(b, "base", (-d / 2 + t, -t / 2, 0.05 + t), (d / 2 - 0.01, t / 2, h - t), wood, WOOD)
    panel(b, "base", (-d / 2 + t, -w / 2 + t, (0.05 + h) / 2), (d / 2 - 0.01, w / 2 - t, (0.05 + h) / 2 + t),
          wood, WOOD)
    legs(b, "base", wood, WOOD, xs=(-d / 2 + 0.04, d / 2 - 0.04), ys=(-w / 2 + 0.04, w / 2 - 0.04), z0=0.0,
         z1=0.052, r=0.02, square=True)
    for s in (-1, 1):
        b.surface(h, (-d / 2, min(s * 0.17, s * w / 2)), (d / 2, max(s * 0.17, s * w / 2)))
    diag_in = b.param("tv_diagonal_inch", 40.0, min(65.0, w / 0.0254 / 0.9))
    tw = diag_in * 0.0254 * 16 / np.hypot(16, 9)
    th = tw * 9 / 16
    tt = b.param("tv_thickness", 0.035, 0.07)
    foot_h = 0.07
    z_tv = h + foot_h
    panel(b, "base", (-0.12, -0.15, h), (0.08, 0.15, h + 0.015), tv_m, STEEL / 4)
    panel(b, "base", (-0.05, -0.03, h + 0.01), (-0.02, 0.03, z_tv + th * 0.3), tv_m, STEEL / 4)
    panel(b, "base", (-0.02 - tt, -tw / 2, z_tv), (-0.02, tw / 2, z_tv + th), tv_m, 500.0)
    panel(b, "base", (-0.021, -tw / 2 + 0.01, z_tv + 0.01), (-0.017, tw / 2 - 0.01, z_tv + th - 0.01),
          screen, 500.0)
    return float(b.param("mass", 25.0, 40.0))


def bookshelf(b: AssetBuilder) -> float | None:
    wood = b.material("wood", pick_color(b, WOODS), roughness=0.55)
    w = b.param("width", 0.6, 1.0)
    d = b.param("depth", 0.25, 0.36)
    h = b.param("height", 1.1, 2.0)
    t = b.param("thickness", 0.016, 0.025)
    carcass(b, "base", wood, WOOD, w=w, d=d, z0=0.0, z1=h, t=t)
    n = max(2, int(round(h / 0.35)))
    b.surface(t, (-d / 2 + t, -w / 2 + t), (d / 2, w / 2 - t), inside=True, clear_height=h / n - t)
    for i in range(1, n):
        z = i * h / n
        panel(b, "base", (-d / 2 + t, -w / 2 + t, z), (d / 2 - 0.005, w / 2 - t, z + t), wood, WOOD)
        b.surface(z + t, (-d / 2 + t, -w / 2 + t), (d / 2 - 0.005, w / 2 - t), inside=True,
                  clear_height=h / n - t)
    b.surface(h, (-d / 2, -w / 2), (d / 2, w / 2))
    return None


def bed(b: AssetBuilder) -> float:
    frame = b.material("frame", pick_color(b, WOODS), roughness=0.55)
    mattress = b.material("mattress", (0.93, 0.93, 0.9), roughness=0.9)
    sheet = b.material("blanket", pick_color(b, FABRICS), roughness=0.95)
    pillow_m = b.material("pillow", (0.96, 0.96, 0.94), roughness=0.95)
    w = b.choice("width_class", [0.9, 1.2, 1.4, 1.6, 1.8]) + b.param("width_jitter", 0.0, 0.06)
    length = b.param("length", 1.98, 2.12)
    fh = b.param("frame_height", 0.22, 0.35)
    mt = b.param("mattress_thickness", 0.18, 0.28)
    hb = b.param("headboard_height", 0.85, 1.2)
    x0, x1 = -length / 2, length / 2
    t = 0.04
    panel(b, "base", (x0, -w / 2, 0.0), (x0 + 0.06, w / 2, hb), frame, WOOD)
    panel(b, "base", (x1 - t, -w / 2, 0.0), (x1, w / 2, fh + 0.05), frame, WOOD)
    for s in (-1, 1):
        y_out = s * w / 2
        y_in = y_out - s * t
        panel(b, "base", (x0 + 0.06, min(y_in, y_out), 0.08), (x1 - t, max(y_in, y_out), fh), frame, WOOD)
    panel(b, "base", (x0 + 0.06, -w / 2 + t, fh - 0.06), (x1 - t, w / 2 - t, fh - 0.04), frame, WOOD)
    m = g.rounded_box((length - 0.06 - t, w - 2 * t + 0.02, mt), 0.05, ((x0 + 0.06 + x1 - t) / 2, 0,
                                                                        fh - 0.04 + mt / 2))
    b.add("base", m, mattress, density=FOAM)
    blanket_x0 = x0 + 0.06 + (length - 0.1) * b.param("blanket_start", 0.3, 0.45)
    bl = g.rounded_box((x1 - t + 0.02 - blanket_x0, w - 2 * t + 0.06, 0.03), 0.012,
                       ((blanket_x0 + x1 - t + 0.02) / 2, 0, fh - 0.04 + mt + 0.005), n=8)
    b.add("base", bl, sheet, density=FOAM)
    b.surface(fh - 0.04 + mt + 0.02, (blanket_x0 + 0.05, -w / 2 + t + 0.05), (x1 - t - 0.05, w / 2 - t - 0.05))
    n_p = 1 if w < 1.3 else 2
    pw = (w - 2 * t) / n_p - 0.06
    for i in range(n_p):
        cy = -w / 2 + t + (w - 2 * t) / n_p * (i + 0.5)
        p = g.rounded_box((0.4, pw, 0.12), 0.05, (x0 + 0.06 + 0.25, cy, fh - 0.04 + mt + 0.05), n=10)
        b.add("base", p, pillow_m, density=FOAM)
    return float(b.param("mass", 35.0, 50.0) * w)


def dining_table(b: AssetBuilder) -> float | None:
    wood = b.material("wood", pick_color(b, WOODS), roughness=0.5)
    leg_m = b.material("legs", pick_color(b, WOODS + METALS[1:2]), roughness=0.5)
    h = b.param("height", 0.72, 0.78)
    top_t = b.param("top_thickness", 0.025, 0.045)
    if b.choice("round", [False, False, True]):
        dia = b.param("diameter", 0.9, 1.2)
        b.add("base", g.cylinder(dia / 2, top_t, (0, 0, h - top_t / 2), n=56), wood, density=WOOD)
        b.add("base", g.cylinder(0.06, h - top_t, (0, 0, (h - top_t) / 2 + 0.001), n=24), leg_m, density=WOOD)
        b.add("base", g.cylinder(dia * 0.28, 0.04, (0, 0, 0.02), n=40), leg_m, density=WOOD)
        b.surface(h, (-dia * 0.35, -dia * 0.35), (dia * 0.35, dia * 0.35))
    else:
        length = b.param("length", 1.2, 2.0)
        width = b.param("width", 0.75, 1.0)
        panel(b, "base", (-length / 2, -width / 2, h - top_t), (length / 2, width / 2, h), wood, WOOD)
        b.surface(h, (-length / 2, -width / 2), (length / 2, width / 2))
        ix, iy = length / 2 - 0.08, width / 2 - 0.08
        panel(b, "base", (-ix, -iy, h - top_t - 0.08), (ix, -iy + 0.02, h - top_t + 0.001), leg_m, WOOD)
        panel(b, "base", (-ix, iy - 0.02, h - top_t - 0.08), (ix, iy, h - top_t + 0.001), leg_m, WOOD)
        legs(b, "base", leg_m, WOOD, xs=(-ix, ix), ys=(-iy, iy), z0=0.0, z1=h - top_t + 0.001,
             r=b.param("leg_radius", 0.022, 0.035), square=bool(b.rng.integers(2)))
    return None


def chair(b: AssetBuilder) -> float | None:
    wood = b.material("wood", pick_color(b, WOODS), roughness=0.5)
    seat_m = b.material("seat", pick_color(b, WOODS + FABRICS), roughness=0.7)
    sh = b.param("seat_height", 0.43, 0.48)
    sw = b.param("seat_width", 0.4, 0.48)
    sd = b.param("seat_depth", 0.4, 0.48)
    bh = b.param("back_height", 0.8, 0.95)
    st = 0.03
    r = b.param("leg_radius", 0.015, 0.022)
    panel(b, "base", (-sd / 2, -sw / 2, sh - st), (sd / 2, sw / 2, sh), seat_m, WOOD)
    b.surface(sh, (-sd / 2 + 0.04, -sw / 2), (sd / 2, sw / 2))
    ix, iy = sd / 2 - r - 0.01, sw / 2 - r - 0.01
    legs(b, "base", wood, WOOD, xs=(ix,), ys=(-iy, iy), z0=0.0, z1=sh - st + 0.001, r=r, square=True)
    for y in (-iy, iy):
        panel(b, "base", (-ix - r, y - r, 0.0), (-ix + r, y + r, bh), wood, WOOD)
    slats = int(b.choice("slats", [1, 2, 3]))
    for i in range(slats):
        z = bh - 0.05 - i * 0.12
        panel(b, "base", (-ix - r * 0.8, -iy + r, z - 0.06), (-ix + r * 0.8, iy - r, z), wood, WOOD)
    if b.choice("stretchers", [False, True]):
        for y in (-iy, iy):
            panel(b, "base", (-ix, y - r * 0.6, 0.15), (ix, y + r * 0.6, 0.18), wood, WOOD)
    return None


def rug(b: AssetBuilder) -> float:
    c = b.material("rug", pick_color(b, FABRICS, 0.08), roughness=1.0)
    border = b.material("border", pick_color(b, FABRICS, 0.08), roughness=1.0)
    length = b.param("length", 1.2, 3.0)
    width = b.param("width", 0.8, min(2.2, length))
    t = b.param("thickness", 0.006, 0.014)
    if b.choice("round", [False, False, True]):
        b.add("base", g.cylinder(0.5, t, (0, 0, t / 2), n=64).scale((length, width, 1)), c, density=300.0)
        b.add("base", g.cylinder(0.5, t * 1.1, (0, 0, t * 0.55), n=64, radius_top=0.5).scale(
            (length * 0.8, width * 0.8, 1)), border, density=300.0)
    else:
        panel(b, "base", (-length / 2, -width / 2, 0), (length / 2, width / 2, t), c, 300.0)
        panel(b, "base", (-length / 2 + 0.1, -width / 2 + 0.1, 0.001), (length / 2 - 0.1, width / 2 - 0.1,
                                                                        t * 1.1),
              border, 300.0)
    return float(length * width * b.param("areal_density", 1.2, 3.0))


def floor_lamp(b: AssetBuilder) -> float | None:
    metal = b.material("metal", pick_color(b, METALS), roughness=0.35, metallic=1.0)
    shade = b.material("shade", pick_color(b, [(0.95, 0.92, 0.85), (0.85, 0.82, 0.75), (0.3, 0.3, 0.32)]),
                       roughness=0.9)
    rb = b.param("base_radius", 0.12, 0.18)
    hp = b.param("height", 1.4, 1.8)
    rs_bot = b.param("shade_bottom_radius", 0.15, 0.25)
    rs_top = rs_bot * b.param("shade_taper", 0.55, 0.9)
    hs = b.param("shade_height", 0.2, 0.32)
    b.add("base", g.cylinder(rb, 0.025, (0, 0, 0.0125), n=40, radius_top=rb * 0.92), metal, density=STEEL)
    b.add("base", g.cylinder(0.012, hp - hs * 0.5, (0, 0, (hp - hs * 0.5) / 2 + 0.02), n=16), metal,
          density=STEEL)
    z0 = hp - hs
    wall = 0.004
    prof = [(rs_bot, z0), (rs_top, hp), (rs_top - wall, hp), (rs_bot - wall, z0)]
    sh = g.lathe(prof, n=40)
    b.add("base", sh, shade, density=400.0, collision=[g.hull([sh])])
    b.add("base", g.cylinder(0.02, 0.06, (0, 0, z0 + hs * 0.45), n=16), shade, density=800.0,
          collision="none")
    zk = z0 + hs * 0.3                                     # three spokes hold the shade on the pole
    rk = rs_bot + (rs_top - rs_bot) * 0.3 - wall / 2
    for k in range(3):
        spoke = g.box((rk, 0.004, 0.004), (rk / 2, 0, zk)).rotate((0, 0, 120.0 * k))
        b.add("base", spoke, metal, density=STEEL, collision="none")
    return b.param("mass", 4.0, 9.0)


def _front_panels(b: AssetBuilder, w: float, d: float, z0: float, z1: float, ncols: int, rows: int,
                  body: str, front: str, handle: str, kinds: list[str]) -> None:
    """Fill a carcass front with a grid of drawers/doors; kinds[i] in {drawer, door_left, door_right}."""
    t = 0.018
    col_w = (w - 2 * t) / ncols
    row_h = (z1 - z0) / rows
    idx = 0
    for c in range(ncols):
        y0 = -w / 2 + t + c * col_w
        for r in range(rows):
            zz0 = z0 + r * row_h
            kind = kinds[idx]
            name = f"{kind.split('_')[0]}_{idx}"
            if kind == "drawer":
                drawer(b, name, parent="base", body_mat=body, front_mat=front, handle_mat=handle,
                       density=WOOD,
                       x_front=d / 2, depth=d - t - 0.04, y0=y0, y1=y0 + col_w, z0=zz0, z1=zz0 + row_h,
                       inner_y0=y0 + (0.008 if c > 0 else 0.0), inner_y1=y0 + col_w - (0.008 if c < ncols - 1 else 0.0),
                       inner_z0=zz0 + (0.008 if r > 0 else 0.0))
            else:
                hinged_door(b, name, parent="base", mat=front, handle_mat=handle, density=WOOD, x_front=d / 2,
                            y0=y0, y1=y0 + col_w, z0=zz0, z1=zz0 + row_h, hinge=kind.split("_")[1])
            idx += 1


def _dividers(b: AssetBuilder, mat: str, w: float, d: float, z0: float, z1: float, ncols: int,
              rows: int) -> None:
    t = 0.018
    col_w = (w - 2 * t) / ncols
    for c in range(1, ncols):
        y = -w / 2 + t + c * col_w
        panel(b, "base", (-d / 2 + t, y - 0.008, z0), (d / 2, y + 0.008, z1), mat, WOOD)
    for r in range(1, rows):
        z = z0 + r * (z1 - z0) / rows
        panel(b, "base", (-d / 2 + t, -w / 2 + t, z - 0.008), (d / 2, w / 2 - t, z + 0.008), mat, WOOD)


def _storage(b: AssetBuilder, *, w: float, d: float, h: float, plinth: float, ncols: int, rows: int,
             kinds: list[str], mass: float) -> float:
    body = b.material("body", pick_color(b, WOODS), roughness=0.55)
    front = b.material("front", pick_color(b, WOODS), roughness=0.5)
    handle = b.material("handle", pick_color(b, METALS), roughness=0.3, metallic=1.0)
    t = 0.018
    carcass(b, "base", body, WOOD, w=w, d=d, z0=plinth, z1=h, t=t)
    if plinth > 0:
        panel(b, "base", (-d / 2 + 0.03, -w / 2 + 0.01, 0.0), (d / 2 - 0.03, w / 2 - 0.01, plinth + 0.001),
              body, WOOD)
    b.surface(h, (-d / 2, -w / 2), (d / 2, w / 2))
    z0, z1 = plinth + t, h - t
    horizontal_dividers = all(k == "drawer" for k in kinds)
    _dividers(b, body, w, d, z0, z1, ncols, rows if horizontal_dividers else 1)
    _front_panels(b, w, d, z0, z1, ncols, rows, body, front, handle, kinds)
    return mass


def nightstand(b: AssetBuilder) -> float:
    w, d, h = b.param("width", 0.4, 0.55), b.param("depth", 0.35, 0.45), b.param("height", 0.5, 0.65)
    rows = int(b.choice("drawers", [1, 2, 2, 3]))
    return _storage(b, w=w, d=d, h=h, plinth=b.param("plinth", 0.04, 0.1), ncols=1, rows=rows,
                    kinds=["drawer"] * rows, mass=b.param("mass", 9.0, 18.0))


def dresser(b: AssetBuilder) -> float:
    w, d, h = b.param("width", 0.8, 1.4), b.param("depth", 0.45, 0.55), b.param("height", 0.75, 1.0)
    rows = int(b.choice("rows", [3, 4]))
    cols = 1 if w < 0.95 else 2
    return _storage(b, w=w, d=d, h=h, plinth=b.param("plinth", 0.05, 0.1), ncols=cols, rows=rows,
                    kinds=["drawer"] * rows * cols, mass=b.param("mass", 35.0, 60.0) * w)


def cabinet(b: AssetBuilder) -> float:
    w, d, h = b.param("width", 0.4, 0.9), b.param("depth", 0.45, 0.6), b.param("height", 0.72, 0.9)
    rows = int(b.choice("drawers", [2, 3, 4]))
    return _storage(b, w=w, d=d, h=h, plinth=b.param("plinth", 0.08, 0.12), ncols=1, rows=rows,
                    kinds=["drawer"] * rows, mass=b.param("mass", 18.0, 35.0) * w / 0.6)


def _hanging(b: AssetBuilder, w: float, d: float, h: float, plinth: float, doors: int, mass: float) -> float:
    body = b.material("body", pick_color(b, WOODS), roughness=0.55)
    front = b.material("front", pick_color(b, WOODS), roughness=0.5)
    handle = b.material("handle", pick_color(b, METALS), roughness=0.3, metallic=1.0)
    t = 0.018
    carcass(b, "base", body, WOOD, w=w, d=d, z0=plinth, z1=h, t=t)
    panel(b, "base", (-d / 2 + 0.03, -w / 2 + 0.01, 0.0), (d / 2 - 0.03, w / 2 - 0.01, plinth + 0.001), body,
          WOOD)
    zs = h - t - 0.3
    panel(b, "base", (-d / 2 + t, -w / 2 + t, zs), (d / 2 - 0.01, w / 2 - t, zs + t), body, WOOD)
    b.surface(zs + t, (-d / 2 + t, -w / 2 + t), (d / 2 - 0.01, w / 2 - t), inside=True,
              clear_height=h - 2 * t - zs)
    b.add("base", g.cylinder(0.012, w - 2 * t + 0.004, (0, 0, zs - 0.06), axis="y", n=16),
          handle, density=STEEL)
    dw = (w - 2 * t) / doors
    for i in range(doors):
        y0 = -w / 2 + t + i * dw
        hinge = "left" if i < doors / 2 else "right"   # never two hinges on one divider (handles would meet)
        hinged_door(b, f"door_{i}", parent="base", mat=front, handle_mat=handle, density=WOOD, x_front=d / 2,
                    y0=y0 - (t if i == 0 else 0), y1=y0 + dw + (t if i == doors - 1 else 0), z0=plinth,
                    z1=h, hinge=hinge, handle_len=0.3, handle_z=1.05, effort=60.0)
    return mass


LOW_RAIL_RADIUS = 0.008  # the wardrobe's lower hanging rail (a 16 mm steel tube) [m]


def wardrobe(b: AssetBuilder) -> float:
    """A two-door wardrobe: a shelf with a hanging rail under it (1.4-1.7 m high) and a lower rail
    (param ``low_rail``: its axis 0.95-1.1 m above the floor, at mid depth, x = 0, across the width;
    a double-hang section, where the mobile Franka reaches a hanger's hook over it)."""
    w, d, h = b.param("width", 0.8, 1.25), b.param("depth", 0.55, 0.62), b.param("height", 1.8, 2.1)
    mass = _hanging(b, w, d, h, b.param("plinth", 0.06, 0.12), 2, b.param("mass", 55.0, 90.0) * w)
    z = b.param("low_rail", 0.95, 1.1)   # drawn last: the other parameters stay as they were
    t = 0.018
    b.add("base", g.cylinder(LOW_RAIL_RADIUS, w - 2 * t + 0.004, (0, 0, z), axis="y", n=16), "handle",
          density=STEEL)
    return mass


def closet(b: AssetBuilder) -> float:
    doors = int(b.choice("doors", [2, 3, 4]))
    w = b.param("door_width", 0.45, 0.6) * doors
    d, h = b.param("depth", 0.55, 0.65), b.param("height", 2.0, 2.4)
    return _hanging(b, w, d, h, b.param("plinth", 0.05, 0.1), doors, b.param("mass", 50.0, 80.0) * w)


def kitchen_counter(b: AssetBuilder) -> float:
    """A run of base cabinets (doors + a drawer column) under a countertop with a sunk sink and faucet."""
    body = b.material("body", pick_color(b, WOODS), roughness=0.55)
    front = b.material("front", pick_color(b, WOODS), roughness=0.45)
    handle = b.material("handle", pick_color(b, METALS), roughness=0.3, metallic=1.0)
    top_m = b.material("countertop", pick_color(b, [(0.85, 0.85, 0.83), (0.2, 0.2, 0.22), (0.6, 0.55, 0.5)]),
                       roughness=0.3)
    steel = b.material("steel", (0.78, 0.78, 0.8), roughness=0.25, metallic=1.0)
    units = int(b.choice("units", [3, 4, 5]))
    uw = b.param("unit_width", 0.5, 0.62)
    w = units * uw
    d = b.param("depth", 0.58, 0.62)
    h = b.param("height", 0.88, 0.92)
    top_t = 0.035
    plinth = 0.1
    t = 0.018
    hc = h - top_t
    carcass(b, "base", body, WOOD, w=w, d=d, z0=plinth, z1=hc, t=t, top=False)
    panel(b, "base", (-d / 2 + 0.05, -w / 2 + 0.01, 0.0), (d / 2 - 0.05, w / 2 - 0.01, plinth + 0.001), body,
          WOOD)
    # countertop with a hole for the sink basin
    sink_unit = int(b.choice("sink_unit", list(range(units - 1))))
    sy = -w / 2 + (sink_unit + 0.5) * uw
    bw, bd, bh = uw - 0.12, b.param("basin_depth_x", 0.36, 0.42), b.param("basin_height", 0.15, 0.2)
    bx = 0.0
    ct0, ct1 = hc, h
    hole = (bx - bd / 2, sy - bw / 2, bx + bd / 2, sy + bw / 2)
    cut = (hole[0] + 0.002, hole[1] + 0.002, hole[2] - 0.002, hole[3] - 0.002)   # top overlaps the basin rim
    for lo, hi in (((-d / 2, -w / 2, ct0), (d / 2 + 0.02, cut[1], ct1)),
                   ((-d / 2, cut[3], ct0), (d / 2 + 0.02, w / 2, ct1)),
                   ((-d / 2, cut[1], ct0), (cut[0], cut[3], ct1)),
                   ((cut[2], cut[1], ct0), (d / 2 + 0.02, cut[3], ct1))):
        panel(b, "base", lo, hi, top_m, 2400.0)
    b.surface(ct1, (-d / 2, -w / 2), (d / 2 + 0.02, hole[1] - 0.05))
    b.surface(ct1, (-d / 2, hole[3] + 0.01), (d / 2 + 0.02, w / 2))
    wt = 0.006
    zb = ct1 - bh
    panel(b, "base", (hole[0], hole[1], zb), (hole[2], hole[3], zb + wt), steel, STEEL)
    panel(b, "base", (hole[0], hole[1], zb), (hole[0] + wt, hole[3], ct1), steel, STEEL)
    panel(b, "base", (hole[2] - wt, hole[1], zb), (hole[2], hole[3], ct1), steel, STEEL)
    panel(b, "base", (hole[0], hole[1], zb), (hole[2], hole[1] + wt, ct1), steel, STEEL)
    panel(b, "base", (hole[0], hole[3] - wt, zb), (hole[2], hole[3], ct1), steel, STEEL)
    # faucet: a post and a spout arching over the basin
    fx = hole[0] - 0.05
    b.add("base", g.cylinder(0.018, 0.252, (fx, sy, ct1 + 0.124), n=16), steel, density=STEEL)
    spout = g.tube_path(np.array([[fx, sy, ct1 + 0.24], [fx + 0.08, sy, ct1 + 0.27], [fx + 0.17, sy,
                                                                                      ct1 + 0.2]]),
                        0.011, n=12)
    for s in spout:
        b.add("base", s, steel, density=STEEL)
    # fronts: a drawer column at one end, door pairs elsewhere
    z0, z1 = plinth, hc
    for u in range(units):
        y0 = -w / 2 + t + u * (w - 2 * t) / units
        y1 = y0 + (w - 2 * t) / units
        if u > 0:
            panel(b, "base", (-d / 2 + t, y0 - 0.008, plinth), (d / 2, y0 + 0.008, hc), body, WOOD)
        if u == units - 1 and u != sink_unit:
            rows = 3
            for r in range(rows):
                zz0 = z0 + r * (z1 - z0) / rows
                if r > 0:
                    panel(b, "base", (-d / 2 + t, y0 + 0.008, zz0 - 0.008), (d / 2, y1, zz0 + 0.008), body,
                          WOOD)
                drawer(b, f"drawer_{u}_{r}", parent="base", body_mat=body, front_mat=front, handle_mat=handle,
                       density=WOOD, x_front=d / 2, depth=d - t - 0.04, y0=y0, y1=y1, z0=zz0,
                       z1=zz0 + (z1 - z0) / rows, inner_y0=y0 + 0.008, inner_y1=y1,
                       inner_z0=zz0 + (0.008 if r > 0 else t))
        else:
            hinged_door(b, f"door_{u}", parent="base", mat=front, handle_mat=handle, density=WOOD,
                        x_front=d / 2,
                        y0=y0, y1=y1, z0=z0, z1=z1, hinge="left",
                        handle_len=0.16, handle_z=z1 - 0.1)
    return b.param("mass", 45.0, 60.0) * w
