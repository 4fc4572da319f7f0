"""Newton physics checks on asset packages written from models built in code (CPU)."""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import trimesh

pytest.importorskip("newton_usd_schemas", reason="Newton's add_usd needs newton-usd-schemas")

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "usd_schemas"))
import usd_test_models as M  # noqa: E402

import usd_schemas  # noqa: E402
from asset_catalog.asset_model import Pose  # noqa: E402
from stages.physics_checks import (  # noqa: E402
    RIGID_CONTACT_SOLIMP,
    RIGID_CONTACT_SOLREF,
    joint_limit_check,
    rest_check,
)


@pytest.fixture(scope="module")
def packages(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("phys")
    models = [M.box_model(), M.bowl_model(), M.textured_model(root / "src"), M.cabinet_model(),
              M.cabinet_model("cabinet_fixed", fixed_base=True), M.tilted_hinge_model(), M.loaded_hinge_model()]
    out = {}
    for m in models:
        pkg = usd_schemas.write_asset_package(m, root / m.name, pipeline_version="0.1.0")
        assert usd_schemas.validate_package(pkg.root_path).ok
        out[m.name] = pkg.root_path
    return out


@pytest.mark.parametrize("name", ["box_01", "bowl_01", "crate_01"])
def test_rigid_assets_come_to_rest(packages, name):
    r = rest_check(packages[name], device="cpu", seconds=1.5)
    assert r.passed, r.reasons
    assert abs(r.final_height) < 0.003
    assert r.settled_min_height > -0.003
    assert r.max_rise < 0.02
    assert r.final_linear_speed < 0.02 and r.final_angular_speed < 0.2
    assert r.solver.solver == "SolverMuJoCo" and r.solver.device == "cpu" and r.solver.backend == "mujoco-c"
    assert r.solver.contacts == "mujoco"
    assert r.solver.contact_solref == RIGID_CONTACT_SOLREF and r.solver.contact_solimp == RIGID_CONTACT_SOLIMP


def _hull_package(tmp_path: Path, name: str, points: np.ndarray, density: float) -> Path:
    """A one-body package whose visual and collider are the convex hull of ``points`` [m]."""
    mesh = trimesh.convex.convex_hull(points)
    box = M.box_model(name)
    link = replace(box.links[0], visuals=(M.part(name, mesh),), colliders=M.hulls([mesh]),
                   mass=M.mass_properties([mesh], density))
    pkg = usd_schemas.write_asset_package(box.replace_links((link,)), tmp_path / name, pipeline_version="0.1.0")
    return pkg.root_path


def _scanned_die(seed: int, side: float = 0.017, bump: float = 0.0005, grid: int = 6) -> np.ndarray:
    """Hull points of a die (side [m], chamfered vertical edges) whose bottom is a grid of points up
    to ``bump`` [m] above z = 0, like a scanned nearly flat face."""
    rng = np.random.default_rng(seed)
    h, c = side / 2, side / 2 - 0.002
    pts = [(sx * a, sy * b, z) for sx in (-1, 1) for sy in (-1, 1) for a, b in ((c, h), (h, c))
           for z in (0.002, side)]
    g = np.linspace(-c, c, grid)
    pts += [(x, y, rng.uniform(0.0, bump)) for x in g for y in g]
    return np.asarray(pts)


def test_nearly_flat_bottom_rests_with_rigid_contacts(tmp_path):
    """A 17 mm die with a 0.5 mm uneven bottom (36 hull points). With MuJoCo's soft default contacts
    it rests 0.2 mm deep, its 3 plane-mesh contacts keep switching and it micro-rocks; with the
    check's stiff contacts it rests still."""
    soft = []
    for seed in (0, 3):
        pkg = _hull_package(tmp_path, f"die_{seed}", _scanned_die(seed), density=950.0)
        r = rest_check(pkg)
        assert r.passed, r.reasons
        assert r.final_angular_speed < 0.02 and r.final_linear_speed < 0.002 and abs(r.final_height) < 1e-4
        soft.append(rest_check(pkg, contact_solref=None, contact_solimp=None))
        assert soft[-1].solver.contact_solref is None and abs(soft[-1].final_height) > 1e-4  # rests deeper
    assert all(r.final_angular_speed > 0.02 for r in soft)  # still rocking after 3 s
    assert any("not at rest" in x for r in soft for x in r.reasons), [r.reasons for r in soft]


def test_toppling_tube_impact_sink_with_rigid_contacts(tmp_path):
    """A 20 cm tube (164 g) standing on a 1.6 mm wide crimped end off its center of mass topples and
    comes to rest; the stiff contacts bound its impact penetration (soft defaults: ~6 mm)."""
    w, d, hgt = 0.037, 0.052, 0.2
    pts = [(sx * w / 2, 0.005 + sy * 0.0008, 0.0) for sx in (-1, 1) for sy in (-1, 1)]
    pts += [(sx * w / 2, sy * d / 2, z) for sx in (-1, 1) for sy in (-1, 1) for z in (0.6 * hgt, hgt)]
    pkg = _hull_package(tmp_path, "tube", np.asarray(pts), density=600.0)
    r = rest_check(pkg)
    assert r.passed, r.reasons
    assert -0.004 < r.min_height < 0.0
    soft = rest_check(pkg, contact_solref=None, contact_solimp=None)
    assert soft.min_height < 1.5 * r.min_height


def test_rest_check_detects_an_asset_that_does_not_rest(tmp_path):
    """A box authored tilted 30 degrees lands on an edge and topples: not at rest after 0.3 s."""
    import math

    box = M.box_model("tilted_01")
    tilted = replace(box.links[0], pose=Pose((0.0, 0.0, 0.0), (math.cos(math.pi / 12), math.sin(math.pi / 12), 0.0, 0.0)))
    pkg = usd_schemas.write_asset_package(box.replace_links((tilted,)), tmp_path, pipeline_version="0.1.0")
    r = rest_check(pkg.root_path, seconds=0.3)
    assert not r.passed and any("not at rest" in x for x in r.reasons), r
    settled = rest_check(pkg.root_path, seconds=2.0)
    assert settled.final_linear_speed < 0.02 and abs(settled.final_height) < 0.003, "given time, it settles"
    no_cols = box.replace_links((replace(box.links[0], colliders=()),))
    pkg2 = usd_schemas.write_asset_package(no_cols, tmp_path / "nocol", pipeline_version="0.1.0")
    r2 = rest_check(pkg2.root_path, seconds=0.1)
    assert not r2.passed and r2.reasons == ("no collider shapes",)


def test_fixed_assets_are_released_for_the_drop(packages, tmp_path):
    r = rest_check(packages["cabinet_fixed"], seconds=1.5)
    assert r.passed and r.released_base and r.body_count == 3, r.reasons
    shelf = replace(M.box_model("shelf_01"), fixed_base=True)  # static: colliders, no rigid body
    pkg = usd_schemas.write_asset_package(shelf, tmp_path, pipeline_version="0.1.0")
    r2 = rest_check(pkg.root_path, seconds=1.0)
    assert r2.passed and r2.released_base and r2.body_count == 1, r2.reasons
    assert not rest_check(packages["box_01"], seconds=0.5).released_base


@pytest.mark.parametrize("name,joints", [("cabinet_01", 2), ("cabinet_fixed", 2), ("flap_01", 1), ("lid_01", 1)])
def test_articulated_joints_reach_their_limits(packages, name, joints):
    r = joint_limit_check(packages[name], device="cpu")
    assert r.passed, r.reasons
    assert len(r.joints) == joints
    for j in r.joints:
        assert j.passed
        assert abs(j.reached_lower - j.lower) <= j.tolerance
        assert abs(j.reached_upper - j.upper) <= j.tolerance
        assert j.max_excursion <= j.tolerance
    if name == "lid_01":  # 2 N m friction + lid weight (1.68 kg at 0.15 m): stiffness sized from the load
        assert r.joints[0].drive_stiffness > 4 * (2.0 + 1.68 * 9.81 * 0.15) / r.joints[0].tolerance * 0.99
    kinds = sorted(j.kind for j in r.joints)
    assert kinds == (["prismatic", "revolute"] if joints == 2 else ["revolute"])


def test_joint_limit_check_without_joints_fails(packages):
    r = joint_limit_check(packages["box_01"])
    assert not r.passed and r.reasons == ("no revolute or prismatic joint",)


def test_checks_work_after_pxr_opened_the_package_first(packages):
    """Import order: a fresh process opens packages with pxr (building USD's schema registry)
    before anything of ours is imported, then runs both checks."""
    import os
    import subprocess

    code = ("import sys\n"
            "from pxr import Usd\n"
            "stages = [Usd.Stage.Open(p) for p in sys.argv[1:]]\n"
            "assert 'AgentWorldAssetAPI' in stages[0].GetDefaultPrim().GetMetadata('apiSchemas').GetAddedOrExplicitItems()\n"
            "assert Usd.SchemaRegistry().FindAppliedAPIPrimDefinition('AgentWorldAssetAPI') is None\n"
            "from stages.physics_checks import joint_limit_check, rest_check\n"
            "r = rest_check(sys.argv[1], seconds=1.5)\n"
            "j = joint_limit_check(sys.argv[2])\n"
            "print(r.passed, r.reasons, j.passed, len(j.joints), j.reasons)\n")
    repo = Path(__file__).resolve().parents[2]
    env = {k: v for k, v in os.environ.items() if k != "PXR_PLUGINPATH_NAME"}
    r = subprocess.run([sys.executable, "-c", code, str(packages["box_01"]), str(packages["cabinet_01"])],
                       cwd=repo, capture_output=True, text=True, timeout=300, env={**env, "PYTHONPATH": str(repo)})
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.split("\n")[-2] == "True () True 2 ()"


_BALL_URDF = """<?xml version="1.0"?>
<robot name="soccerball">
  <link name="base_link">
    <contact>
      <lateral_friction value="0.9"/>
      <rolling_friction value="0.03"/>
      <spinning_friction value="0.03"/>
      <contact_cfm value="0.0"/>
    </contact>
    <inertial><mass value="10.0"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>
    <visual><geometry><sphere radius="0.5"/></geometry></visual>
    <collision><geometry><sphere radius="0.5"/></geometry></collision>
  </link>
</robot>
"""


def test_urdf_ball_contact_extension_reaches_usd_and_the_ball_rests(tmp_path):
    """A URDF ball with <contact> rolling and spinning friction (PyBullet's soccer ball: 1 m, 10 kg)
    through the real ingest job: its collider's material carries them as Newton's torsional and
    rolling friction, the collider asks MuJoCo for condim 6, and the ball comes to rest (without
    them it still rolls at 0.084 m/s after 3 s)."""
    from pxr import Usd, UsdPhysics, UsdShade

    from pipeline import build_job, run_job

    cat = tmp_path / "cat"
    cat.mkdir()
    (cat / "ball.urdf").write_text(_BALL_URDF)
    (cat / "annotations.toml").write_text('[[asset]]\nid = "ball_01"\nsource = "ball.urdf"\ncategory = "ball"\n'
                                          'placement = "on_floor"\nmaterial = "rubber"\n')
    out = tmp_path / "out"
    job = {"job": {"name": "ball", "seed": 0, "out": str(out), "executor": "inline", "workers": 1},
           "step": [{"name": "assets", "kind": "ingest", "config": {"catalog": str(cat)}}]}
    (step,) = run_job(build_job(job, source="<test>", base_dir=tmp_path), progress=False).steps
    assert step.done == 1, step.failures
    usd = out / "assets" / "ball_01" / "ball_01.usda"
    stage = Usd.Stage.Open(str(usd))
    (collider,) = [p for p in stage.Traverse() if p.HasAPI(UsdPhysics.CollisionAPI)]
    mat = UsdShade.MaterialBindingAPI(collider).GetDirectBinding("physics").GetMaterial().GetPrim()
    assert mat.GetAttribute("newton:rollingFriction").Get() == pytest.approx(0.03)
    assert mat.GetAttribute("newton:torsionalFriction").Get() == pytest.approx(0.03)
    assert mat.GetAttribute("physics:dynamicFriction").Get() == pytest.approx(0.9)
    assert collider.GetAttribute("mjc:condim").Get() == 6
    default = stage.GetPrimAtPath("/ball_01/Looks/PhysicsMaterial")   # the asset's (rubber) material
    assert default.GetAttribute("newton:rollingFriction").Get() == pytest.approx(0.001)
    assert default.GetAttribute("newton:torsionalFriction").Get() == pytest.approx(0.008)
    assert usd_schemas.validate_package(usd).ok
    r = rest_check(usd, seconds=3.0)
    assert r.passed, r.reasons
    assert r.final_linear_speed < 0.005 and r.final_angular_speed < 0.01
