"""Collision stage: one hull for near-convex shapes, CoACD for concave ones (cavities stay open)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from asset_catalog.annotations import AssetAnnotation
from asset_catalog.asset_model import AssetModel, ColliderApprox, Link, MeshPart
from stages.collision import CollisionConfig, collider_kind, compute_colliders
from ingest_testutil import SHARED_RIGID_ANNOTATIONS, bowl_mesh, box_arrays, shelf_mesh

# A CoACD budget that keeps the CI tests to seconds; the defaults are exercised by the slow tests.
FAST = CollisionConfig(coacd_resolution=150, coacd_mcts_iterations=6, coacd_mcts_nodes=3,
                       max_hulls_per_piece=8)


def _model(vertices, faces, collider: str = "auto", material: str = "ceramic") -> AssetModel:
    ann = AssetAnnotation(id="thing", source="thing.obj", category="thing", collider=collider,
                          material=material)
    part = MeshPart(name="m", vertices=np.asarray(vertices, float), faces=np.asarray(faces, np.int64))
    return AssetModel(name="thing", annotation=ann, links=(Link(name="body", visuals=(part,)),))


def _inside_any(colliders, points: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """(N,) bool: point inside at least one convex collider (half-space test on its hull)."""
    from scipy.spatial import ConvexHull

    inside = np.zeros(len(points), dtype=bool)
    for c in colliders:
        eq = ConvexHull(c.vertices).equations
        inside |= (points @ eq[:, :3].T + eq[:, 3] <= tol).all(axis=1)
    return inside


def test_box_gets_one_hull_covering_it():
    v, f = box_arrays((0.2, 0.1, 0.05))
    m = compute_colliders(_model(v, f), CollisionConfig(), np.random.default_rng(0))
    link = m.links[0]
    assert link.collider_approx == ColliderApprox.HULL and len(link.colliders) == 1
    assert collider_kind(m) == "hull"
    hull = link.colliders[0]
    np.testing.assert_allclose(hull.vertices.min(0), v.min(0), atol=1e-9)
    np.testing.assert_allclose(hull.vertices.max(0), v.max(0), atol=1e-9)
    assert len(hull.vertices) == 8


def test_bowl_keeps_its_cavity_open_and_is_deterministic():
    bowl = bowl_mesh()
    assert bowl.is_watertight
    m1 = compute_colliders(_model(bowl.vertices, bowl.faces), FAST, np.random.default_rng(3))
    link = m1.links[0]
    assert link.collider_approx == ColliderApprox.DECOMPOSITION and collider_kind(m1) == "coacd"
    assert 2 <= len(link.colliders) <= FAST.max_hulls_per_piece
    # points in the cavity (well inside the inner wall, above the inner bottom) touch no hull
    cavity = np.array([[0.0, 0.0, 0.045], [0.0, 0.0, 0.06], [0.02, 0.0, 0.05], [0.0, -0.025, 0.055],
                       [-0.015, 0.015, 0.065]])
    assert not _inside_any(link.colliders, cavity).any()
    # the bowl's wall is covered: points in the middle of the wall are inside some hull
    ang = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    r = 0.07 - 0.004
    wall = np.stack([r * np.cos(ang) * np.sin(np.pi * 0.75), r * np.sin(ang) * np.sin(np.pi * 0.75),
                     np.full_like(ang, 0.07 + r * np.cos(np.pi * 0.75))], axis=1)
    assert _inside_any(link.colliders, wall, tol=2e-3).mean() >= 0.9
    # same seed -> the same hulls
    m2 = compute_colliders(_model(bowl.vertices, bowl.faces), FAST, np.random.default_rng(3))
    assert len(m2.links[0].colliders) == len(link.colliders)
    for a, b in zip(link.colliders, m2.links[0].colliders, strict=True):
        np.testing.assert_array_equal(a.vertices, b.vertices)


def test_collider_override_hull_and_none():
    bowl = bowl_mesh()
    rng = np.random.default_rng(0)
    hull = compute_colliders(_model(bowl.vertices, bowl.faces, collider="hull"), FAST, rng)
    assert len(hull.links[0].colliders) == 1 and hull.links[0].collider_approx == ColliderApprox.HULL
    assert _inside_any(hull.links[0].colliders, np.array([[0.0, 0.0, 0.05]])).all()  # cavity filled
    none = compute_colliders(_model(bowl.vertices, bowl.faces, collider="none"), FAST, rng)
    assert none.links[0].colliders == () and collider_kind(none) == "none"


def test_shelf_of_separate_boards_keeps_its_compartments():
    shelf = shelf_mesh()
    m = compute_colliders(_model(shelf.vertices, shelf.faces), FAST, np.random.default_rng(0))
    cols = m.links[0].colliders
    assert len(cols) == 7 and collider_kind(m) == "hulls"  # one hull per board, no CoACD needed
    centres = np.array([[0.0, -0.02, z] for z in (0.13, 0.4, 0.66)])  # middle of each compartment
    assert not _inside_any(cols, centres).any()


def test_flat_open_piece_is_thickened_to_a_valid_hull():
    quad_v = np.array([[0, 0, 0], [0.3, 0, 0], [0.3, 0.2, 0], [0, 0.2, 0]], float)
    quad_f = np.array([[0, 1, 2], [0, 2, 3]])
    m = compute_colliders(_model(quad_v, quad_f), CollisionConfig(), np.random.default_rng(0))
    (hull,) = m.links[0].colliders
    assert np.ptp(hull.vertices[:, 2]) == pytest.approx(CollisionConfig().min_thickness_m)


def test_collision_source_is_used_when_present():
    v, f = box_arrays((0.1, 0.1, 0.1))
    cv, cf = box_arrays((0.05, 0.05, 0.05))
    ann = AssetAnnotation(id="thing", source="thing.urdf", category="thing")
    link = Link(name="body", visuals=(MeshPart(name="v", vertices=v, faces=f),),
                collision_source=(MeshPart(name="c", vertices=cv, faces=cf),))
    m = compute_colliders(AssetModel(name="thing", annotation=ann, links=(link,)), CollisionConfig(),
                          np.random.default_rng(0))
    assert np.ptp(m.links[0].colliders[0].vertices, axis=0) == pytest.approx([0.05] * 3)


@pytest.mark.slow
@pytest.mark.parametrize("asset_id,cavity", [
    ("os_bowl", [[0.0, 0.0, 0.05], [0.02, 0.02, 0.06]]),
    ("os_mug", [[0.0, 0.0, 0.06], [0.0, 0.0, 0.09]]),
    ("ms_shelves", [[0.0, 0.0, 0.14], [0.0, 0.0, 0.40], [0.0, 0.0, 0.67]]),  # boards at 0, 0.27, 0.53, 0.8 m
])
def test_real_concave_assets_keep_cavities_open(shared_assets: Path, asset_id, cavity):
    from asset_catalog.annotations import load_annotations
    from stages.loaders.mesh import load_mesh_asset

    anns = {a.id: a for a in load_annotations(shared_assets, SHARED_RIGID_ANNOTATIONS).assets}
    a = anns[asset_id]
    model = load_mesh_asset(shared_assets / a.source, a, catalog_root=shared_assets)
    m = compute_colliders(model, CollisionConfig(), np.random.default_rng(0))
    cols = m.links[0].colliders
    assert collider_kind(m) == "coacd" and len(cols) >= 2
    pts = np.asarray(cavity, float)
    if asset_id == "os_mug":  # centre of the mug's body, not of its bbox (the handle is on one side)
        body = model.links[0].visuals[0].vertices
        pts[:, :2] = np.median(body[:, :2], axis=0)
    assert not _inside_any(cols, pts).any()
