"""The dual-arm double-door task's geometry and success predicate (stages/demos/double_door.py):
doors assigned to the arms by their handles' side, the handle's path as a door swings about its
hinge, and success only when both joint angles pass 70 degrees."""

from __future__ import annotations

import math

import numpy as np
import pytest


def _wardrobe_record():
    """A two-door record in the shape of the catalog's wardrobe_01 (handles 5 cm either side of the
    middle, hinges 0.45 m out; door_0 at -Y opening about -Z, door_1 at +Y about +Z)."""
    info = {"asset_id": "wardrobe_x", "handles": [
        {"bar_axis": [0.0, 0.0, 1.0], "center": [0.352, -0.05, 1.05], "link": "door_0", "kind": "bar"},
        {"bar_axis": [0.0, 0.0, 1.0], "center": [0.352, 0.05, 1.05], "link": "door_1", "kind": "bar"}]}
    joints = {"door_0_joint": (np.array([0.315, -0.455, 0.98]), -1.0),
              "door_1_joint": (np.array([0.315, 0.455, 0.98]), 1.0)}
    return info, joints


def test_doors_go_to_the_arm_on_their_side_when_the_wardrobe_faces_the_robot():
    """Turned 180 deg to face the robot, the asset's door_1 (+Y in the asset) lands at -Y: the right
    arm's; each door opens towards the robot (its handle's x falls as the door swings)."""
    from stages.demos.double_door import doors_of, handle_on_swing

    info, joints = _wardrobe_record()
    doors = doors_of(info, joints, (1.0, 0.0, 0.0), math.pi)
    assert doors["left"].body.endswith("door_0") and doors["right"].body.endswith("door_1")
    assert doors["left"].handle == pytest.approx([0.648, 0.05, 1.05])
    assert doors["left"].hinge[:2] == pytest.approx([0.685, 0.455])
    for arm, d in doors.items():
        r = np.linalg.norm(d.handle[:2] - d.hinge[:2])
        p70 = handle_on_swing(d, math.radians(70.0))
        assert np.linalg.norm(p70[:2] - d.hinge[:2]) == pytest.approx(r)   # on the circle about the hinge
        assert p70[0] < d.handle[0] - 0.3, arm                             # swung out towards the robot
        assert abs(p70[1]) > abs(d.handle[1]), arm                          # and towards its own side
        assert p70[2] == d.handle[2]


def test_a_record_without_two_vertical_handles_is_refused():
    from stages.demos.double_door import doors_of

    info, joints = _wardrobe_record()
    info["handles"] = info["handles"][:1]
    with pytest.raises(ValueError, match="two hinged doors"):
        doors_of(info, joints, (0.0, 0.0, 0.0), math.pi)


def test_success_needs_both_doors_past_70_degrees():
    from stages.demos.double_door import judge_doors

    r = math.radians
    assert judge_doors({"left": r(75.0), "right": r(88.0)})[:2] == (True, "")
    assert judge_doors({"left": r(69.0), "right": r(88.0)})[:2] == (False, "left_door_shut")
    assert judge_doors({"left": r(80.0), "right": r(10.0)})[:2] == (False, "right_door_shut")
    ok, reason, detail = judge_doors({"left": 0.0, "right": r(5.0)})
    assert (ok, reason, detail["door_deg"]["right"]) == (False, "doors_shut", 5.0)
    with pytest.raises(ValueError, match="expected"):
        judge_doors({"left": 1.5})


def _door_frame(door, p, angle):
    """(along, front) [m] of point ``p`` in the frame of ``door`` opened ``angle`` [rad]: along the
    door from its hinge line, and off its front face (negative: behind it)."""
    from stages.demos.double_door import _turn

    a = door.opening * angle
    u = _turn(np.array([0.0, -np.sign(door.hinge[1]), 0.0]), a)
    front = _turn(np.array([-1.0, 0.0, 0.0]), a)
    r = np.asarray(p, float) - door.hinge
    return float(r @ u), float(r @ front)


@pytest.mark.parametrize("from_deg", [None, 38.0])
def test_door_plan_pulls_along_the_handle_then_pushes_the_back_of_the_door(from_deg):
    """The expert's waypoints per arm: the pull on the handle's circle up to PULL_DEG with the
    fingers into the door's front; going round past the free edge (in front, then behind it); the
    push behind the back face, its last at PUSH_DEG; the gripper pointing down for the push."""
    from stages.demos.double_door import (DOOR_THICKNESS, PULL_DEG, PUSH_DEG, door_plan, doors_of,
                                          handle_on_swing)

    info, joints = _wardrobe_record()
    doors = doors_of(info, joints, (1.05, 0.0, 0.0), math.pi)
    for arm, d in doors.items():
        plan = door_plan(d, from_deg=from_deg)
        a0 = math.radians(PULL_DEG if from_deg is None else from_deg)
        width = float(np.linalg.norm((d.handle - d.hinge)[:2])) + 0.05   # the wardrobe's doors: 45.5 cm
        assert plan.grasp[:3, 3] == pytest.approx(d.handle)
        assert plan.pull[-1][:3, 3] == pytest.approx(handle_on_swing(d, math.radians(PULL_DEG)))
        for k, p in enumerate(plan.pull):
            along, front = _door_frame(d, p[:3, 3], math.radians(PULL_DEG) * (k + 1) / len(plan.pull))
            assert front == pytest.approx(0.037, abs=1e-3) and along == pytest.approx(0.405, abs=1e-3), arm
            assert p[:3, 2] @ _door_frame_normal(d, math.radians(PULL_DEG) * (k + 1) / len(plan.pull)) > 0.999
        along, front = _door_frame(d, plan.around[:3, 3], a0)
        assert along > width and front > 0.03, arm                        # before the door, past its edge
        along, front = _door_frame(d, plan.past[:3, 3], a0)
        assert along > width and front < -DOOR_THICKNESS, arm              # behind it, past its edge
        for p, a in zip(plan.push, np.linspace(a0, math.radians(PUSH_DEG), len(plan.push) + 1)[1:], strict=True):
            along, front = _door_frame(d, p[:3, 3], a)
            assert front < -DOOR_THICKNESS - 0.01 and along < width - 0.04, arm  # on the door, off its edge
            assert p[2, 2] == pytest.approx(-1.0)                            # pointing down
        assert _door_frame(d, plan.push[-1][:3, 3], math.radians(PUSH_DEG))[1] < -DOOR_THICKNESS


def _door_frame_normal(door, angle):
    """The unit vector (3,) into the door's front face opened ``angle`` [rad]."""
    from stages.demos.double_door import _turn

    return _turn(np.array([1.0, 0.0, 0.0]), door.opening * angle)


def test_the_double_door_pair_needs_the_wardrobe(tmp_path):
    """record-table's aloha/open_double_door pair names its package (wardrobe_01) and refuses to
    build without it."""
    from stages.demos.table_tasks import PACKAGES, PAIRS, build_rig

    assert "aloha/open_double_door" in PAIRS and PACKAGES["open_double_door"] == "wardrobe_01"
    with pytest.raises(ValueError, match="wardrobe_01"):
        build_rig("aloha/open_double_door", tmp_path, assets={})


@pytest.mark.slow  # ~3 min on 2 shared cores (the wardrobe's catalog job, building the rig, one episode)
@pytest.mark.xfail(reason="session 14: the doors are pulled to 49.8 deg, but reaching behind them the forearm "
                          "presses the door's front (44-48 deg at the end); the expert is not finished", strict=False)
def test_both_arms_open_the_wardrobe_doors_past_70_degrees(tmp_path, shared_assets):
    """One real episode of aloha/open_double_door (record-table seed 0 episode 0): each arm pulls its
    door open by the handle, goes round its free edge and pushes it on from behind; both doors end
    at least 70 deg open."""
    pytest.importorskip("newton")
    from stages.demos.table_record import catalog_assets
    from stages.demos.table_tasks import PAIRS, build_rig, run_expert

    pair = "aloha/open_double_door"
    assets = catalog_assets(tmp_path, None, ["wardrobe_01"])
    rig = build_rig(pair, tmp_path / "rig", assets=assets, shared_assets=shared_assets)
    out = run_expert(rig, rig.reset(np.random.default_rng([0, 0, PAIRS.index(pair)])))
    assert out.success, out
    assert min(out.detail["pulled_deg"].values()) > 40.0
    assert min(out.detail["door_deg"].values()) >= 70.0
