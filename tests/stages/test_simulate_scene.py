"""The robot in a furnished room: driving into walls, free spawn, state, and cameras."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("newton")
pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")

from stages.simulate.control import RobotControl  # noqa: E402
from stages.simulate.demo_scene import write_demo_room  # noqa: E402
from stages.simulate.robot import write_robot_urdf  # noqa: E402
from stages.simulate.sensors import (  # noqa: E402
    CameraRig,
    CameraSpec,
    colorize_labels,
    depth_to_png,
    look_at,
    robot_cameras,
)
from stages.simulate.state import read_state  # noqa: E402
from stages.simulate.world import SimConfig, build_sim, find_free_spawn  # noqa: E402

PANDA = "robots/franka_panda__example_robot_data"


@pytest.fixture(scope="module")
def room(shared_assets, tmp_path_factory):
    return write_demo_room(tmp_path_factory.mktemp("room") / "room.usda", shared_assets=shared_assets)


@pytest.fixture(scope="module")
def desc(shared_assets, tmp_path_factory):
    return write_robot_urdf(tmp_path_factory.mktemp("robot"), panda_root=shared_assets / PANDA)


@pytest.fixture(scope="module")
def sim(room, desc):
    s = build_sim(SimConfig(scenes=(room.usd,), spawn=(1.0, 1.0, 0.0)), desc, np.random.default_rng(0))
    s.ctl = RobotControl(s)
    return s


def _collider_bodies(sim) -> np.ndarray:
    """Robot bodies with collision geometry (camera and TCP frames are massless markers)."""
    import newton

    flags = sim.model.shape_flags.numpy()
    shape_body = sim.model.shape_body.numpy()
    return np.array(
        sorted(
            {
                int(shape_body[s])
                for s in range(sim.robot.shape_start, sim.robot.shape_end)
                if flags[s] & int(newton.ShapeFlags.COLLIDE_SHAPES)
            }
        )
    )


def test_drives_across_a_generated_room_and_is_stopped_by_the_wall(desc, tmp_path):
    """A room from the layout stage (walls, floor, ceiling, windows as USD colliders): the robot
    spawns at the free pose nearest the west wall, is commanded 0.8 m/s east for 8 s, crosses the
    room and stops at the east wall: the chassis stays inside the wall's inner face and no robot
    body ever gets past the wall (the arm may reach into a window recess up to its pane)."""
    import newton

    from stages.layout.build import generate_layout
    from stages.layout.spec import LayoutSpec
    from stages.simulate.world import load_scene, shape_footprints

    layout = generate_layout(LayoutSpec(rooms={"living_room": 1}), 3, tmp_path / "layout")
    probe = newton.ModelBuilder()
    scene = load_scene(probe, layout.usd)
    boxes, idx = shape_footprints(probe)
    walls = boxes[[k for k, i in enumerate(idx) if scene.shape_label[i] == "wall"]]
    lo, hi = walls[:, :2].min(0), walls[:, 2:].max(0)
    x0, y0, _ = find_free_spawn(
        probe, np.random.default_rng(0), radius=0.5, near=(lo[0], (lo[1] + hi[1]) / 2)
    )
    sim = build_sim(SimConfig(scenes=(layout.usd,), spawn=(x0, y0, 0.0)), desc, np.random.default_rng(0))
    ctl = RobotControl(sim)
    # the inner face of the first wall east of the robot, across the robot's width
    band = (walls[:, 1] < y0 + 0.5) & (walls[:, 3] > y0 - 0.5) & (walls[:, 0] > x0)
    wall_x = float(walls[band, 0].min())
    wall_out = float(walls[band & (walls[:, 0] < wall_x + 0.3), 2].min())  # its outer face
    assert wall_x - x0 > 2.5, "the generated room is too small to drive across"
    bodies = _collider_bodies(sim)
    assert len(bodies) >= 12
    ctl.set_base_velocity(0.8, 0.0, 0.0)
    max_x = -np.inf
    for _ in range(80):
        sim.step(50)
        max_x = max(max_x, float(sim.state_0.body_q.numpy()[bodies, 0].max()))
    st = read_state(sim, contacts=True)
    half = sim.desc.base.chassis[0] / 2
    assert st.robot.base.x > x0 + 2.0, "the base did not cross the room"
    assert st.robot.base.x + half < wall_x + 0.01, "the chassis went through the wall"
    assert st.robot.base.x + half > wall_x - 0.4, "the base stopped short of the wall"
    assert max_x < wall_out, f"a robot body reached x={max_x} past the wall ({wall_x}..{wall_out})"
    assert abs(st.robot.base.y - y0) < 0.05 and abs(st.robot.base.theta) < 0.05
    assert abs(st.robot.qd[0]) < 0.05, "the base is still moving into the wall"
    assert any({"wall", "robot"} == {c.label_a, c.label_b} for c in st.contacts)
    # and it drives back when told to
    ctl.set_base_velocity(-0.5, 0.0, 0.0)
    sim.step(250)
    assert read_state(sim).robot.base.x < st.robot.base.x - 0.15


def test_base_velocity_is_in_the_base_frame(sim):
    sim.reset()
    sim.ctl.set_base_velocity(0.0, 0.0, 0.8)
    sim.step(250)  # turn ~ 0.4 rad
    theta = read_state(sim).robot.base.theta
    assert 0.25 < theta < 0.5
    x0, y0 = read_state(sim).robot.base.x, read_state(sim).robot.base.y
    sim.ctl.set_base_velocity(0.4, 0.0, 0.0)
    sim.step(500)
    st = read_state(sim)
    heading = np.arctan2(st.robot.base.y - y0, st.robot.base.x - x0)
    assert abs(heading - st.robot.base.theta) < 0.05, "forward is not along the base's heading"
    sim.ctl.set_base_velocity(0.0, 0.0, 0.0)


def test_free_spawn_is_clear_of_every_obstacle(room, desc):
    import newton

    b = newton.ModelBuilder()
    b.add_usd(str(room.usd))
    rng = np.random.default_rng(11)
    from stages.simulate.world import shape_footprints

    boxes, _ = shape_footprints(b)
    for _ in range(5):
        x, y, _yaw = find_free_spawn(b, rng, radius=0.45)
        assert 0.45 <= x <= room.size[0] - 0.45 and 0.45 <= y <= room.size[1] - 0.45
        dx = np.maximum(np.maximum(boxes[:, 0] - x, x - boxes[:, 2]), 0)
        dy = np.maximum(np.maximum(boxes[:, 1] - y, y - boxes[:, 3]), 0)
        assert np.all(np.hypot(dx, dy) > 0.45)
    x, y, yaw = find_free_spawn(b, rng, radius=0.45, near=(3.0, 3.0))
    assert np.hypot(x - 3.0, y - 3.0) < 0.9 and abs(np.cos(yaw - np.arctan2(3.0 - y, 3.0 - x)) - 1) < 1e-6


def test_state_reports_robot_objects_and_settings(sim, room):
    sim.reset()
    sim.step(10)
    st = read_state(sim)
    assert st.robot.joint_names[:3] == ("base_x", "base_y", "base_yaw")
    assert st.robot.q.shape == (12,) and st.robot.qd.shape == (12,)
    np.testing.assert_allclose(st.robot.q[3:10], sim.desc.arm_home, atol=0.02)
    assert abs(st.robot.gripper_opening - 0.08) < 0.01
    assert st.robot.ee_pose.position[2] > 0.3
    mug = st.objects["/World/Mug"]
    np.testing.assert_allclose(mug.position[:2], room.mug_position[:2], atol=0.01)
    assert set(st.scene_joints) == {"/World/Cabinet/DrawerJoint", "/World/Cabinet/DoorJoint"}
    js = sim.settings.to_json()
    assert js["solver"] == "mujoco" and js["dt"] == 0.002 and js["world_count"] == 1
    assert js["options"]["integrator"] == "implicitfast"


def _backproject(frame, v: int = 0) -> np.ndarray:
    """World points (H, W, 3) of every pixel from planar depth, intrinsics and extrinsics."""
    k = frame.intrinsics
    h, w = frame.depth.shape[1:]
    u, vv = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    d = frame.depth[v]
    pc = np.stack([(u - k.cx) / k.fx * d, -(vv - k.cy) / k.fy * d, -d, np.ones_like(d)], axis=-1)
    return (pc @ frame.extrinsics[v].T)[..., :3]


def test_camera_frames_agree_with_the_geometry(sim, room, desc, tmp_path):
    """Writes RGB, depth and segmentation PNGs of the head, wrist and a third-person camera, then
    checks each labelled pixel's back-projected depth lands on that object's geometry."""
    from PIL import Image

    sim.reset()
    sim.step(5)
    third = CameraSpec(
        name="third", width=160, height=120, vertical_fov=1.0, pose=look_at((0.4, 0.4, 2.2), (3.0, 3.0, 0.4))
    )
    rig = CameraRig(sim, robot_cameras(desc) + [third])
    frames = rig.render()
    out = Path(os.environ.get("AGENTWORLD_TEST_ARTIFACTS", tmp_path))
    out.mkdir(parents=True, exist_ok=True)
    for name, f in frames.items():
        labels = f.labels(sim.shape_label)[0]
        Image.fromarray(f.rgb[0]).save(out / f"{name}_rgb.png")
        Image.fromarray(depth_to_png(f.depth[0])).save(out / f"{name}_depth.png")
        Image.fromarray(colorize_labels(labels)).save(out / f"{name}_seg.png")
        assert (out / f"{name}_rgb.png").stat().st_size > 500
        assert f.rgb[0].std() > 10, f"{name}: flat image"
    f = frames["third"]
    labels = f.labels(sim.shape_label)[0]
    pts = _backproject(f)
    for lab in ("floor", "wall", "table", "robot", "cabinet", "mug"):
        assert (labels == lab).sum() > 3, f"third-person view shows no {lab}"
    floor = pts[labels == "floor"]
    assert np.abs(floor[:, 2]).max() < 0.01
    wall = pts[labels == "wall"]
    dist = np.min(
        np.abs(np.stack([wall[:, 0], wall[:, 0] - room.size[0], wall[:, 1], wall[:, 1] - room.size[1]])),
        axis=0,
    )
    assert np.percentile(dist, 99) < 0.01
    tab = pts[labels == "table"]
    c, s = np.asarray(room.table.center), np.asarray(room.table.size)
    assert np.all(tab[:, :2] >= c[:2] - s[:2] / 2 - 0.01) and np.all(tab[:, :2] <= c[:2] + s[:2] / 2 + 0.01)
    assert tab[:, 2].max() < c[2] + s[2] / 2 + 0.01
    mug = pts[labels == "mug"]
    assert np.linalg.norm(mug[:, :2] - np.asarray(room.mug_position[:2]), axis=1).max() < 0.08
    # the head camera looks over the base and sees the robot's own arm and the floor
    head_labels = frames["head"].labels(sim.shape_label)[0]
    assert (head_labels == "robot").any() and (head_labels == "floor").any()
    # extrinsics: the head camera rides on the mast above the base
    st = read_state(sim)
    e = frames["head"].extrinsics[0]
    assert e[2, 3] > 1.2 and np.hypot(e[0, 3] - st.robot.base.x, e[1, 3] - st.robot.base.y) < 0.35
    assert np.allclose(
        frames["head"].extrinsics_opencv()[0] @ np.append(e[:3, 3], 1.0), [0, 0, 0, 1], atol=1e-6
    )
    assert rig.lights_used and rig.lights_used[0].source == "/World/Lights/Sun"
    # the recorded calibration projects the mug's centre onto a mug pixel at its depth
    cal = f.calibration(0)
    assert set(cal.to_json()) >= {"fx", "fy", "cx", "cy", "camera_to_world_gl", "world_to_camera_cv"}
    centre = np.asarray(room.mug_position) + [0.0, 0.0, 0.03]
    u, v, d = cal.project(centre)
    assert labels[int(v), int(u)] == "mug"
    assert abs(f.depth[0][int(v), int(u)] - d) < 0.06


def test_recording_saves_the_scene_with_the_robot_as_usd(sim, tmp_path):
    """A USD recording of a short drive holds every shape, and the robot's prims move +x."""
    from pxr import Usd, UsdGeom

    from stages.simulate.record import UsdRecorder

    sim.reset()
    sim.ctl.set_base_velocity(0.5, 0.0, 0.0)
    path = tmp_path / "episode.usda"
    with UsdRecorder(sim, path, fps=10) as rec:
        for _ in range(6):
            rec.frame()
            sim.step(50)
    sim.ctl.set_base_velocity(0.0, 0.0, 0.0)
    assert rec.frames == 6 and path.is_file()
    stage = Usd.Stage.Open(str(path))
    assert stage.GetEndTimeCode() >= 5
    moved = []
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Xformable):
            continue
        xf = UsdGeom.Xformable(prim)
        m0 = np.array(xf.ComputeLocalToWorldTransform(0.0))
        m5 = np.array(xf.ComputeLocalToWorldTransform(stage.GetEndTimeCode()))
        if np.abs(m5[3, :3] - m0[3, :3]).max() > 1e-4:
            moved.append(m5[3, 0] - m0[3, 0])
    # the base, mast, arm links and hand shapes all travel about 0.5 m/s x 0.5 s
    assert len(moved) >= 10
    assert np.median(moved) > 0.15


@pytest.mark.slow
def test_two_worlds_are_independent(room, desc):
    """Two replicated worlds (MuJoCo-Warp, here on CPU; slow: its CPU kernels compile for minutes
    on a cold cache): a base command to world 0 moves only world 0's robot, per-world state and
    per-world camera frames follow."""
    sim2 = build_sim(
        SimConfig(scenes=(room.usd,), world_count=2, spawn=(1.0, 1.0, 0.0)), desc, np.random.default_rng(0)
    )
    ctl = RobotControl(sim2)
    ctl.set_base_velocity(0.5, 0.0, 0.0, world=0)
    sim2.step(200)
    s0, s1 = read_state(sim2, world=0), read_state(sim2, world=1)
    assert s0.robot.base.x > 1.1 and abs(s1.robot.base.x - 1.0) < 0.01
    assert len(sim2.shape_label) == 2 * sim2.shapes_per_world
    frames = CameraRig(sim2, robot_cameras(desc)[:1]).render()
    head = frames["head"]
    assert head.rgb.shape[0] == 2 and not np.array_equal(head.depth[0], head.depth[1])
    np.testing.assert_allclose(
        head.extrinsics[0, 0, 3] - head.extrinsics[1, 0, 3], s0.robot.base.x - s1.robot.base.x, atol=1e-4
    )


def test_usd_lights_map_photometrically(tmp_path):
    """UsdLux lights authored in lux/nits (the scene stage's convention) map to renderer lights:
    auto exposure on the indoor illuminance, a sun capped, local falloff matched at 2 m."""
    from pxr import Usd, UsdGeom, UsdLux

    from stages.simulate.sensors import (
        DIRECTIONAL,
        DISTANT_CAP,
        POINT,
        REFERENCE_DISTANCE,
        auto_exposure_lux,
        map_lights,
        read_usd_lights,
    )

    stage = Usd.Stage.CreateInMemory()
    UsdGeom.Xform.Define(stage, "/W")
    sphere = UsdLux.SphereLight.Define(stage, "/W/Lamp")
    sphere.CreateRadiusAttr(0.1)
    # 400 lux at 2 m: I = E d^2 = 1600 cd = L pi r^2
    sphere.CreateIntensityAttr(1600.0 / (np.pi * 0.01))
    UsdGeom.Xformable(sphere).AddTranslateOp().Set((1.0, 2.0, 2.5))
    sun = UsdLux.DistantLight.Define(stage, "/W/Sun")
    sun.CreateIntensityAttr(4000.0)
    sun.CreateExposureAttr(1.0)  # 8000 lux
    dome = UsdLux.DomeLight.Define(stage, "/W/Sky")
    dome.CreateIntensityAttr(100.0 / np.pi)  # 100 lux
    lights = read_usd_lights(stage)
    by_kind = {lt.kind: lt for lt in lights}
    assert by_kind["SphereLight"].illuminance == pytest.approx(400.0, rel=1e-4)
    assert by_kind["DistantLight"].illuminance == pytest.approx(8000.0)
    assert by_kind["DomeLight"].illuminance == pytest.approx(100.0, rel=1e-4)
    assert auto_exposure_lux(lights) == pytest.approx(500.0, rel=1e-4)
    mapped, sky = map_lights(lights)
    kinds = {m.source: m for m in mapped}
    assert kinds["/W/Sun"].type == DIRECTIONAL and kinds["/W/Sun"].cast_shadow
    assert max(kinds["/W/Sun"].color) == pytest.approx(DISTANT_CAP)
    np.testing.assert_allclose(kinds["/W/Sun"].direction, (0, 0, -1), atol=1e-6)
    lamp = kinds["/W/Lamp"]
    assert lamp.type == POINT and lamp.position == pytest.approx((1.0, 2.0, 2.5))
    # renderer falloff 1 / (1 + 0.02 d^2) at 2 m gives 400/500 of white
    assert lamp.color[0] / (1 + 0.02 * REFERENCE_DISTANCE**2) == pytest.approx(0.8, rel=1e-4)
    np.testing.assert_allclose(sky, [0.2, 0.2, 0.2], rtol=1e-4)
