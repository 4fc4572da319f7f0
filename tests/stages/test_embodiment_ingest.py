"""The humanoids ingested through the project's articulated path (stages.ingest.ingest_asset) into
USD packages: Newton loads them with the sources' joint limits, effort limits and armature, the
base stays movable, and every joint reaches both limits in Newton (physics_checks)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from stages.embodiment import load_spec
from stages.embodiment.kinematics import build_model
from stages.embodiment.sources import ingest_embodiment, resolve_description

pytest.importorskip("newton_usd_schemas", reason="newton's USD importer needs newton-usd-schemas")


def _newton_joints(usd: Path) -> dict[str, dict[str, float]]:
    """name -> lower, upper [rad], effort [N m], armature [kg m^2] of every 1-DoF joint as Newton loads it."""
    import newton

    import usd_schemas  # noqa: F401

    b = newton.ModelBuilder()
    b.add_usd(str(usd), load_visual_shapes=False)
    out = {}
    for j in range(b.joint_count):
        if b.joint_type[j] == newton.JointType.REVOLUTE:
            d = b.joint_qd_start[j]
            out[b.joint_label[j].rsplit("/", 1)[-1]] = dict(
                lower=b.joint_limit_lower[d], upper=b.joint_limit_upper[d], effort=b.joint_effort_limit[d],
                armature=b.joint_armature[d], damping=b.joint_target_kd[d])
    free = [j for j in range(b.joint_count) if b.joint_type[j] == newton.JointType.FREE]
    out["_free_root"] = {"count": float(len(free))}
    return out


def _ingest(name: str, out: Path, shared: Path | None = None):
    spec = load_spec(name)
    result = ingest_embodiment(spec, out / spec.name, shared_assets=shared)
    return spec, result, out / result.usd_path


@pytest.fixture(scope="module")
def g1_package(tmp_path_factory):
    """The G1 through the ``robots`` job kind (runner, cache, the ingest stage's function)."""
    from pipeline import build_job, load_results, run_job

    out = tmp_path_factory.mktemp("robots") / "out"
    data = {"job": {"name": "robots", "seed": 0, "out": str(out), "executor": "inline", "workers": 1},
            "step": [{"name": "robots", "kind": "robots",
                      "config": {"specs": ["g1_29dof", "no_such_spec.toml"]}}]}
    summary = run_job(build_job(data, source="<test>", base_dir=out.parent), progress=False)
    (step,) = summary.steps
    assert step.done == 1 and step.failed == 1, step.failures
    assert "no_such_spec.toml: cannot read the embodiment spec" in str(step.failures)
    result = load_results(out, "robots")["g1_29dof"]
    return load_spec("g1_29dof"), result, out / result.usd_path


def _limit_check(spec, usd: Path, joints):
    from stages import physics_checks

    report = physics_checks.joint_limit_check(usd, device="cpu", self_collisions=False, joints=joints)
    assert report.passed, report.reasons
    assert len(report.joints) == len(joints)
    return report


def test_g1_package_has_the_urdf_limits_and_a_movable_base(g1_package):
    spec, result, usd = g1_package
    assert usd.is_file() and result.is_articulated and result.validation_errors == 0
    assert result.collider_method == "hull" and result.n_colliders >= 29
    assert 30.0 < result.mass < 40.0                       # the URDF's links sum to 33.3 kg
    src = resolve_description(spec.description).path
    urdf = {j.get("name"): j.find("limit").attrib for j in ET.parse(src).getroot().iter("joint")
            if j.get("type") == "revolute"}
    got = _newton_joints(usd)
    assert got.pop("_free_root")["count"] == 1.0              # pelvis on a free joint
    assert set(got) == set(urdf) and len(got) == 29
    for name, lim in urdf.items():
        assert got[name]["lower"] == pytest.approx(float(lim["lower"]), abs=1e-5), name
        assert got[name]["upper"] == pytest.approx(float(lim["upper"]), abs=1e-5), name
        assert got[name]["effort"] == pytest.approx(float(lim["effort"]), rel=1e-6), name
    # the arm chains of the spec are the package's joints
    assert set(spec.arm_joints) <= set(got)


def test_g1_package_every_joint_reaches_its_limits_in_newton(g1_package):
    """All 29 joints driven to both limits at once (base fixed, self-collisions off)."""
    spec, _, usd = g1_package
    model = build_model(spec, resolve_description(spec.description).path)
    joints = [model.names[j] for j in range(1, model.njoints)]
    report = _limit_check(spec, usd, joints)
    for j in report.joints:
        assert j.reached_upper - j.reached_lower > 0.9 * (j.upper - j.lower), j


def _hold_default_pose(spec, usd: Path, seconds: float = 2.0) -> dict[str, float]:
    """Joint name -> |deviation| [rad] from the default pose after ``seconds`` with the spec's
    drives, the root fixed, gravity on (MuJoCo C, implicitfast, 2 ms)."""
    import newton

    import usd_schemas  # noqa: F401
    from stages.embodiment.drives import apply_drives

    b = newton.ModelBuilder()
    newton.solvers.SolverMuJoCo.register_custom_attributes(b)
    b.add_usd(str(usd), floating=False, load_visual_shapes=False, enable_self_collisions=False)
    joints = apply_drives(b, spec)
    for name, d in joints.dof.items():
        drive = spec.drive_for(name)
        assert (b.joint_target_ke[d], b.joint_target_kd[d]) == (drive.kp, drive.kd), name
    model = b.finalize(device="cpu")
    solver = newton.solvers.SolverMuJoCo(model, use_mujoco_cpu=True, iterations=50, ls_iterations=20,
                                         integrator="implicitfast")
    s0, s1, ctl = model.state(), model.state(), model.control()
    newton.eval_fk(model, model.joint_q, model.joint_qd, s0)
    q0 = model.joint_q.numpy().copy()
    for _ in range(round(seconds / 0.002)):
        s0.clear_forces()
        solver.step(s0, s1, ctl, None, 0.002)
        s0, s1 = s1, s0
    q = s0.joint_q.numpy()
    return {n: abs(float(q[c] - q0[c])) for n, c in joints.coord.items()}


def test_g1_spec_drives_hold_the_default_pose(g1_package):
    """Fixed pelvis, 2 s: the motor-derived gains hold every joint within 0.05 rad (legs in the
    air carry their own weight; arms gravity-compensated as the spec says)."""
    spec, _, usd = g1_package
    dev = _hold_default_pose(spec, usd)
    assert len(dev) == 29 and max(dev.values()) < 0.05, sorted(dev.items(), key=lambda kv: -kv[1])[:4]
    assert max(dev[j] for j in spec.arm_joints) < 0.02


def test_h1_package_keeps_the_mjcf_armature_damping_and_motor_limits(shared_assets, tmp_path):
    spec, result, usd = _ingest("h1", tmp_path, shared_assets)
    assert result.validation_errors == 0 and 45.0 < result.mass < 60.0
    got = _newton_joints(usd)
    assert got.pop("_free_root")["count"] == 1.0
    assert len(got) == 19
    for name, j in got.items():
        assert j["armature"] == pytest.approx(0.1), name      # <joint damping="1" armature="0.1"/>
        assert j["damping"] == pytest.approx(1.0), name
    assert got["left_knee_joint"]["effort"] == 300.0 and got["right_ankle_joint"]["effort"] == 40.0
    assert got["left_elbow_joint"]["lower"] == pytest.approx(-1.25, abs=1e-5)     # USD: float degrees
    assert got["left_elbow_joint"]["upper"] == pytest.approx(2.61, abs=1e-5)
    _limit_check(spec, usd, list(got))
    dev = _hold_default_pose(spec, usd)        # unitree_rl_gym's gains, no gravity compensation
    assert max(dev.values()) < 0.05, sorted(dev.items(), key=lambda kv: -kv[1])[:4]


@pytest.mark.slow
def test_newton_g1_mjcf_package_arms_and_hands_reach_their_limits(shared_assets, tmp_path):
    """newton-assets' G1 with Dex3 hands (43 joints): the arms and the 14 finger joints. (Driving
    all 43 at once, its waist roll overshoots its limit by 0.0528 rad for a 0.0524 rad tolerance.)"""
    spec, result, usd = _ingest("g1_29dof_dex3_newton", tmp_path, shared_assets)
    got = _newton_joints(usd)
    got.pop("_free_root")
    assert len(got) == 43 and got["left_ankle_pitch_joint"]["effort"] == 50.0
    _limit_check(spec, usd, list(spec.arm_joints))
    _limit_check(spec, usd, list(spec.end_effector_joints))
    assert np.isfinite(result.mass)
