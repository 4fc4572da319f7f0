"""Annotate stage: masses from material density and volume, inertia, physics material, record figures."""

from __future__ import annotations

import numpy as np
import pytest

from asset_catalog.annotations import AssetAnnotation
from asset_catalog.asset_model import AssetModel, Link, MassProperties, MeshPart, Pose
from stages.annotate import SHELL_THICKNESS_M, annotate_physics, annotate_with_stats
from stages.collision import CollisionConfig, compute_colliders
from ingest_testutil import box_arrays


def _cube_model(size=0.1, material="wood", mass=None, z0=0.0) -> AssetModel:
    v, f = box_arrays((size, size, size))
    v = v + (0, 0, size / 2 + z0)
    ann = AssetAnnotation(id="cube", source="cube.obj", category="block", material=material, mass=mass)
    link = Link(name="body", visuals=(MeshPart(name="m", vertices=v, faces=f),))
    m = AssetModel(name="cube", annotation=ann, links=(link,))
    return compute_colliders(m, CollisionConfig(), np.random.default_rng(0))


def test_wooden_cube_of_10_cm_weighs_about_0_7_kg():
    m, st = annotate_with_stats(_cube_model(), np.random.default_rng(0))
    mp = m.links[0].mass
    assert mp.mass == pytest.approx(0.7, rel=1e-6)
    assert mp.center_of_mass == pytest.approx((0.0, 0.0, 0.05), abs=1e-9)
    i = 0.7 * (0.1**2 + 0.1**2) / 12  # solid cube about its centre
    assert mp.diagonal_inertia == pytest.approx((i, i, i), rel=1e-6)
    assert st.mass == pytest.approx(0.7) and st.volume == pytest.approx(1e-3)
    assert st.dimensions == pytest.approx((0.1, 0.1, 0.1))
    assert st.bbox_min == pytest.approx((-0.05, -0.05, 0.0))
    pm = m.physics_material
    assert 0.3 <= pm.dynamic_friction <= 0.5 and pm.density == 700.0  # wood 0.4 +/- 0.1
    assert st.dynamic_friction == pm.dynamic_friction and 0.0 <= st.restitution <= 1.0


def test_material_and_annotated_mass():
    metal = annotate_physics(_cube_model(material="metal"), np.random.default_rng(0))
    assert metal.links[0].mass.mass == pytest.approx(7.8)
    assert 0.15 <= metal.physics_material.dynamic_friction <= 0.25  # metal 0.2 +/- 0.05
    fixed = annotate_physics(_cube_model(mass=2.5), np.random.default_rng(0))
    assert fixed.links[0].mass.mass == pytest.approx(2.5)


def test_seeded_friction_is_deterministic():
    a = annotate_physics(_cube_model(), np.random.default_rng(42)).physics_material
    b = annotate_physics(_cube_model(), np.random.default_rng(42)).physics_material
    c = annotate_physics(_cube_model(), np.random.default_rng(43)).physics_material
    assert a == b and a != c


def test_open_crate_is_hollow_not_solid():
    """A 1 m open-top wooden crate (5 faces, not watertight) weighs its walls, not a solid cube."""
    v, f = box_arrays((1.0, 1.0, 1.0))
    v = v + (0, 0, 0.5)
    centres = v[f].mean(axis=1)
    f = f[centres[:, 2] < 0.999]  # drop the top face
    ann = AssetAnnotation(id="crate", source="crate.obj", category="crate", material="wood")
    link = Link(name="body", visuals=(MeshPart(name="m", vertices=v, faces=f),))
    m = AssetModel(name="crate", annotation=ann, links=(link,))
    m = compute_colliders(m, CollisionConfig(), np.random.default_rng(0))
    out, st = annotate_with_stats(m, np.random.default_rng(0))
    expected = 700.0 * 0.5 * 5.0 * SHELL_THICKNESS_M["wood"]  # 5 m^2 of walls, half-area convention
    assert out.links[0].mass.mass == pytest.approx(expected, rel=1e-6)
    assert out.links[0].mass.mass < 0.1 * 700.0


def test_articulated_mass_split_by_volume_and_source_mass_kept():
    v1, f1 = box_arrays((0.2, 0.2, 0.2))
    v2, f2 = box_arrays((0.1, 0.1, 0.1))
    ann = AssetAnnotation(id="cab", source="cab.urdf", category="cabinet", mass=9.0)
    base = Link(name="base", visuals=(MeshPart(name="a", vertices=v1, faces=f1),))
    door = Link(name="door", pose=Pose((0.3, 0, 0)), visuals=(MeshPart(name="b", vertices=v2, faces=f2),))
    knob_mass = MassProperties(mass=1.0, center_of_mass=(0, 0, 0), diagonal_inertia=(1e-4,) * 3)
    given = Link(name="knob", mass=knob_mass, mass_from_source=True)
    m = AssetModel(name="cab", annotation=ann, links=(base, door, given))
    m = compute_colliders(m, CollisionConfig(), np.random.default_rng(0))
    out = annotate_physics(m, np.random.default_rng(0))
    masses = [lk.mass.mass for lk in out.links]
    assert masses[2] == 1.0  # from the source, untouched
    assert masses[0] + masses[1] == pytest.approx(8.0)
    assert masses[0] / masses[1] == pytest.approx(8.0)  # volume ratio 0.008 / 0.001
