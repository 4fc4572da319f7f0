"""Mass properties of the articulated loaders (URDF, MJCF): principal axes, the parallel-axis rule,
plausibility of source-given masses and inertias, and mass spread over a convex hull.
"""

from __future__ import annotations

import logging

import numpy as np

from asset_catalog.asset_model import MassProperties
from stages.loaders._geom import matrix_quat, quat_matrix

log = logging.getLogger(__name__)


# ------------------------------------------------------------------------------------------ inertia


def mass_properties(mass: float, com, tensor: np.ndarray) -> MassProperties:
    """MassProperties from a mass [kg], centre of mass (3,) [m] and a 3x3 inertia tensor about the
    centre of mass in the link frame [kg m^2] (principal axes by eigen-decomposition)."""
    tensor = 0.5 * (np.asarray(tensor, float) + np.asarray(tensor, float).T)
    vals, vecs = np.linalg.eigh(tensor)
    if np.linalg.det(vecs) < 0:
        vecs[:, 2] = -vecs[:, 2]
    return MassProperties(mass=float(mass), center_of_mass=tuple(float(c) for c in com),
                          diagonal_inertia=tuple(float(max(v, 0.0)) for v in vals),
                          principal_axes=matrix_quat(vecs))


def tensor_of(mp: MassProperties) -> np.ndarray:
    """The 3x3 inertia tensor about the centre of mass, in the link frame [kg m^2]."""
    r = quat_matrix(mp.principal_axes)
    return r @ np.diag(mp.diagonal_inertia) @ r.T


def combine_mass(parts: list[tuple[float, np.ndarray, np.ndarray]]) -> tuple[float, np.ndarray, np.ndarray]:
    """Combine (mass, com (3,), tensor about com (3,3)) in one frame -> total, by the parallel-axis rule."""
    total = sum(m for m, _, _ in parts)
    if total <= 0:
        return 0.0, np.zeros(3), np.zeros((3, 3))
    com = sum(m * np.asarray(c) for m, c, _ in parts) / total
    tensor = np.zeros((3, 3))
    for m, c, i in parts:
        d = np.asarray(c) - com
        tensor += i + m * (np.dot(d, d) * np.eye(3) - np.outer(d, d))
    return total, com, tensor


def implausible_inertia(mp: MassProperties, points: np.ndarray | None) -> str | None:
    """Why the mass properties are physically implausible, or None.

    Checks: finite, mass > 0, principal moments > 0 obeying the triangle inequality (1 % slack), and,
    where the link has geometry ``points`` (K, 3) [m], no moment larger than 4 x mass x (largest distance
    from the centre of mass to the geometry)^2 (placeholder inertias such as 1 kg m^2 on a 20 cm drawer)."""
    vals = np.array(mp.diagonal_inertia)
    if not (np.isfinite(mp.mass) and mp.mass > 0 and np.isfinite(vals).all()
            and np.isfinite(mp.center_of_mass).all()):
        return "non-finite or non-positive mass/inertia"
    if (vals <= 0).any():
        return f"non-positive principal inertia {tuple(vals)}"
    a, b, c = np.sort(vals)
    if a + b < c * 0.99:
        return f"principal inertia {tuple(vals)} violates the triangle inequality"
    if points is not None and len(points):
        r2 = float(np.max(np.sum((points - np.asarray(mp.center_of_mass)) ** 2, axis=1)))
        if vals.max() > 4.0 * mp.mass * max(r2, 1e-8):
            return (f"inertia {vals.max():.3g} kg m^2 too large for mass {mp.mass:.3g} kg "
                    f"within {np.sqrt(r2):.3g} m")
    return None


def hull_mass_properties(points: np.ndarray, mass: float, com) -> MassProperties | None:
    """Mass properties of ``mass`` [kg] spread uniformly over the convex hull of ``points`` (K, 3) [m],
    expressed about ``com`` (3,) [m] (the source's centre of mass): used where a source gives a plausible
    mass but an implausible inertia. None if the points span no volume."""
    import trimesh

    try:
        hull = trimesh.convex.convex_hull(np.asarray(points, float))
    except Exception as e:  # qhull raises its own error types for flat or degenerate input
        log.debug("no hull for inertia: %s", e)
        return None
    if not hull.is_volume or hull.volume <= 1e-12:
        return None
    tensor = np.asarray(hull.moment_inertia, float) * (mass / hull.volume)   # about the hull's centroid
    d = np.asarray(com, float) - np.asarray(hull.center_mass, float)
    tensor = tensor + mass * (np.dot(d, d) * np.eye(3) - np.outer(d, d))
    return mass_properties(mass, com, tensor)


def judge_masses(model):
    """The AssetModel with each source-given mass judged against its link's geometry (in final units).

    Kept as is when plausible. Dropped (mass None, mass_from_source False: the annotate stage computes it)
    when non-finite or non-positive, or when mass / (convex-hull volume of the link's geometry) exceeds
    3 x the density of the annotated material (placeholder masses such as 1 kg on a 7 cm fruit; a hull
    only over-estimates the solid volume, so heavier is impossible). With a plausible mass but an
    implausible inertia (see ``implausible_inertia``), the mass and centre of mass are kept and the inertia
    is that of the mass spread over the geometry's hull.
    """
    from dataclasses import replace

    from asset_catalog.materials import MATERIAL_RULES, MaterialClass

    density = MATERIAL_RULES[MaterialClass(model.annotation.material)].density
    links = []
    for lk in model.links:
        if lk.mass is None or not lk.mass_from_source:
            links.append(lk)
            continue
        parts = list(lk.collision_source or ()) or list(lk.visuals)
        pts = np.vstack([p.vertices for p in parts]) if parts else None
        mp, why = lk.mass, None
        if not (np.isfinite(mp.mass) and mp.mass > 0 and np.isfinite(mp.center_of_mass).all()):
            mp, why = None, f"mass {mp.mass} is not positive and finite"
        elif pts is not None:
            vol = _hull_volume(pts)
            if vol > 0 and mp.mass / vol > 3.0 * density:
                mp, why = None, (f"mass {mp.mass:.4g} kg in a hull of {vol:.3g} m^3 is denser than 3 x "
                                 f"{model.annotation.material} ({density:.0f} kg/m^3)")
        if mp is None:
            log.warning("%s: link %r: source mass ignored (%s); it will be computed",
                        model.name, lk.name, why)
            links.append(replace(lk, mass=None, mass_from_source=False))
            continue
        why = implausible_inertia(mp, pts)
        if why is not None:
            hull = hull_mass_properties(pts, mp.mass, mp.center_of_mass) if pts is not None else None
            if hull is None:
                log.warning("%s: link %r: source mass ignored (%s)", model.name, lk.name, why)
                links.append(replace(lk, mass=None, mass_from_source=False))
                continue
            log.warning("%s: link %r: %s; kept mass %.4g kg, inertia from the geometry's hull",
                        model.name, lk.name, why, mp.mass)
            mp = hull
        links.append(replace(lk, mass=mp))
    return replace(model, links=tuple(links))


def _hull_volume(points: np.ndarray) -> float:
    """Volume [m^3] of the convex hull of (K, 3) points; 0 for flat or degenerate sets."""
    from scipy.spatial import ConvexHull, QhullError

    pts = np.asarray(points, float)
    if len(pts) < 4096:
        pts = np.unique(np.round(pts, 9), axis=0)
    try:
        return float(ConvexHull(pts).volume)
    except (QhullError, ValueError) as e:
        log.debug("no hull: %s", e)
        return 0.0
