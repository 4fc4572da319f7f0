"""Dexterous hands on the mobile Panda: the specs match what robot.py builds, and each hand lifts
a catalog mug and can with the grasp synthesis and holds them 2 s in Newton (MuJoCo solver)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("newton")
pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")

HANDS = ("allegro", "shadow")


@pytest.mark.parametrize("kind", HANDS)
def test_hand_spec_describes_what_robot_py_builds(tmp_path, shared_assets, kind):
    """The spec mobile_panda_<hand> names robot.py's joints, synergy, TCP and drives, and checks
    clean against the URDF it writes (chains, TCP at ee_xyz/ee_rpy, postures inside the limits)."""
    from stages.embodiment.kinematics import build_model, check_spec
    from stages.embodiment.spec import EndEffectorKind, load_spec
    from stages.simulate.robot import write_robot_urdf

    desc = write_robot_urdf(tmp_path, gripper=kind, shared_assets=shared_assets)
    hand = desc.gripper.hand
    spec = load_spec(f"mobile_panda_{kind}")
    (arm,) = spec.arms
    ee = spec.end_effectors[arm.end_effector]
    assert ee.kind == EndEffectorKind.HAND
    assert spec.actuated_joints == desc.joints and ee.joints == hand.joints
    assert len(ee.joints) == {"allegro": 16, "shadow": 22}[kind]
    assert (ee.open, ee.closed) == (hand.open, hand.closed) and ee.mount_link == hand.palm_link
    assert arm.ee_frame == desc.ee_frame == hand.tcp and arm.ee_xyz[2] == hand.tcp_z
    for j, effort in zip(hand.joints, hand.drive.effort, strict=True):
        d = spec.drive_for(j)
        assert (d.kp, d.kd, d.armature, d.effort_limit) == (hand.drive.kp, hand.drive.kd, hand.drive.armature, effort)
    assert check_spec(spec, build_model(spec, desc.urdf)) == []
    # the synergy: command 0 / 1 gives the open / closed postures, halfway between in the middle
    np.testing.assert_allclose(desc.gripper.finger_targets(0.0), hand.open)
    np.testing.assert_allclose(desc.gripper.finger_targets(1.0), hand.closed)
    np.testing.assert_allclose(desc.gripper.finger_targets(0.5), (np.array(hand.open) + hand.closed) / 2)


@pytest.fixture(scope="module")
def packages(kitchen_catalog) -> dict:
    """The mug and can of the session's kitchen catalog (tests/stages/conftest.py: generated and
    ingested by the real catalog and ingest steps; the default catalog's variants do not depend on
    which categories a job selects)."""
    from stages.demos.packages import CatalogAsset

    out = kitchen_catalog
    info = json.loads((out / "catalog" / "default" / "generated.json").read_text())
    return {a.category: a for a in (CatalogAsset(asset_id=i, category=info[i]["category"],
                                                 usd=out / "assets" / i / f"{i}.usda", info=info[i])
                                    for i in ("mug_04", "can_00"))}


def lift_and_hold(kind: str, asset, shared_assets: Path, tmp: Path, *, lift: float = 0.10) -> dict:
    """Grasp ``asset`` from a 0.55 m table with hand ``kind`` (grasp synthesis: shape fit, top
    power grasp, closing synergy until contact), lift it ``lift`` [m] and hold it 2 s; returns
    the figures: fitted radius, contact command, lift [m] after the lift and after 2 s, slip [m]
    (change of the object's position relative to the TCP over the 2 s), fingers touching."""
    from stages.demos import hand_grasps as hg
    from stages.demos.hand_scene import write_table_scene
    from stages.simulate.control import Clik, RobotControl, move_ee
    from stages.simulate.robot import write_robot_urdf
    from stages.simulate.world import SimConfig, build_sim

    scene = write_table_scene(tmp / "scene.usda", asset, table_xy=(0.95, 0.0), object_xy=(0.72, 0.0))
    desc = write_robot_urdf(tmp / "robot", gripper=kind, shared_assets=shared_assets)
    sim = build_sim(SimConfig(scenes=(scene.usd,), spawn=(0.0, 0.0, 0.0)), desc, np.random.default_rng(0))
    ctl, ik, hand = RobotControl(sim), Clik(desc), desc.gripper.hand
    body = sim.body_of_path(scene.body)
    sim.step(50)
    shape = hg.fit_upright(hg.object_points(sim, body))
    plan = hg.plan_top_grasp(shape, hand, sim.spawn[:2])
    move_ee(sim, ctl, ik, plan.pre_grasp, 2.0, segments=4, settle=0.2)
    move_ee(sim, ctl, ik, plan.grasp, 1.0, segments=2, settle=0.2)
    z0 = float(sim.state_0.body_q.numpy()[body][2])
    closing = hg.close_until_contact(sim, ctl, hand, body)
    up = plan.grasp.copy()
    up[2, 3] += lift
    move_ee(sim, ctl, ik, up, 1.5, segments=3)

    def rel():
        bq = sim.state_0.body_q.numpy()
        return bq[body][:3] - bq[sim.world_body(hand.tcp)][:3]

    z1, r1 = float(sim.state_0.body_q.numpy()[body][2]), rel()
    sim.step(int(round(2.0 / sim.settings.dt)))
    z2, r2 = float(sim.state_0.body_q.numpy()[body][2]), rel()
    return {"radius": shape.radius, "handle": shape.handle, "contact_command": closing.contact_command,
            "lift": z1 - z0, "lift_2s": z2 - z0, "slip": float(np.linalg.norm(r2 - r1)),
            "touching": hg.contact_fingers(sim, hand, body)}


def _check(fig: dict, asset) -> None:
    assert fig["radius"] == pytest.approx(asset.params["radius"], abs=0.004), "shape fit: wrong radius"
    assert fig["contact_command"] is not None, "the contact check never passed while closing"
    assert fig["lift"] >= 0.05, f"lifted only {fig['lift']:.3f} m"
    assert fig["lift_2s"] >= 0.05, f"dropped within 2 s (lift {fig['lift_2s']:.3f} m)"
    assert fig["slip"] < 0.01, f"slipped {fig['slip']:.4f} m in 2 s"
    from stages.demos.hand_grasps import is_held

    assert is_held(fig["touching"]), f"not held after 2 s: touching {sorted(fig['touching'])}"


@pytest.mark.parametrize("kind", HANDS)
def test_hand_lifts_a_can_and_holds_it_2_s(kind, packages, shared_assets, tmp_path):
    """Fast check of the issue's first Done-when item, per hand: a catalog can (76 mm across,
    124 mm tall) lifted 10 cm by a top power grasp stays in the hand for 2 s."""
    fig = lift_and_hold(kind, packages["can"], shared_assets, tmp_path)
    print(kind, "can", {k: v for k, v in fig.items() if k != "handle"})
    _check(fig, packages["can"])


@pytest.mark.parametrize("kind", HANDS)
def test_hand_lifts_a_mug_by_its_body_and_holds_it_2_s(kind, packages, shared_assets, tmp_path):
    """The same with the catalog mug (73 mm body, a loop handle): the shape fit finds the handle
    and the grasp keeps it across the fingers."""
    fig = lift_and_hold(kind, packages["mug"], shared_assets, tmp_path)
    print(kind, "mug", {k: v for k, v in fig.items() if k != "handle"})
    assert fig["handle"] is not None and abs(fig["handle"][1]) > 0.99   # mug_04's handle: +y
    _check(fig, packages["mug"])
