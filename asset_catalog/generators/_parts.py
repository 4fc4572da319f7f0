"""Reusable furniture parts: panels, carcasses, legs, bar handles, knobs, drawers, hinged doors.

All coordinates are in the asset's root frame [m]: Z up, +X front, the footprint centred on the origin.
A carcass's front plane is x = +depth/2; doors and drawer fronts sit in front of it.
"""

from __future__ import annotations

import numpy as np

import asset_catalog.generators._geom as g
from asset_catalog.generators._builder import AssetBuilder

WOODS = [(0.55, 0.38, 0.22), (0.72, 0.55, 0.36), (0.36, 0.23, 0.13), (0.85, 0.74, 0.56), (0.93, 0.92, 0.89),
         (0.25, 0.25, 0.27), (0.62, 0.45, 0.30)]
FABRICS = [(0.45, 0.50, 0.60), (0.62, 0.58, 0.52), (0.30, 0.35, 0.32), (0.70, 0.30, 0.25), (0.22, 0.24, 0.35),
           (0.80, 0.78, 0.72), (0.50, 0.42, 0.55), (0.35, 0.45, 0.40)]
METALS = [(0.75, 0.75, 0.77), (0.20, 0.20, 0.21), (0.80, 0.70, 0.45), (0.55, 0.56, 0.58)]
APPLIANCE = [(0.93, 0.93, 0.92), (0.72, 0.73, 0.74), (0.12, 0.12, 0.13), (0.82, 0.80, 0.76)]
PLASTICS = [(0.85, 0.20, 0.18), (0.15, 0.45, 0.80), (0.20, 0.65, 0.30), (0.95, 0.75, 0.15), (0.92, 0.92,
                                                                                             0.92),
            (0.10, 0.10, 0.10), (0.60, 0.30, 0.70)]

GAP = 0.003          # clearance between moving parts and their frame [m]
HANDLE_MIN_CLEARANCE = 0.025   # free space behind a furniture bar handle [m]


def jitter(rng: np.random.Generator, color, amount: float = 0.04) -> tuple[float, float, float]:
    c = np.asarray(color) + rng.uniform(-amount, amount, 3)
    return tuple(float(x) for x in np.clip(c, 0.02, 0.98))


def pick_color(b: AssetBuilder, palette, amount: float = 0.04):
    return jitter(b.rng, palette[int(b.rng.integers(len(palette)))], amount)


def panel(b: AssetBuilder, link: str, lo, hi, mat: str, density: float) -> None:
    """A box panel from corner ``lo`` to ``hi``, its own convex collider."""
    b.add(link, g.box_between(lo, hi), mat, density=density)


def carcass(b: AssetBuilder, link: str, mat: str, density: float, *, w: float, d: float, z0: float, z1: float,
            t: float, top: bool = True) -> None:
    """An open-front box of 5 panels (bottom, top, left, right, back) of thickness ``t`` between
    heights z0 and z1, footprint d (x) by w (y). Its interior stays open for drawers and doors."""
    x0, x1, y0, y1 = -d / 2, d / 2, -w / 2, w / 2
    panel(b, link, (x0, y0, z0), (x1, y0 + t, z1), mat, density)
    panel(b, link, (x0, y1 - t, z0), (x1, y1, z1), mat, density)
    panel(b, link, (x0, y0 + t, z0), (x0 + t, y1 - t, z1), mat, density)
    panel(b, link, (x0 + t, y0 + t, z0), (x1, y1 - t, z0 + t), mat, density)
    if top:
        panel(b, link, (x0 + t, y0 + t, z1 - t), (x1, y1 - t, z1), mat, density)


def bar_handle(b: AssetBuilder, link: str, mat: str, *, x_surface: float, center_yz, along: str,
               length: float,
               diameter: float, clearance: float, density: float = 7800.0) -> None:
    """A bar pull on a surface facing +X at ``x_surface``: a round bar of ``diameter`` [m] and
    ``length`` [m] along ``along`` ("y" or "z"), held ``clearance`` [m] off the surface by two posts."""
    y, z = center_yz
    r = diameter / 2
    xb = x_surface + clearance + r
    bar = g.cylinder(r, length, (xb, y, z), axis=along, n=16)
    post_r = min(r * 0.8, 0.006)
    posts = []
    for s in (-1, 1):
        off = s * (length / 2 - max(r, 0.012))
        py, pz = (y + off, z) if along == "y" else (y, z + off)
        # posts reach 2 mm into the surface so the handle and its door are one solid
        posts.append(g.cylinder(post_r, clearance + r + 0.002, (x_surface + (clearance + r) / 2 - 0.001, py, pz),
                                axis="x", n=12))
    b.add(link, bar, mat, density=density)
    for p in posts:
        b.add(link, p, mat, density=density)
    axis = (0.0, 1.0, 0.0) if along == "y" else (0.0, 0.0, 1.0)
    b.handle(link, (xb, y, z), diameter, clearance, axis)


def legs(b: AssetBuilder, link: str, mat: str, density: float, *, xs, ys, z0: float, z1: float, r: float,
         square: bool = False, taper: float = 1.0) -> None:
    """One leg at every (x, y) of xs x ys, from z0 to z1, radius (or half-width) r [m]."""
    for x in xs:
        for y in ys:
            if square:
                b.add(link, g.box((2 * r, 2 * r, z1 - z0), (x, y, (z0 + z1) / 2)), mat, density=density)
            else:
                leg = g.cylinder(r * taper, z1 - z0, (x, y, (z0 + z1) / 2), n=16, radius_top=r)
                b.add(link, leg, mat, density=density)


def drawer(b: AssetBuilder, name: str, *, parent: str, body_mat: str, front_mat: str, handle_mat: str,
           density: float, x_front: float, depth: float, y0: float, y1: float, z0: float, z1: float,
           inner_y0: float, inner_y1: float, inner_z0: float, t: float = 0.015) -> None:
    """A drawer sliding along +X: front plate covering y0..y1, z0..z1 at x_front, and an open box behind
    it (bottom, back, two sides) of ``depth`` [m] that fits inside inner_y0..inner_y1 above inner_z0.
    Travel is 75 % of the box depth; the handle is a horizontal bar."""
    front_t = 0.018
    b.link(name, parent=parent, origin=(x_front, (y0 + y1) / 2, (z0 + z1) / 2), joint="prismatic",
           axis=(1, 0, 0), lower=0.0, upper=0.75 * depth, effort=60.0, velocity=0.5, damping=2.0,
           friction=0.5, role="drawer")
    panel(b, name, (x_front + GAP, y0 + GAP, z0 + GAP), (x_front + GAP + front_t, y1 - GAP, z1 - GAP),
          front_mat, density)
    by0, by1 = inner_y0 + GAP, inner_y1 - GAP
    bz0, bz1 = inner_z0 + GAP, min(z1 - 0.02, inner_z0 + (z1 - z0) * 0.8)
    bx0 = x_front - depth
    xf = x_front + GAP + 0.002   # the box reaches into the front plate, so the drawer is one solid
    panel(b, name, (bx0, by0, bz0), (xf, by1, bz0 + t), body_mat, density)
    panel(b, name, (bx0, by0, bz0 + t), (bx0 + t, by1, bz1), body_mat, density)
    panel(b, name, (bx0 + t, by0, bz0 + t), (xf, by0 + t, bz1), body_mat, density)
    panel(b, name, (bx0 + t, by1 - t, bz0 + t), (xf, by1, bz1), body_mat, density)
    length = float(np.clip((y1 - y0) * 0.4, 0.08, 0.3))
    bar_handle(b, name, handle_mat, x_surface=x_front + GAP + front_t, center_yz=((y0 + y1) / 2,
                                                                                  (z0 + z1) / 2),
               along="y", length=length, diameter=0.012, clearance=0.03)


def hinged_door(b: AssetBuilder, name: str, *, parent: str, mat: str, handle_mat: str, density: float,
                x_front: float, y0: float, y1: float, z0: float, z1: float, hinge: str, thickness: float = 0.018,
                upper: float = float(np.pi / 2), handle_len: float | None = None, handle_z: float | None = None,
                effort: float = 40.0, handle_diameter: float = 0.014, handle_clearance: float = 0.03,
                handle_inset: float = 0.05) -> None:
    """An overlay door in front of x_front covering y0..y1, z0..z1, hinged on its ``hinge`` side
    ("left" = -Y, "right" = +Y) about a vertical axis through its outer front corner; positive angle opens
    it outward (towards +X). Up to 90 degrees such a door never crosses its hinge line, so neighbouring
    doors and the carcass stay clear."""
    hy = y0 + GAP if hinge == "left" else y1 - GAP
    axis = (0, 0, -1) if hinge == "left" else (0, 0, 1)
    b.link(name, parent=parent, origin=(x_front + GAP + thickness, hy, (z0 + z1) / 2), joint="revolute",
           axis=axis,
           lower=0.0, upper=upper, effort=effort, velocity=1.5, damping=1.0, friction=0.3, role="door")
    panel(b, name, (x_front + GAP, y0 + GAP, z0 + GAP), (x_front + GAP + thickness, y1 - GAP, z1 - GAP), mat,
          density)
    hl = handle_len if handle_len is not None else float(np.clip((z1 - z0) * 0.3, 0.1, 0.4))
    hz = handle_z if handle_z is not None else (z0 + z1) / 2
    hz = float(np.clip(hz, z0 + hl / 2 + 0.02, z1 - hl / 2 - 0.02))
    hy_handle = (y1 - handle_inset) if hinge == "left" else (y0 + handle_inset)
    bar_handle(b, name, handle_mat, x_surface=x_front + GAP + thickness, center_yz=(hy_handle, hz), along="z",
               length=hl, diameter=handle_diameter, clearance=handle_clearance)


def knob(b: AssetBuilder, name: str, *, parent: str, mat: str, x_surface: float, y: float, z: float,
         radius: float, depth: float, upper: float = 4.7) -> None:
    """A rotary knob on a +X-facing panel: revolute about +X, 0..upper [rad]; a cylinder with a grip ridge."""
    b.link(name, parent=parent, origin=(x_surface, y, z), joint="revolute", axis=(1, 0, 0), lower=0.0,
           upper=upper, effort=2.0, velocity=3.0, damping=0.01, friction=0.02, role="knob")
    body = g.cylinder(radius, depth, (x_surface + 0.001 + depth / 2, y, z), axis="x", n=24)
    ridge = g.box((depth * 0.6, radius * 0.35, radius * 1.7), (x_surface + depth + depth * 0.3 - 0.001, y, z))
    b.add(name, body, mat, density=1100.0)
    b.add(name, ridge, mat, density=1100.0)
    b.handle(name, (x_surface + depth + 0.001, y, z), radius * 0.35, depth, (0.0, 0.0, 1.0), kind="knob")
