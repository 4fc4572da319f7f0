"""The open containers of the household tasks, checked on their collider pieces (what simulation sees):
a trash can is closed at the bottom and around, open on top, with a free cavity; a dish rack's slots
take a plate of the catalog on its edge."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from asset_catalog.default_catalog import generate_default_assets
from asset_catalog.generators import GENERATORS_BY_CATEGORY


@functools.cache
def _pieces(category: str):
    """Per variant: (asset, list of (vertices, hull equations)) of its single link's collider pieces."""
    out = []
    for a in generate_default_assets(variants_per_category=5, seed=0, categories=[category]):
        (link,) = a.model.links
        pieces = [(c.vertices, ConvexHull(c.vertices).equations) for c in link.collision_source]
        out.append((a, pieces))
    return out


def _inside_any(points: np.ndarray, pieces) -> np.ndarray:
    """Which points lie inside (or on) at least one convex piece."""
    points = np.atleast_2d(points)
    hit = np.zeros(len(points), bool)
    for _, eq in pieces:
        hit |= np.all(points @ eq[:, :3].T + eq[:, 3] <= 1e-9, axis=1)
    return hit


@pytest.mark.parametrize("variant", range(5))
def test_trash_can_is_open_on_top_closed_below_and_around(variant):
    a, pieces = _pieces("trash_can")[variant]
    pts = np.vstack([v for v, _ in pieces])
    lo, hi = pts.min(0), pts.max(0)
    h = hi[2]
    # the bottom: solid under the centre
    assert _inside_any(np.array([0.0, 0.0, 0.003]), pieces).all(), f"{a.model.name}: no bottom"
    bottom_top = max(v[:, 2].max() for v, _ in pieces if v[:, 2].max() < 0.5 * h)
    # the cavity: a column of +-3 cm around the axis, from just above the bottom to above the rim, is free
    zs = np.linspace(bottom_top + 0.002, h + 0.05, 25)
    g = np.array([(x, y, z) for x in (-0.03, 0.0, 0.03) for y in (-0.03, 0.0, 0.03) for z in zs])
    assert not _inside_any(g, pieces).any(), f"{a.model.name}: its cavity is blocked"
    # the walls: every horizontal band 4 mm wide from the axis outwards meets a collider, at a third and two
    # thirds of the height (pieces are shrunk by a fraction of a millimetre, so seams are hairline gaps)
    for z in (h / 3, 2 * h / 3):
        for ang in np.linspace(0, 2 * np.pi, 48, endpoint=False):
            d, side = np.array([np.cos(ang), np.sin(ang), 0.0]), np.array([-np.sin(ang), np.cos(ang), 0.0])
            band = np.vstack([np.outer(np.linspace(0.0, 0.6, 600), d) + off * side + [0.0, 0.0, z]
                              for off in (-0.002, 0.0, 0.002)])
            assert _inside_any(band, pieces).any(), f"{a.model.name}: open side at {np.degrees(ang):.0f} deg"
    # a can of the catalog fits through the opening (the rim is wider than the largest can)
    can = GENERATORS_BY_CATEGORY["can"].size_max
    assert min(hi[0] - lo[0], hi[1] - lo[1]) - 0.02 > max(can[:2]) * 2


@pytest.mark.parametrize("variant", range(5))
def test_dish_rack_slots_hold_a_catalog_plate_on_edge(variant):
    a, pieces = _pieces("dish_rack")[variant]
    pts = np.vstack([v for v, _ in pieces])
    lo, hi = pts.min(0), pts.max(0)
    tray_top = max(v[:, 2].max() for v, _ in pieces if v[:, 2].max() < hi[2] - 0.02)
    tines = [v for v, _ in pieces if v[:, 2].max() > tray_top + 0.02]
    rows: dict[float, list[tuple[float, float]]] = {}
    for v in tines:
        y_span = (float(v[:, 1].min()), float(v[:, 1].max()))
        rows.setdefault(round(float(v[:, 0].mean()), 3), []).append(y_span)
    assert len(rows) == 2 and len({len(r) for r in rows.values()}) == 1, f"{a.model.name}: rows {rows.keys()}"
    plate_min, plate_max = GENERATORS_BY_CATEGORY["plate"].size_min, GENERATORS_BY_CATEGORY["plate"].size_max
    xs = sorted(rows)
    # a plate on edge rests across both rows of tines, inside the tray
    assert xs[1] - xs[0] < plate_min[0] - 0.05
    assert xs[0] > lo[0] and xs[1] < hi[0]
    for r in rows.values():
        r.sort()
        gaps = [r[i + 1][0] - r[i][1] for i in range(len(r) - 1)]
        assert len(gaps) >= 5, f"{a.model.name}: only {len(gaps)} slots"
        # the thickest plate of the catalog (its height, rim to foot) passes between two tines
        assert min(gaps) > plate_max[2] + 0.01, f"{a.model.name}: slots {np.round(gaps, 4)}"
    # the slots are free from the tray bottom up: a plate's edge reaches the bottom between two tines
    r = rows[xs[0]]
    y = (r[0][1] + r[1][0]) / 2
    col = np.array([(x, y, z) for x in np.linspace(lo[0] + 0.01, hi[0] - 0.01, 15)
                    for z in np.linspace(tray_top * 0.3 + 0.003, hi[2] + 0.05, 20)])
    col = col[col[:, 2] > 0.005]
    assert not _inside_any(col, pieces).any(), f"{a.model.name}: a slot is blocked"
