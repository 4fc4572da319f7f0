"""A small box set on a thin static bar (a 14 mm convex mesh, as a pitcher's handle) rests on it.

With Newton's default contact gap (0.1 m a shape, 0.2 m a pair) MuJoCo's native CCD reports a box
pressed a few mm into a thin convex mesh as apart, so nothing pushes back: the box falls through the
bar (a Franka pad closed through the pitcher handle's bar that way, issue 16's serve_drinks).
:class:`stages.simulate.world.SimConfig` ``contact_gap`` (:data:`stages.simulate.world.CONTACT_GAP`,
0.01 m) keeps the detection right. test_simulate_thin_contacts.py checks the contact depth MuJoCo
reports for a fingertip in a thin disc; this one checks the dynamics on the pitcher generator's own
handle tube (the box stays on the bar for 0.1 s)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("newton")
pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")

from contact_testutil import add_free_box, floor_stage  # noqa: E402
from stages.simulate.robot import find_panda_description, write_robot_urdf  # noqa: E402
from stages.simulate.world import SimConfig, build_sim  # noqa: E402

BAR_Z = 0.5      # [m] the bar's axis height
BAR_R = 0.007    # [m] the bar's radius (the pitcher generator's handle rod)
BOX_H = 0.0152   # [m] the box's height (a Franka finger pad's thickness)
OVERLAP = 0.001  # [m] how far the box starts inside the bar


def write_bar_scene(path: Path) -> Path:
    """A floor, a static bar (the pitcher generator's handle rod: a convex-hull tube of radius BAR_R,
    40 mm along X, its far end 8 mm off along Y, axis at (3, 3, BAR_Z)) and a 17.5 x 18.5 x BOX_H mm
    box of 20 g that starts OVERLAP into it from above (as a pad that closed onto it in one step)."""
    from pxr import Gf, UsdGeom, UsdPhysics

    import asset_catalog.generators._geom as geom

    stage = floor_stage(path)
    ends = np.array([[2.98, 2.996, BAR_Z], [3.02, 3.004, BAR_Z]])
    mesh = geom.tube_path(ends, BAR_R, n=10)[0].to_mesh()
    bar = UsdGeom.Mesh.Define(stage, "/World/Bar")
    bar.CreatePointsAttr([Gf.Vec3f(*map(float, p[:3])) for p in np.asarray(mesh.vert_properties)])
    tris = np.asarray(mesh.tri_verts)
    bar.CreateFaceVertexCountsAttr([3] * len(tris))
    bar.CreateFaceVertexIndicesAttr([int(i) for i in tris.ravel()])
    UsdPhysics.CollisionAPI.Apply(bar.GetPrim())
    UsdPhysics.MeshCollisionAPI.Apply(bar.GetPrim()).CreateApproximationAttr("convexHull")
    add_free_box(stage, "/World/Box", (3.0, 3.0, BAR_Z + BAR_R + BOX_H / 2 - OVERLAP), (0.0175, 0.0185, BOX_H), 0.02)
    stage.Save()
    return path


def _box_z_after(scene: Path, desc, **cfg) -> float:
    sim = build_sim(SimConfig(scenes=(scene,), spawn=(1.0, 1.0, 0.0), **cfg), desc, np.random.default_rng(0))
    sim.step(int(round(0.1 / sim.settings.dt)))  # 0.1 s: a box balanced on a round bar rolls off later
    return float(sim.state_0.body_q.numpy()[sim.body_of_path("/World/Box")][2])


def test_a_box_set_on_a_thin_bar_rests_on_it(tmp_path):
    desc = write_robot_urdf(tmp_path / "robot", panda_root=find_panda_description(None))
    scene = write_bar_scene(tmp_path / "bar.usda")
    rest = BAR_Z + BAR_R + BOX_H / 2   # on the bar's top
    z = _box_z_after(scene, desc)
    assert abs(z - rest) < 0.0015, f"box at z {z:.4f} m, resting would be {rest:.4f} m"
