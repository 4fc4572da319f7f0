"""The open containers of the household tasks in Newton (MuJoCo solver, CPU, the contact settings of the
physics checks): paper trash dropped from 0.6 m falls into a trash can and stays in it; a catalog plate
set on edge into a dish rack slot stays standing in the slot."""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest

pytestmark = pytest.mark.skipif(importlib.util.find_spec("newton_usd_schemas") is None,
                                reason="Newton's add_usd needs newton-usd-schemas")


@pytest.fixture(scope="module")
def packages(tmp_path_factory):
    from stages.scene.standin import build_library
    from stages.scene.solver import Library

    lib = Library.from_index(build_library(tmp_path_factory.mktemp("containers"),
                                           categories=["trash_can", "crumpled_paper", "dish_rack", "plate"],
                                           variants=1))
    return {c: lib.usd(r[0]) for c, r in lib.records.items()}


def _simulate(parts, seconds: float = 1.5) -> np.ndarray:
    """Body poses (n, 7: position, quaternion xyzw) after ``seconds`` of the assets ``(usd, position,
    quaternion)`` on a ground plane."""
    import newton
    import warp as wp

    import usd_schemas  # noqa: F401
    from stages.physics_checks import _contact_settings, _set_contact_parameters, _solver

    b = newton.ModelBuilder()
    newton.solvers.SolverMuJoCo.register_custom_attributes(b)
    for path, pos, quat in parts:
        b.add_usd(str(path), xform=wp.transform(pos, quat), load_visual_shapes=False)
    b.add_ground_plane()
    st = _contact_settings("cpu", "mujoco")
    model = b.finalize(device="cpu")
    _set_contact_parameters(model, st)
    solver = _solver(model, st)
    s0, s1, control = model.state(), model.state(), model.control()
    newton.eval_fk(model, model.joint_q, model.joint_qd, s0)
    for _ in range(round(seconds / st.dt)):
        s0.clear_forces()
        solver.step(s0, s1, control, None, st.dt)
        s0, s1 = s1, s0
    return s0.body_q.numpy().astype(np.float64)


def _rot(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of quaternion q (xyzw)."""
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _tilt(q: np.ndarray) -> float:
    """Angle [deg] between the body's local Z turned by quaternion q (xyzw) and world Z."""
    return math.degrees(math.acos(np.clip(_rot(q)[2, 2], -1.0, 1.0)))


def _catalog_asset(category: str):
    from asset_catalog.default_catalog import generate_default_assets

    (a,) = generate_default_assets(variants_per_category=1, seed=0, categories=[category])
    return a


def test_paper_dropped_into_the_trash_can_stays_inside(packages):
    import warp as wp

    can = _catalog_asset("trash_can")
    pts = np.vstack([p.vertices for lk in can.model.links for p in lk.visuals])
    lo, hi = pts.min(0), pts.max(0)
    q = _simulate([(packages["trash_can"], (0.0, 0.0, 0.001), wp.quat_identity()),
                   (packages["crumpled_paper"], (0.02, -0.01, 0.6), wp.quat_identity())])
    can_q, paper_q = q[0], q[1]
    assert _tilt(can_q[3:]) < 3.0 and np.abs(can_q[:2]).max() < 0.02       # the can stood still
    assert lo[0] < paper_q[0] < hi[0] and lo[1] < paper_q[1] < hi[1]       # inside its footprint
    assert 0.0 < paper_q[2] < 0.3 * hi[2], f"paper at z={paper_q[2]:.3f} (rim {hi[2]:.3f})"   # at the bottom


def test_plate_set_into_a_dish_rack_slot_stays_on_edge(packages):
    import warp as wp

    rack = _catalog_asset("dish_rack")
    (link,) = rack.model.links
    top = max(float(c.vertices[:, 2].max()) for c in link.collision_source)
    ys = sorted({round(float(c.vertices[:, 1].mean()), 4) for c in link.collision_source
                 if c.vertices[:, 2].max() > top - 1e-6})
    mid = len(ys) // 2
    slot = (ys[mid - 1] + ys[mid]) / 2              # between the two middle tines
    plate = _catalog_asset("plate").params
    radius, half = plate["radius"], plate["height"] / 2     # its origin is its foot: centre at +Z half
    # on edge: its face across Y (local Z -> world -Y)
    on_edge = wp.quat_from_axis_angle(wp.vec3(1.0, 0.0, 0.0), math.pi / 2)
    q = _simulate([(packages["dish_rack"], (0.0, 0.0, 0.001), wp.quat_identity()),
                   (packages["plate"], (0.0, slot + half, radius + 0.03), on_edge)])
    rack_q, plate_q = q[0], q[1]
    assert _tilt(rack_q[3:]) < 3.0
    tilt = _tilt(plate_q[3:])   # the plate's axis: 90 deg when it stands on edge, 0 lying flat
    assert 60.0 < tilt < 120.0, f"plate axis {tilt:.0f} deg from vertical: it fell over"
    centre = plate_q[:3] + _rot(plate_q[3:]) @ np.array([0.0, 0.0, half])
    assert ys[mid - 1] < centre[1] < ys[mid], f"plate y={centre[1]:.3f}, slot {ys[mid - 1]:.3f}..{ys[mid]:.3f}"
    assert centre[2] > 0.6 * radius                 # standing in the slot, not lying in the tray
