"""Mobile manipulation in the demo room: grasping a mug, opening the drawer and the door."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("newton")
pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")

from stages.simulate.control import Clik, RobotControl, move_ee, pose, top_down  # noqa: E402
from stages.simulate.demo_scene import write_demo_room  # noqa: E402
from stages.simulate.robot import write_robot_urdf  # noqa: E402
from stages.simulate.state import read_state  # noqa: E402
from stages.simulate.world import SimConfig, build_sim  # noqa: E402

PANDA = "robots/franka_panda__example_robot_data"


@pytest.fixture(scope="module")
def room(shared_assets, tmp_path_factory):
    # the real mug mesh scaled to 0.8: 66 mm across, inside the Franka hand's 80 mm stroke
    return write_demo_room(
        tmp_path_factory.mktemp("room") / "room.usda", shared_assets=shared_assets, mug_scale=0.8
    )


@pytest.fixture(scope="module")
def sim(room, shared_assets, tmp_path_factory):
    """One simulation for the module; each test puts the base where it needs it with reset()."""
    desc = write_robot_urdf(tmp_path_factory.mktemp("robot"), panda_root=shared_assets / PANDA)
    s = build_sim(
        SimConfig(scenes=(room.usd,), spawn_near=room.mug_position[:2]), desc, np.random.default_rng(0)
    )
    s.ctl, s.ik = RobotControl(s), Clik(desc)
    return s


def _reset(sim, base=None):
    sim.reset(base=base)
    sim.ctl.reset()
    return sim.ctl, sim.ik


DRAWER = "/World/Cabinet/DrawerJoint"
DOOR = "/World/Cabinet/DoorJoint"


def test_grasps_the_drawer_handle_and_opens_the_drawer_by_driving_back(sim, room):
    """Grasp the drawer's bar handle (gripper pointing at the cabinet, pitched 20 deg down,
    fingers closing vertically), then back the base away at 0.12 m/s with the arm held: the
    drawer must open by at least 80% of its 0.30 m travel and stay open after the release."""
    from scipy.spatial.transform import Rotation

    h = np.asarray(room.drawer_handle)
    ctl, ik = _reset(sim, base=(h[0] - 0.75, h[1], 0.0))
    rot = Rotation.from_euler("y", 20, degrees=True).as_matrix() @ np.stack(
        [[0, 1, 0], [0, 0, 1], [1, 0, 0]], axis=1
    ).astype(float)
    move_ee(
        sim, ctl, ik, pose(h + [-0.12, 0, 0], rot), 1.5, segments=3, settle=0.2, rng=np.random.default_rng(1)
    )
    move_ee(sim, ctl, ik, pose(h, rot), 1.0, segments=2, settle=0.2, rng=np.random.default_rng(2))
    st = read_state(sim)
    assert np.linalg.norm(np.asarray(st.robot.ee_pose.position) - h) < 0.01
    ctl.set_gripper(1.0)
    sim.step(300)
    opening = read_state(sim).robot.gripper_opening
    assert 0.01 < opening < 0.04, "the fingers did not close on the 20 mm handle bar"
    travel = room.cabinet.drawer_travel
    ctl.set_base_velocity(-0.12, 0.0, 0.0)
    sim.step(int(0.9 * travel / 0.12 / sim.settings.dt))
    ctl.set_base_velocity(0.0, 0.0, 0.0)
    sim.step(200)
    ctl.set_gripper(0.0)
    sim.step(300)
    opened = -read_state(sim).scene_joints[DRAWER]
    assert opened >= 0.8 * travel, f"drawer opened {opened:.3f} m of {travel} m"
    assert abs(read_state(sim).scene_joints[DOOR]) < 0.05


def test_grasps_the_mug_lifts_it_and_holds_it_for_2_s(sim, room):
    """Top-down grasp across the mug's body (the real mesh scaled to 0.8: 66 mm across, inside the
    Franka hand's 80 mm stroke), lift by 15 cm, hold 2 s: the mug rises with the hand and neither
    slips nor drops while held."""
    ctl, ik = _reset(sim)  # the free spawn pose nearest the mug, facing it
    mug0 = np.asarray(read_state(sim).objects["/World/Mug"].position)
    grasp = mug0 + [0.0, 0.0, 0.084 - 0.025]  # pads 25 mm below the rim
    rot = top_down(0.0)  # fingers close along world y, the handle (+x) stays clear
    move_ee(sim, ctl, ik, pose(grasp + [0, 0, 0.12], rot), 1.5, segments=3, settle=0.2)
    move_ee(sim, ctl, ik, pose(grasp, rot), 1.0, segments=2, settle=0.3)
    ctl.set_gripper(1.0)
    sim.step(400)
    st = read_state(sim)
    assert 0.055 < st.robot.gripper_opening < 0.07, "the fingers are not on the 66 mm body"
    move_ee(sim, ctl, ik, pose(grasp + [0, 0, 0.15], rot), 1.5, segments=3)
    z_lift = read_state(sim).objects["/World/Mug"].position[2]
    assert z_lift > mug0[2] + 0.12, "the mug was not lifted"
    zs, offsets = [], []
    for _ in range(10):
        sim.step(int(0.2 / sim.settings.dt))
        st = read_state(sim)
        zs.append(st.objects["/World/Mug"].position[2])
        offsets.append(np.subtract(st.objects["/World/Mug"].position, st.robot.ee_pose.position))
    assert sim.settings.dt * 10 * int(0.2 / sim.settings.dt) >= 2.0 - 1e-9
    assert min(zs) > mug0[2] + 0.12, "the mug dropped while held"
    assert np.ptp(np.array(offsets), axis=0).max() < 0.005, "the mug slipped in the hand"


def test_grasps_the_door_handle_and_swings_the_door_open(sim, room):
    """Grasp the door's vertical bar (gripper pitched 35 deg down, fingers closing horizontally),
    then carry the handle along the door's arc in 6 deg steps, the gripper turning with the door
    (CLIK per step): the door opens by at least 80% of its 90 deg range and stays open after the
    release."""
    from scipy.spatial.transform import Rotation

    h, hinge = np.asarray(room.door_handle), np.asarray(room.door_hinge)
    # a base pose from which the whole arc is reachable without the door hitting the chassis
    ctl, ik = _reset(sim, base=(hinge[0] - 0.655, hinge[1] - 0.58, 0.3))
    rng = np.random.default_rng(1)
    grip = Rotation.from_euler("y", 35, degrees=True).as_matrix() @ np.stack(
        [[0, 0, -1], [0, 1, 0], [1, 0, 0]], axis=1
    ).astype(float)

    def handle_pose(theta: float, back: float = 0.0) -> np.ndarray:
        rz = Rotation.from_euler("z", theta).as_matrix()
        p = hinge + rz @ (h - hinge)
        p[2] = h[2]
        rot = rz @ grip
        return pose(p - back * rot[:, 2], rot)

    move_ee(sim, ctl, ik, handle_pose(0.0, 0.12), 1.5, segments=3, settle=0.2, rng=rng)
    move_ee(sim, ctl, ik, handle_pose(0.0), 1.0, segments=2, settle=0.2, rng=rng)
    ctl.set_gripper(1.0)
    sim.step(300)
    assert 0.015 < read_state(sim).robot.gripper_opening < 0.03, "the fingers did not close on the bar"
    for theta in np.deg2rad(np.arange(-6, -87, -6)):
        move_ee(sim, ctl, ik, handle_pose(theta), 0.4, rng=rng)
    ctl.set_gripper(0.0)
    sim.step(300)
    door = read_state(sim).scene_joints[DOOR]
    assert -door >= 0.8 * room.cabinet.door_range, f"door opened {np.rad2deg(-door):.1f} deg"
    assert abs(read_state(sim).scene_joints[DRAWER]) < 0.02


@pytest.mark.slow
def test_robotiq_2f85_grasps_the_full_size_mug(shared_assets, tmp_path):
    """The alternative gripper (2F-85 as a parallel approximation, 85 mm stroke) takes the real,
    unscaled 82 mm mug across its body, lifts it 15 cm and holds it 2 s. Slow (own simulation)."""
    room = write_demo_room(tmp_path / "room.usda", shared_assets=shared_assets)
    desc = write_robot_urdf(
        tmp_path,
        gripper="robotiq_2f85",
        panda_root=shared_assets / PANDA,
        robotiq_root=shared_assets / "robots/robotiq_2f85__menagerie",
    )
    sim = build_sim(
        SimConfig(scenes=(room.usd,), spawn_near=room.mug_position[:2]), desc, np.random.default_rng(0)
    )
    ctl, ik = RobotControl(sim), Clik(desc)
    mug0 = np.asarray(read_state(sim).objects["/World/Mug"].position)
    grasp = mug0 + [0.0, 0.0, 0.105 - 0.03]
    move_ee(sim, ctl, ik, pose(grasp + [0, 0, 0.12], top_down(0.0)), 1.5, segments=3, settle=0.2)
    move_ee(sim, ctl, ik, pose(grasp, top_down(0.0)), 1.0, segments=2, settle=0.3)
    ctl.set_gripper(1.0)
    sim.step(400)
    assert 0.075 < read_state(sim).robot.gripper_opening < 0.085
    move_ee(sim, ctl, ik, pose(grasp + [0, 0, 0.15], top_down(0.0)), 1.5, segments=3)
    zs = []
    for _ in range(10):
        sim.step(int(0.2 / sim.settings.dt))
        zs.append(read_state(sim).objects["/World/Mug"].position[2])
    assert min(zs) > mug0[2] + 0.12
