"""The built-in procedural library: every category x 5 variants, checked for geometry, sizes, handles,
joints, masses and distinctness; URDF/OBJ files read back with the project's loaders; determinism."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
import trimesh

from asset_catalog.asset_model import JointType
from asset_catalog.default_catalog import build_default_catalog, generate_default_assets
from asset_catalog.generators import GENERATORS, GENERATORS_BY_CATEGORY, GeneratedAsset
from asset_catalog.generators._mesh import manifold_arrays

VARIANTS = 5
CATEGORIES = [s.category for s in GENERATORS]
# minimum free space behind a grip [m] per handle kind
MIN_CLEARANCE = {"bar": 0.025, "lever": 0.03, "loop": 0.012, "knob": 0.015, "rim": 0.0}


@pytest.fixture(scope="module")
def assets() -> dict[str, list[GeneratedAsset]]:
    out: dict[str, list[GeneratedAsset]] = {}
    for a in generate_default_assets(variants_per_category=VARIANTS, seed=0):
        out.setdefault(a.annotation.category, []).append(a)
    return out


def _world_points(a: GeneratedAsset) -> np.ndarray:
    return np.vstack([p.vertices + lk.pose.position for lk in a.model.links for p in lk.visuals])


def test_library_covers_the_issue():
    required = {"sofa", "armchair", "coffee_table", "tv_stand", "bookshelf", "bed", "nightstand", "wardrobe",
                "dresser", "dining_table", "chair", "kitchen_counter", "rug", "floor_lamp", "fridge", "microwave",
                "oven", "cabinet", "closet", "door", "bowl", "plate", "mug", "cup", "bottle", "pitcher", "book",
                "box", "can", "apple", "orange", "banana", "crumpled_paper", "pillow", "sponge", "alarm_clock",
                "hanger"}
    assert required <= set(CATEGORIES)
    assert len(CATEGORIES) >= 30 and len(set(CATEGORIES)) == len(CATEGORIES)


@pytest.mark.parametrize("category", CATEGORIES)
def test_geometry_is_closed_finite_and_sized(assets, category):
    spec = GENERATORS_BY_CATEGORY[category]
    for a in assets[category]:
        for name, solid in a.link_solids.items():
            assert len(solid.decompose()) == 1, f"{a.model.name}/{name} has a floating part"
            v, f, _ = manifold_arrays(solid)
            tm = trimesh.Trimesh(v, f, process=False)
            assert tm.is_watertight and tm.is_winding_consistent, f"{a.model.name}/{name} is not closed"
            assert tm.volume > 0, f"{a.model.name}/{name} has non-positive volume"
        for lk in a.model.links:
            for p in lk.visuals:
                assert np.isfinite(p.vertices).all() and np.isfinite(p.normals).all() and np.isfinite(p.uvs).all()
                assert p.faces.min() >= 0 and p.faces.max() < len(p.vertices)
                assert np.allclose(np.linalg.norm(p.normals, axis=1), 1.0, atol=1e-3)
                assert p.material in a.model.materials
            for c in lk.collision_source or ():
                hull = trimesh.Trimesh(c.vertices, c.faces, process=True)
                assert hull.is_watertight and hull.is_convex, f"{a.model.name}: collider {c.name} is not convex"
        pts = _world_points(a)
        size = pts.max(0) - pts.min(0)
        assert abs(pts[:, 2].min()) < 1e-6, f"{a.model.name} does not start at z = 0"
        assert np.all(size >= np.array(spec.size_min) - 1e-6) and np.all(size <= np.array(spec.size_max) + 1e-6), (
            f"{a.model.name}: size {np.round(size, 3)} outside {spec.size_min}..{spec.size_max}")


@pytest.mark.parametrize("category", CATEGORIES)
def test_masses_are_plausible(assets, category):
    for a in assets[category]:
        links = a.model.links
        total = sum(lk.mass.mass for lk in links)
        pts = _world_points(a)
        box_volume = float(np.prod(pts.max(0) - pts.min(0)))
        assert 0.003 < total < 250.0, f"{a.model.name}: {total} kg"
        assert total / box_volume < 3000.0, f"{a.model.name}: {total} kg in a {box_volume:.3g} m^3 box"
        if a.annotation.mass is not None:
            assert a.annotation.mass == pytest.approx(total, rel=1e-3)
        for lk in links:
            assert all(i > 0 for i in lk.mass.diagonal_inertia)


@pytest.mark.parametrize("category", CATEGORIES)
def test_handles_are_graspable(assets, category):
    for a in assets[category]:
        for h in a.handles:
            assert h.grip_width <= 0.08, f"{a.model.name}: handle {h.grip_width} m across"
            assert h.clearance >= MIN_CLEARANCE[h.kind], f"{a.model.name}: {h.kind} clearance {h.clearance}"
            solid = a.link_solids[h.link]
            v, f, _ = manifold_arrays(solid)
            tm = trimesh.Trimesh(v + a.model.link(h.link).pose.position, f, process=False)
            _, dist, _ = trimesh.proximity.closest_point(tm, np.array([h.center]))
            assert dist[0] <= h.grip_width, f"{a.model.name}: handle centre {h.center} is {dist[0]} m off the mesh"
    spec = GENERATORS_BY_CATEGORY[category]
    if category in {"fridge", "microwave", "oven", "door", "nightstand", "dresser", "cabinet", "wardrobe",
                    "closet",
                    "kitchen_counter", "mug", "pitcher"}:
        assert all(a.handles for a in assets[category]), f"{spec.category} without handles"


@pytest.mark.parametrize("category", CATEGORIES)
def test_joints_have_intended_axes_and_limits(assets, category):
    for a in assets[category]:
        roles = {j.name: j.role for j in a.joints}
        names = {lk.name for lk in a.model.links}
        for j in a.model.joints:
            assert j.parent in names and j.child in names
            assert np.linalg.norm(j.axis) == pytest.approx(1.0)
            assert j.lower == 0.0 and j.upper > 0 and j.max_effort > 0 and j.max_velocity > 0
            role = roles[j.name]
            if role == "door":
                assert j.type == JointType.REVOLUTE and 1.4 <= j.upper <= np.pi / 2 + 1e-9
                assert np.abs(j.axis).max() == pytest.approx(1.0) and abs(j.axis[0]) < 1e-9
            elif role == "drawer":
                assert j.type == JointType.PRISMATIC and j.axis == (1.0, 0.0, 0.0) and 0.15 < j.upper < 0.6
            elif role == "button":
                assert j.type == JointType.PRISMATIC and 0.002 <= j.upper <= 0.01
            elif role == "switch":  # a slide switch: prismatic along a horizontal axis
                assert j.type == JointType.PRISMATIC and abs(j.axis[2]) < 1e-9 and 0.008 <= j.upper <= 0.03
            elif role == "knob":
                assert j.type == JointType.REVOLUTE and j.axis == (1.0, 0.0, 0.0)
            else:
                pytest.fail(f"{a.model.name}: joint {j.name} has no role")
        if a.annotation.fixed_base is not None:
            assert a.annotation.fixed_base == GENERATORS_BY_CATEGORY[category].fixed_base


def test_alarm_clock_has_a_top_button_and_a_back_slide_switch(assets):
    """The set_alarm_clock task's parts (issue 16): a button pressed down from the top and a slide
    switch on the back face, its knob clear of the body at both ends of its travel."""
    for a in assets["alarm_clock"]:
        roles = {j.role: j for j in a.joints}
        joints = {j.name: j for j in a.model.joints}
        button, switch = joints[roles["button"].name], joints[roles["switch"].name]
        assert button.axis == (0.0, 0.0, -1.0)
        assert switch.type == JointType.PRISMATIC and switch.axis == (0.0, 1.0, 0.0)
        back = min(p.vertices[:, 0].min() for p in a.model.link("base").visuals)
        knob = min(p.vertices[:, 0].min() + a.model.link(switch.child).pose.position[0]
                   for p in a.model.link(switch.child).visuals)
        assert knob < back - 0.008  # the knob stands proud of the back face
        for val in (0.0, switch.upper):
            pieces = _moved_pieces(a, switch.child, {switch.name: val})
            assert _overlap(pieces, _moved_pieces(a, "base", {})) < 2e-6


def _moved_pieces(a: GeneratedAsset, link: str, q: dict[str, float]):
    """Collision pieces of ``link`` as manifolds in the root frame with joint values ``q``."""
    from manifold3d import Manifold
    from scipy.spatial.transform import Rotation

    chain, cur = [], link
    parent_of = {j.child: j for j in a.model.joints}
    while cur in parent_of:
        chain.append(parent_of[cur])
        cur = parent_of[cur].parent
    m = np.eye(4)
    for j in reversed(chain):
        t = np.eye(4)
        t[:3, 3] = j.frame.position
        val = q.get(j.name, 0.0)
        if j.type == JointType.REVOLUTE:
            t[:3, :3] = Rotation.from_rotvec(np.asarray(j.axis) * val).as_matrix()
        else:
            t[:3, 3] += np.asarray(j.axis) * val
        m = m @ t
    out = []
    for c in a.model.link(link).collision_source or ():
        v = c.vertices @ m[:3, :3].T + m[:3, 3]
        out.append(Manifold.hull_points(v))
    return out


def _overlap(p: list, q: list) -> float:
    worst = 0.0
    for x, y in itertools.product(p, q):
        (ax0, ay0, az0, ax1, ay1, az1), (bx0, by0, bz0, bx1, by1, bz1) = x.bounding_box(), y.bounding_box()
        if ax1 < bx0 or bx1 < ax0 or ay1 < by0 or by1 < ay0 or az1 < bz0 or bz1 < az0:
            continue
        worst = max(worst, (x ^ y).volume())
    return worst


@pytest.mark.parametrize("category", [s.category for s in GENERATORS if s.fixed_base] + ["microwave",
                                                                                         "alarm_clock"])
def test_moving_parts_clear_their_frame(assets, category):
    """At the closed and at the open limit of each joint, its link's colliders overlap no other link's
    colliders (so the joints can really reach both limits)."""
    a = assets[category][0]
    for j in a.model.joints:
        for val in (0.0, j.upper):
            moving = _moved_pieces(a, j.child, {j.name: val})
            for other in a.model.links:
                if other.name == j.child:
                    continue
                ov = _overlap(moving, _moved_pieces(a, other.name, {}))
                assert ov < 2e-6, f"{a.model.name}: {j.child} at {val:.3f} overlaps {other.name} by {ov:.2e} m^3"
    # all joints at their upper limits at once (the joint-limit check drives them together)
    q = {j.name: j.upper for j in a.model.joints}
    pieces = {lk.name: _moved_pieces(a, lk.name, q) for lk in a.model.links}
    for x, y in itertools.combinations(pieces, 2):
        ov = _overlap(pieces[x], pieces[y])
        assert ov < 2e-6, f"{a.model.name}: with every joint open, {x} overlaps {y} by {ov:.2e} m^3"


@pytest.mark.parametrize("category", CATEGORIES)
def test_variants_differ(assets, category):
    vs = assets[category]
    assert len(vs) == VARIANTS
    for x, y in itertools.combinations(vs, 2):
        assert x.params != y.params
        sx, sy = np.ptp(_world_points(x), axis=0), np.ptp(_world_points(y), axis=0)
        assert not np.allclose(sx, sy, atol=1e-3), f"{x.model.name} and {y.model.name} have the same size"


def test_written_files_load_with_project_loaders(tmp_path: Path):
    """Every written source reads back through stages.loaders with the intended joints and colliders."""
    from asset_catalog.annotations import load_annotations, resolve_source
    from stages.loaders import load_source

    rep = build_default_catalog(tmp_path, variants_per_category=1, seed=3)
    cat = load_annotations(tmp_path)
    assert not cat.invalid and len(cat.assets) == len(rep.asset_ids) == len(GENERATORS)
    by_id = {a.model.name: a for a in generate_default_assets(variants_per_category=1, seed=3)}
    for ann in cat.assets:
        gen = by_id[ann.id]
        model = load_source(resolve_source(tmp_path, ann.source), ann)
        if gen.source_kind == "urdf":
            assert [lk.name for lk in model.links] == [lk.name for lk in gen.model.links]
        else:
            assert len(model.links) == 1 and not model.joints
        for j_loaded, j_gen in zip(model.joints, gen.model.joints, strict=True):
            assert j_loaded.type == j_gen.type and j_loaded.child == j_gen.child
            assert np.allclose(j_loaded.axis, j_gen.axis, atol=1e-6)
            assert j_loaded.lower == pytest.approx(j_gen.lower, abs=1e-6)
            assert j_loaded.upper == pytest.approx(j_gen.upper, abs=1e-6)
            assert np.allclose(j_loaded.frame.position, j_gen.frame.position, atol=1e-6)
        for lk_loaded, lk_gen in zip(model.links, gen.model.links, strict=True):
            assert len(lk_loaded.collision_source or ()) == len(lk_gen.collision_source or ())
        if gen.source_kind == "obj":
            mesh = trimesh.load(resolve_source(tmp_path, ann.source), force="mesh", process=False)
            mesh.merge_vertices(merge_tex=True, merge_norm=True)   # the OBJ's own shared positions
            assert mesh.is_watertight, f"{ann.source} is not closed on disk"
            assert ann.collider.value == "hull" and ann.mass is not None


def test_build_is_deterministic_and_selection_independent(tmp_path: Path):
    cats = ["mug", "cabinet", "door"]
    build_default_catalog(tmp_path / "a", variants_per_category=2, seed=7, categories=cats)
    build_default_catalog(tmp_path / "b", variants_per_category=2, seed=7, categories=cats)
    build_default_catalog(tmp_path / "c", variants_per_category=1, seed=7, categories=["door"])
    files_a = sorted(p.relative_to(tmp_path / "a") for p in (tmp_path / "a").rglob("*") if p.is_file())
    files_b = sorted(p.relative_to(tmp_path / "b") for p in (tmp_path / "b").rglob("*") if p.is_file())
    assert files_a == files_b and len(files_a) > 10
    for rel in files_a:
        assert (tmp_path / "a" / rel).read_bytes() == (tmp_path / "b" / rel).read_bytes(), rel
    for p in (tmp_path / "c" / "door").rglob("*"):
        if p.is_file():
            assert p.read_bytes() == (tmp_path / "a" / p.relative_to(tmp_path / "c")).read_bytes()
    build_default_catalog(tmp_path / "d", variants_per_category=1, seed=8, categories=["door"])
    a0 = (tmp_path / "c/door/door_00/door_00.urdf").read_bytes()
    assert a0 != (tmp_path / "d/door/door_00/door_00.urdf").read_bytes()


def test_unknown_category_is_a_clear_error(tmp_path: Path):
    with pytest.raises(ValueError, match="unknown categories: sofaa"):
        build_default_catalog(tmp_path, categories=["sofaa"])


def test_door_fills_a_given_wall_opening():
    from asset_catalog.generators import door_for_opening

    d = door_for_opening(0.92, 2.1, 0.12, np.random.default_rng(1), "door_x")
    frame = d.model.link("base").collision_source
    pts = np.vstack([c.vertices for c in frame])
    assert np.allclose(pts.min(0), (-0.06, -0.46, 0.0), atol=5e-4)
    assert np.allclose(pts.max(0), (0.06, 0.46, 2.1), atol=5e-4)
    assert d.params["leaf_width"] == pytest.approx(0.92 - 0.086) and d.annotation.fixed_base
    with pytest.raises(ValueError, match="outside"):
        door_for_opening(0.4, 2.1, 0.12, np.random.default_rng(1))


def test_overrides_fix_named_parameters_only():
    from asset_catalog.generators import generate

    spec = GENERATORS_BY_CATEGORY["sofa"]
    a = generate(spec, np.random.default_rng(5), "s")
    b = generate(spec, np.random.default_rng(5), "s", overrides={"seat_height": 0.5})
    assert b.params["seat_height"] == 0.5
    assert {k: v for k, v in a.params.items() if k != "seat_height"} == {k: v for k, v in b.params.items()
                                                                         if k != "seat_height"}


def _solid_at(solid, point) -> bool:
    """Whether the solid fills a 1 mm cube around ``point`` (exact, via a manifold intersection)."""
    from manifold3d import Manifold

    cube = Manifold.cube((0.001, 0.001, 0.001), True).translate(tuple(float(c) for c in point))
    return (solid ^ cube).volume() > 0.5e-9


SURFACE_CATEGORIES = ["sofa", "armchair", "coffee_table", "tv_stand", "bookshelf", "bed", "nightstand", "wardrobe",
                      "dresser", "dining_table", "chair", "kitchen_counter", "fridge", "microwave", "oven", "cabinet",
                      "closet"]


@pytest.mark.parametrize("category", SURFACE_CATEGORIES)
def test_support_surfaces_lie_on_the_geometry(assets, category):
    """Each recorded support surface has solid right below its centre and is inside the footprint."""
    for a in assets[category]:
        assert a.surfaces, f"{a.model.name} has no support surface"
        pts = _world_points(a)
        for s in a.surfaces:
            assert np.all(np.array(s.lo) < np.array(s.hi))
            assert np.all(np.array(s.lo) >= pts.min(0)[:2] - 1e-6) and np.all(np.array(s.hi) <= pts.max(0)[:2] + 1e-6)
            solid = a.link_solids[s.link]
            fx, fy = np.meshgrid(np.linspace(0.1, 0.9, 3), np.linspace(0.1, 0.9, 3))
            xy = np.array(s.lo) + np.column_stack([fx.ravel(), fy.ravel()]) * (np.array(s.hi) - np.array(s.lo))
            below = np.array([_solid_at(solid, (x, y, s.z - 0.004)) for x, y in xy])
            above = np.array([_solid_at(solid, (x, y, s.z + 0.004)) for x, y in xy])
            assert below.sum() >= 6, f"{a.model.name}: nothing solid under the surface at z={s.z:.3f}"
            assert above.sum() <= 1, f"{a.model.name}: surface z={s.z:.3f} is buried"
