"""Embodiment specs: the shipped TOML files load, the mobile Panda's spec describes what
stages/simulate/robot.py builds, the humanoids' specs match their real descriptions (chains, frames,
limits), and bad specs fail with one message naming the file and every problem."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from stages.embodiment import BaseKind, EmbodimentError, EndEffectorKind, load_spec, shipped_specs
from stages.embodiment.kinematics import (Kinematics, build_model, camera_mount_pose, chain_joints, check_spec,
                                          require_spec_matches)
from stages.embodiment.sources import default_shared_assets, resolve_description

ROBOTIQ = "robots/robotiq_2f85__menagerie"


def _model(name: str, shared: Path | None = None):
    spec = load_spec(name)
    res = resolve_description(spec.description, shared_assets=shared)
    return spec, build_model(spec, res.path), res


def test_every_shipped_spec_loads():
    specs = {n: load_spec(n) for n in shipped_specs()}
    assert {"mobile_panda", "mobile_panda_robotiq", "g1_29dof", "g1_29dof_dex3", "g1_29dof_dex3_newton",
            "h1"} <= set(specs)
    for name, s in specs.items():
        assert s.name == name
        assert s.arms and s.cameras
        assert all(s.drive_for(j) is not None for j in s.actuated_joints)
    assert specs["mobile_panda"].base.kind == BaseKind.HOLONOMIC
    assert specs["g1_29dof"].base.kind == specs["h1"].base.kind == BaseKind.LEGGED_POLICY
    assert specs["g1_29dof"].arm_dof == 14 and specs["h1"].arm_dof == 8
    assert specs["g1_29dof_dex3"].end_effectors["left_hand"].kind == EndEffectorKind.HAND
    assert len(specs["g1_29dof_dex3"].end_effector_joints) == 14


# ------------------------------------------------------------------------------- the mobile Panda


@pytest.mark.parametrize("gripper,spec_name", [("panda_hand", "mobile_panda"),
                                                ("robotiq_2f85", "mobile_panda_robotiq")])
def test_panda_spec_describes_what_robot_py_builds(tmp_path, gripper, spec_name):
    """Joint names and order, gripper, base geometry, camera mounts, home pose and drive gains of
    the spec equal robot.py's; and the spec checks clean against the URDF robot.py writes."""
    from stages.simulate.robot import ARM_HOME, BaseGeometry, write_robot_urdf
    from stages.simulate.robot_load import DriveGains

    robotiq = None
    if gripper == "robotiq_2f85":
        robotiq = default_shared_assets() / ROBOTIQ
        if not robotiq.is_dir():
            pytest.skip(f"Robotiq 2F-85 meshes not found at {robotiq}")
    desc = write_robot_urdf(tmp_path, gripper=gripper, robotiq_root=robotiq)
    spec = load_spec(spec_name)
    (arm,) = spec.arms
    ee = spec.end_effectors[arm.end_effector]
    assert spec.actuated_joints == desc.joints
    assert spec.base.joints == desc.base_joints and arm.joints == desc.arm_joints
    assert ee.joints == desc.gripper.finger_joints and arm.ee_frame == desc.ee_frame
    assert ee.mount_link == desc.gripper.hand_link
    assert ee.open == (desc.gripper.open_q,) * 2 and ee.closed == (desc.gripper.closed_q,) * 2
    assert ee.max_force == desc.gripper.max_force and ee.squeeze == desc.gripper.squeeze
    assert tuple(spec.default_pose[j] for j in arm.joints) == ARM_HOME == desc.arm_home
    base = BaseGeometry()
    mobile = spec.base.mobile
    assert (mobile.chassis, mobile.clearance, mobile.mass, mobile.arm_mount, mobile.mast_xy, mobile.mast_height) \
        == (base.chassis, base.clearance, base.mass, base.arm_mount, base.mast_xy, base.mast_height)
    assert (spec.base.max_force, spec.base.max_torque) == (base.max_force, base.max_torque)
    # camera mounts: same links, parents, poses and intrinsics
    assert set(spec.link_cameras()) == set(desc.cameras)
    from scipy.spatial.transform import Rotation

    for name, mount in desc.cameras.items():
        cam = spec.cameras[name]
        assert (cam.link, cam.parent) == (mount.link, mount.parent)
        assert (cam.width, cam.height) == (mount.width, mount.height)
        assert np.deg2rad(cam.vertical_fov_deg) == pytest.approx(mount.vertical_fov)
        pose = camera_mount_pose(spec, name)
        np.testing.assert_allclose(pose[:3, 3], mount.xyz, atol=1e-12)
        np.testing.assert_allclose(pose[:3, :3], Rotation.from_euler("xyz", mount.rpy).as_matrix(), atol=1e-9)
    from stages.simulate.sensors import CameraSpec

    k = CameraSpec(name="head", width=128, height=128, vertical_fov=desc.cameras["head"].vertical_fov).intrinsics
    assert spec.cameras["head"].intrinsics() == pytest.approx((k.fx, k.fy, k.cx, k.cy))
    # third person: stages/engine/engine.py's eye (0.3, 0.3, 2.3), target (0.6 sx, 0.6 sy, 0.6), 1 rad
    third = spec.cameras["third_person"]
    assert third.fixed and third.look_at((5.0, 4.0)) == ((0.3, 0.3, 2.3), (3.0, 2.4, 0.6))
    assert third.vertical_fov == pytest.approx(1.0)
    # drive gains: robot.DriveGains
    g = DriveGains()
    assert spec.drive_for("base_x").kd == g.base_kd and spec.drive_for("base_x").mode == "velocity"
    for i, j in enumerate(arm.joints):
        d = spec.drive_for(j)
        assert (d.kp, d.kd, d.armature, d.gravity_compensation) == (g.arm_ke[i], g.arm_kd[i], g.arm_armature, True)
    f = spec.drive_for(ee.joints[0])
    assert (f.kp, f.kd, f.armature) == (g.finger_ke, g.finger_kd, g.finger_armature)
    # against the written URDF: chains, the TCP frame at ee_xyz/ee_rpy, limits, drives for every joint
    model = build_model(spec, desc.urdf)
    assert check_spec(spec, model) == []
    kin = Kinematics(spec, model)
    for name in desc.cameras:    # robot.py's camera links sit where the spec mounts them
        parent = kin.frame_pose(kin.default_q(), spec.cameras[name].parent)
        np.testing.assert_allclose(kin.frame_pose(kin.default_q(), spec.cameras[name].link),
                                   parent @ camera_mount_pose(spec, name), atol=1e-8)   # URDF: 9 digits


def test_panda_spec_matches_the_dataset_schema_defaults():
    from stages.dataset.schema import DatasetSpec

    spec, d = load_spec("mobile_panda"), DatasetSpec()
    assert (spec.robot_type, spec.arm_dof) == (d.robot_type, d.arm_dof)
    assert set(spec.cameras) == {c.name for c in d.cameras}


# ------------------------------------------------------------------------------------ humanoids


@pytest.mark.parametrize("name", ["g1_29dof", "g1_29dof_dex3"])
def test_g1_specs_match_the_example_robot_data_urdf(name):
    spec, model, res = _model(name)
    assert res.origin == "package" and res.path.is_file()
    assert check_spec(spec, model) == []
    assert model.nq == 29 + len(spec.end_effector_joints)
    assert chain_joints(model, "torso_link", "left_wrist_yaw_link") == spec.arm("left").joints
    # the head camera is the D435's frame: optical -Z along d435_link's +X, +Y along its +Z
    kin = Kinematics(spec, model)
    q = kin.default_q()
    d435, cam = kin.frame_pose(q, "d435_link"), kin.frame_pose(q, "head_camera")
    np.testing.assert_allclose(cam[:3, 3], d435[:3, 3], atol=1e-9)
    np.testing.assert_allclose(-cam[:3, 2], d435[:3, 0], atol=1e-4)
    np.testing.assert_allclose(cam[:3, 1], d435[:3, 2], atol=1e-4)
    # the hands sit in front of the torso, left on the left, at the default pose
    left, right = kin.ee_pose(q, "left"), kin.ee_pose(q, "right")
    assert left[1, 3] > 0.1 and right[1, 3] < -0.1 and left[0, 3] > 0.0


def test_newton_g1_mjcf_matches_the_urdf(shared_assets):
    """The MJCF (compiled by MuJoCo, written as URDF for Pinocchio) and example-robot-data's URDF
    give the same hands and head camera at the default pose."""
    spec_m, model_m, res = _model("g1_29dof_dex3_newton", shared_assets)
    assert res.origin == "shared" and model_m.nq == 43
    assert check_spec(spec_m, model_m) == []
    spec_u, model_u, _ = _model("g1_29dof_dex3")
    km, ku = Kinematics(spec_m, model_m), Kinematics(spec_u, model_u)
    for frame in ("left_ee", "right_ee", "head_camera", "left_wrist_camera", "right_hand_index_1_link"):
        np.testing.assert_allclose(km.frame_pose(km.default_q(), frame), ku.frame_pose(ku.default_q(), frame),
                                   atol=1e-5, err_msg=frame)


def test_h1_spec_matches_the_mjcf(shared_assets):
    spec, model, res = _model("h1", shared_assets)
    assert res.origin == "shared"
    assert check_spec(spec, model) == []
    assert model.nq == 19 and not any(a.orientation for a in spec.arms)


# ----------------------------------------------------------------------------------- bad specs


def test_bad_spec_lists_every_problem_and_names_the_file(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("""
name = "Bad Name"
robot_type = "x"
[description]
format = "sdf"
file = "../r.urdf"
package = "p"
[base]
kind = "holonomic"
root_link = "r"
[[arms]]
name = "a"
root_link = "r"
tip_link = "t"
joints = ["j1"]
end_effector = "nowhere"
ee_frame = "ee"
""")
    with pytest.raises(EmbodimentError) as e:
        load_spec(path)
    msg = str(e.value)
    assert msg.startswith(str(path)) and "\n" not in msg
    for needle in ("name", "description.format", "must be relative", "holonomic base names its 3 joints"):
        assert needle in msg, needle


def test_spec_consistency_problems_collected(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text("""
extends = "%s"
name = "s"
[end_effectors.left_hand]
joints = ["a"]
""" % (Path(__file__).resolve().parents[2] / "stages/embodiment/specs/g1_29dof.toml").as_posix())
    with pytest.raises(EmbodimentError, match="open/closed need one value per joint"):
        load_spec(path)
    with pytest.raises(EmbodimentError, match="no shipped embodiment spec 'nope'"):
        load_spec("nope")


def test_check_spec_reports_wrong_chains_frames_and_limits():
    spec, model, res = _model("g1_29dof")
    arm = spec.arm("left")
    bad = spec.model_copy(update={
        "arms": (arm.model_copy(update={"joints": arm.joints[:-1]}),
                 spec.arm("right").model_copy(update={"tip_link": "left_wrist_yaw_link"})),
        "default_pose": {**spec.default_pose, "left_knee_joint": 5.0, "nonexistent_joint": 0.0},
    })
    problems = check_spec(bad, model)
    text = " | ".join(problems)
    assert "arm 'left': chain torso_link -> left_wrist_yaw_link has joints" in text
    assert "arm 'right': chain" in text
    assert "left_knee_joint = 5.0 outside its limits" in text
    assert "'nonexistent_joint' not in the description" in text
    with pytest.raises(EmbodimentError) as e:
        require_spec_matches(bad, model, res.path)
    assert str(e.value).startswith(str(res.path))


def test_missing_description_names_what_was_tried(tmp_path):
    spec = load_spec("h1")
    from pipeline.types import ItemError

    with pytest.raises(ItemError, match="robot description not found; tried .*nowhere/robots/unitree_h1"):
        resolve_description(spec.description, shared_assets=tmp_path / "nowhere")


def test_robots_job_file_is_valid():
    from pipeline import load_job

    job = load_job(Path(__file__).resolve().parents[2] / "jobs" / "robots.toml")
    (step,) = job.steps
    assert step.kind == "robots" and set(step.config.specs) <= set(shipped_specs())


def test_state_and_action_layout_per_embodiment():
    """The mobile Panda's layout is DatasetSpec's; the G1's has both arms, both hands' poses."""
    from stages.dataset.schema import DatasetSpec
    from stages.embodiment.layout import action_names, state_names

    d = DatasetSpec()
    assert state_names(load_spec("mobile_panda")) == d.state_names()
    assert action_names(load_spec("mobile_panda")) == d.action_names()
    g1 = load_spec("g1_29dof")
    s, a = state_names(g1), action_names(g1)
    assert len(s) == 14 + 2 * 7 + 3 and s[:2] == ["left_q0", "left_q1"] and "right_ee_qz" in s
    assert len(a) == 14 + 2 * 7 + 3 + 1 and "left_gripper" not in a and a[-1] == "mode"  # fixed hands
    assert {"left_gripper", "right_gripper"} <= set(action_names(load_spec("g1_29dof_dex3")))
    assert len(set(s)) == len(s) and len(set(a)) == len(a)
    # teleoperation's retargeted hands: the hand's joints in the state, their targets in the action
    for kind in ("allegro", "shadow"):
        spec = load_spec(f"mobile_panda_{kind}")
        hd = DatasetSpec(hand_joints=spec.end_effectors[spec.arms[0].end_effector].joints)
        assert state_names(spec, hand_targets=True) == hd.state_names()
        assert action_names(spec, hand_targets=True) == hd.action_names()
        assert action_names(spec) == d.action_names()  # scripted: the hand's synergy command
    dex = action_names(load_spec("g1_29dof_dex3"), hand_targets=True)
    assert "left_gripper" not in dex and len(dex) == 14 + 2 * 7 + 3 + 14 + 1


def test_panda_spec_drives_equal_robot_py_drives(tmp_path):
    """Newton builders of the same URDF: robot.add_robot's drives vs the spec's apply_drives."""
    import newton

    from stages.embodiment.drives import apply_drives
    from stages.simulate.robot import write_robot_urdf
    from stages.simulate.robot_load import add_robot

    desc = write_robot_urdf(tmp_path)
    ref = newton.ModelBuilder()
    idx = add_robot(ref, desc)
    ours = newton.ModelBuilder()
    newton.solvers.SolverMuJoCo.register_custom_attributes(ours)
    ours.add_urdf(str(desc.urdf), floating=False, enable_self_collisions=False, joint_ordering="dfs",
                  collapse_fixed_joints=False)
    joints = apply_drives(ours, load_spec("mobile_panda"))
    assert joints.dof == {n: idx.dof[n] for n in joints.dof} and set(joints.dof) == set(desc.joints)
    for name, d in joints.dof.items():
        for attr in ("joint_target_ke", "joint_target_kd", "joint_target_mode", "joint_armature",
                     "joint_effort_limit"):
            assert getattr(ours, attr)[d] == pytest.approx(getattr(ref, attr)[d]), (name, attr)
        c = joints.coord[name]
        assert ours.joint_q[c] == pytest.approx(ref.joint_q[c]) and ours.joint_target_q[c] == ref.joint_target_q[c]
    gc_ref = {b for b, v in ref.custom_attributes["mujoco:gravcomp"].values.items() if v}
    gc_ours = {b for b, v in ours.custom_attributes["mujoco:gravcomp"].values.items() if v}
    assert gc_ours == gc_ref and idx.body["panda_hand"] in gc_ours and idx.body["base_link"] not in gc_ours
