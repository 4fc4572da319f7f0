"""Where a placed asset touches its support, and whether its center of mass is over that contact.

An asset rests ``REST_GAP`` above the floor or a support surface of the asset below it (see
``stages.scene.solver``). Its contact with a support surface is not the outline of its whole base:
only the parts of its base that are over the surface carry load. A microwave on four feet whose two
right feet stand past the counter's end (or over the sink's hole) rests on its two left feet only,
and tips over their line when its center of mass is not above it, however much of the base's
outline lies over the counter. So the contact region is built per collider piece: each piece's own
base patch (its points within ``BASE_TOL`` of the asset's lowest point; convex, as the piece is)
clipped to each support surface polygon at that height, and the region is the convex hull of those
clipped patches (``contact_region``). Used by the rest proof (``stages.scene.rest``) and by the
placement of objects on surfaces (``stages.scene.solver``), so that no object is placed where it
would tip. Lengths [m], world frame.
"""

from __future__ import annotations

import numpy as np

from stages.scene.geom import convex_hull_2d, polygon_area, rot2

REST_GAP = 0.001      # [m] assets are placed this far above their support
BASE_TOL = 0.002      # [m] collider points this close to an asset's lowest point form its base
GAP_TOL = 2.0e-4      # [m] slack on the rest gap between a base and its support
REST_MARGIN = 0.005   # [m] the combined center of mass lies this far inside the contact region


def clip_convex(subject: np.ndarray, clip: np.ndarray) -> np.ndarray:
    """Intersection of two CCW convex polygons (K, 2) (Sutherland-Hodgman); (0, 2) if empty. A
    subject of one or two points (a point or edge contact) is clipped as such."""
    out = np.asarray(subject, dtype=np.float64)
    n = len(clip)
    for i in range(n):
        if len(out) == 0:
            break
        a, b = clip[i], clip[(i + 1) % n]
        e = b - a
        side = e[0] * (out[:, 1] - a[1]) - e[1] * (out[:, 0] - a[0])  # >= 0: inside (left of a->b)
        res = []
        for k in range(len(out)):
            p, q = out[k], out[(k + 1) % len(out)]
            sp, sq = side[k], side[(k + 1) % len(out)]
            if sp >= 0:
                res.append(p)
            if (sp >= 0) != (sq >= 0):
                t = sp / (sp - sq)
                res.append(p + t * (q - p))
        out = np.asarray(res, dtype=np.float64).reshape(-1, 2)
    return out


def signed_inside(pt: np.ndarray, poly: np.ndarray) -> float:
    """Distance of ``pt`` (2,) inside the CCW convex polygon ``poly`` [m] (negative: outside)."""
    e = np.roll(poly, -1, axis=0) - poly
    n = np.stack([-e[:, 1], e[:, 0]], axis=1)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    return float(np.min(np.einsum("kd,kd->k", pt[None] - poly, n)))


def contact_region(inst, sup, floor_top: float | None) -> tuple[np.ndarray | None, str | None]:
    """(contact region (K, 2) CCW, None), or (None, why there is none) of a placed instance
    (``stages.scene.solver._Inst``: world collider pieces, ``geo.moving``, placement) on ``sup``
    (the support's ``_Inst``; None: the floor, whose top is at ``floor_top`` [m], unbounded)."""
    low = min(float(p.lo[2]) for p in inst.pieces)
    if any(float(p.lo[2]) < low + BASE_TOL for p, mv in zip(inst.pieces, inst.geo.moving) if mv):
        return None, "a moving part touches the support"
    fixed = [p for p, mv in zip(inst.pieces, inst.geo.moving) if not mv]
    feet = [p.vertices[p.vertices[:, 2] < low + BASE_TOL][:, :2] for p in fixed]
    feet = [f for f in feet if len(f)]
    if sum(len(f) for f in feet) < 3:
        return None, "no flat base"
    if inst.p.support is None:
        top, region = floor_top, convex_hull_2d(np.vstack(feet))
    else:
        # each base patch clipped to every surface of the support at that height (coplanar cushions,
        # shelf boards); the region is the hull of what lies over a surface
        top, patches = None, []
        if sup is not None:
            hulls = [convex_hull_2d(f) for f in feet]
            for s in sup.geo.surfaces:
                z = sup.p.position[2] + s.z
                if abs(low - REST_GAP - z) <= GAP_TOL:
                    top = z
                    poly = s.polygon @ rot2(sup.p.yaw).T + np.asarray(sup.p.position[:2])
                    patches += [c for c in (clip_convex(h, poly) for h in hulls) if len(c)]
        region = convex_hull_2d(np.vstack(patches)) if patches else np.zeros((0, 2))
    if top is None or not (0.0 <= low - top <= REST_GAP + GAP_TOL):
        return None, "not resting on its support's surface"
    if len(region) < 3 or polygon_area(region) < 1e-8:
        return None, "no contact area"
    return region, None


def world_com(inst) -> np.ndarray:
    """(3,) center of mass of a placed instance, world [m] (its package's ``geo.com``)."""
    return np.asarray(inst.p.position) + np.append(rot2(inst.p.yaw) @ inst.geo.com[:2], inst.geo.com[2])


def tips_over(inst, sup, margin: float = REST_MARGIN) -> str | None:
    """Why an object placed on ``sup`` would not rest (its center of mass less than ``margin`` [m]
    inside its contact region, or no contact with a surface), or None: it rests, or that cannot be
    judged here (no authored mass, a moving part at its base: the settle check decides)."""
    if inst.geo.dynamic and not inst.geo.mass > 0:
        return None
    region, why = contact_region(inst, sup, None)
    if region is None:
        return why if why in ("no contact area", "no flat base") else None
    if signed_inside(world_com(inst)[:2], region) < margin:
        return f"would tip: center of mass not over its contact with {sup.p.record.category}"
    return None
