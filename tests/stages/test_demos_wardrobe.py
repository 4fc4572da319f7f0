"""Organize the wardrobe (issue 16, ``stages.demos.skill_wardrobe``, task file
``stages/demos/multistage/organize_wardrobe.toml``): the catalog's wardrobe has two revolute doors and a
lower rail the hangers' hooks fit over (fast, from the generators); the task file's stages and the
skills' registration (fast); the hang-on-rail predicate on simulated-state values built from a real
generated hanger (fast); one real organize_wardrobe episode in a generated bedroom (slow)."""

from __future__ import annotations

import math

import numpy as np
import pytest


def _generated(category: str, k: int):
    from asset_catalog.generators import GENERATORS_BY_CATEGORY, generate

    return generate(GENERATORS_BY_CATEGORY[category], np.random.default_rng(k), f"{category}_{k:02d}")


def test_wardrobe_doors_and_lower_rail_take_the_hangers_hook():
    """Every wardrobe variant has two revolute door leaves and a 16 mm rail across its inside at its
    ``low_rail`` height (0.95-1.1 m); every hanger's hook (inner radius ``hook_radius``) clears that
    rail by at least 8 mm and its recorded ``rod`` is its kind's."""
    from asset_catalog.generators.furniture import LOW_RAIL_RADIUS
    from asset_catalog.generators.objects import HANGER_NECK

    for k in range(5):
        w = _generated("wardrobe", k)
        assert sorted(j.role for j in w.joints) == ["door", "door"], k
        kinds = {j.name: j.type.value for j in w.model.joints}
        assert sorted(kinds.values()) == ["revolute", "revolute"], kinds
        z, width = w.params["low_rail"], w.params["width"]
        assert 0.95 <= z <= 1.1
        # the rail: base-link collider pieces thin in X and Z around (0, z), spanning the inside's width
        base = next(lk for lk in w.model.links if lk.name == "base")
        pts = [c.vertices for c in base.collision_source or ()]
        rails = [v for v in pts if abs(v[:, 2].mean() - z) < 0.002 and np.ptp(v[:, 2]) <= 2 * LOW_RAIL_RADIUS + 1e-4
                 and abs(v[:, 0].mean()) < 1e-3]
        assert rails, f"wardrobe {k}: no rail collider at z = {z:.3f}"
        assert max(float(np.ptp(v[:, 1])) for v in rails) >= width - 0.04
    rods = {0.0: (0.0018, 0.0025), 1.0: (0.004, 0.006), 2.0: (0.007, 0.009)}
    for k in range(5):
        h = _generated("hanger", k)
        lo, hi = rods[h.params["kind"]]
        assert lo <= h.params["rod"] <= hi, (k, h.params)
        assert h.params["hook_radius"] >= LOW_RAIL_RADIUS + 0.008
        assert h.params["neck"] == HANGER_NECK


def test_hanger_neck_has_a_boss_the_pinch_sits_under():
    """Every hanger's neck ends under its hook in a boss (``neck_stop`` long) that stands up on the
    hanger's +Z side at least 5 mm beyond the rod and is flush with the rods' underside (the hanger lies
    flat on its rods); the skill's pinch point lies on the neck, a pad's half width and a gap below it."""
    from asset_catalog.generators.objects import HANGER_NECK, NECK_STOP
    from stages.demos.skill_wardrobe import PAD_HALF, STOP_GAP

    for k in range(5):
        h = _generated("hanger", k)
        p = h.params
        rod, hh, stop = p["rod"], p["shoulder_height"], p["neck_stop"]
        assert stop == NECK_STOP[0]
        base = next(lk for lk in h.model.links if lk.name == "base")
        pts = [c.vertices for c in base.collision_source or ()]
        top_end = -hh - HANGER_NECK
        boss = [v for v in pts if abs(v[:, 0].min() - top_end) < 1e-3 and abs(v[:, 0].max() - (top_end + stop)) < 1e-3]
        assert len(boss) == 1, (k, len(boss))
        v = boss[0]
        assert v[:, 2].min() == pytest.approx(0.0, abs=5e-4)          # flush with the rods' underside
        assert v[:, 2].max() >= 2 * rod + 0.01                         # stands up beyond the rod
        assert min(float(c[:, 2].min()) for c in pts) >= -5e-4        # nothing below the rods
        grasp = HANGER_NECK - stop - PAD_HALF - STOP_GAP               # from the apex along the neck
        assert 0.03 < grasp < HANGER_NECK - stop


def test_organize_wardrobe_task_file_and_skills():
    from stages.demos.experts import EXPERTS
    from stages.demos.multistage import TASKS_DIR, load_multistage_dir
    from stages.demos.tasks import BASIC_TASKS, TASKS

    spec = load_multistage_dir(TASKS_DIR)["organize_wardrobe"]
    assert spec.room == "bedroom"
    assert [s.skill for s in spec.stages] == ["open_wardrobe", "hang_on_rail", "close_wardrobe"]
    assert [s.final for s in spec.stages] == [False, True, True]
    for s in spec.stages:
        assert s.skill in TASKS and s.skill in EXPERTS and s.skill not in BASIC_TASKS


def _hanger_world(tmp_path):
    """A world holding a real generated hanger (its parameters; the package's bounds from the
    generated model, not ingested) and a rail along world Y at 1.0 m, the wardrobe's front to +X."""
    from types import SimpleNamespace

    from stages.demos.packages import CatalogAsset, Placed
    from stages.demos.skill_wardrobe import Rail

    g = _generated("hanger", 3)
    pts = np.vstack([p.vertices for lk in g.model.links for p in lk.visuals])
    asset = CatalogAsset("hanger_03", "hanger", tmp_path / "hanger_03.usda", {"params": dict(g.params)})
    asset.__dict__["_facts"] = (tuple(pts.min(0)), tuple(pts.max(0)), "base")
    h = Placed("Objects/hanger_0", asset, (0.0, 0.0, 0.0), 0.0)
    rail = Rail((0.3, 0.0, 1.0), (0.3, 0.8, 1.0), 0.008, (1.0, 0.0))
    return SimpleNamespace(world=SimpleNamespace(placed={"hanger": h}, rail=rail)), h, rail


def _state(h, origin, rot, *, grip: float = 0.08, ee=(0.8, 0.4, 1.0)):
    from asset_catalog.asset_model import Pose
    from stages.simulate.state import BasePose, RobotState, StepState

    rot = np.asarray(rot, float)
    w = math.sqrt(max(0.0, 1.0 + np.trace(rot))) / 2
    q = (w, (rot[2, 1] - rot[1, 2]) / (4 * w), (rot[0, 2] - rot[2, 0]) / (4 * w), (rot[1, 0] - rot[0, 1]) / (4 * w))
    robot = RobotState(joint_names=(), q=np.zeros(0), qd=np.zeros(0), ee_pose=Pose(tuple(ee), (1.0, 0.0, 0.0, 0.0)),
                       base=BasePose(x=0.0, y=0.0, theta=0.0), gripper_opening=grip)
    return StepState(time=0.0, step=0, world=0, robot=robot,
                     objects={h.body(): Pose(tuple(float(v) for v in origin), q)}, scene_joints={})


def test_hang_on_rail_predicate(tmp_path):
    """Hung: the hook's centre where the rail sits in its top, the neck vertical, the hand open away: a
    success; the same hanger 5 cm lower, past the rail's end, lying flat there, or still in the closed
    hand fails with its reason."""
    from stages.demos.skill_wardrobe import _hook, hang_on_rail_success

    inst, h, rail = _hanger_world(tmp_path)
    _, cx, rod = _hook(h)
    hr = h.asset.params["hook_radius"]
    # hanging: local -X up, local +Y into the wardrobe (-X world), local Z along the rail (+Y world)
    hung = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])

    def origin_for(centre, rot):
        return np.asarray(centre) - rot @ np.array([cx, 0.0, rod])

    rest = np.array([0.3, 0.4, 1.0 - (hr - rail.radius)])
    assert hang_on_rail_success(inst, _state(h, origin_for(rest, hung), hung)) == (True, "")
    assert hang_on_rail_success(inst, _state(h, origin_for(rest - [0, 0, 0.05], hung), hung))[1] == "not_on_rail"
    assert hang_on_rail_success(inst, _state(h, origin_for(rest + [0, 0.5, 0], hung), hung))[1] == "not_on_rail"
    flat = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    assert hang_on_rail_success(inst, _state(h, origin_for(rest, flat), flat))[1] == "not_hanging"
    assert hang_on_rail_success(inst, _state(h, origin_for(rest, hung), hung, grip=0.01,
                                             ee=rest - [0, 0, 0.05]))[1] == "object_still_held"
    assert hang_on_rail_success(inst, _state(h, [0.3, 0.4, 0.02], flat))[1] == "hanger_fell"


def test_arm_width_tells_an_elbow_out_sideways(tmp_path):
    """The posture before the wardrobe is judged by how far the elbow and wrist reach sideways of the arm's
    mount (wardrobe_arm.arm_width, on the Panda's Pinocchio model): the home posture and the carry posture
    of flat_008 stay within NARROW_MAX, the posture flat_038's nearest IK solution had (joint 1 at 122 deg,
    the base stopped 10 cm short of the wardrobe) does not."""
    from types import SimpleNamespace

    from stages.demos.experts import timed_clik
    from stages.demos.wardrobe_arm import NARROW_MAX, arm_width
    from stages.simulate.robot import find_panda_description, write_robot_urdf

    desc = write_robot_urdf(tmp_path / "robot", panda_root=find_panda_description(None))
    d = SimpleNamespace(ik=timed_clik(desc))

    def width(deg) -> float:
        return arm_width(d, d.ik.with_arm(d.ik.neutral(), np.radians(deg)))

    assert width(np.degrees(desc.arm_home)) < NARROW_MAX
    assert width([-3, -24, 16, -123, 69, 175, 160]) < NARROW_MAX       # flat_008's staged posture (hung)
    assert width([122, -80, -47, -124, -143, 82, -64]) > NARROW_MAX    # flat_038 s2's (drive_timeout)


@pytest.fixture(scope="module")
def bedroom(tmp_path_factory):
    """The task world of flat_008's bedroom (job seed 0, as ``bench_house_tasks.py --room bedroom``):
    one of the 4 of the first 37 flats whose bedroom converts with a wardrobe, its lower rail and a hanger."""
    pytest.importorskip("newton")
    from test_demos_house_bedroom import BEDROOM_PACKAGES

    from pipeline import build_job, run_job
    from stages.demos.house_bedroom import house_bedroom
    from stages.scene.rules import HOUSEHOLD_TASK_RULES

    out = tmp_path_factory.mktemp("wardrobe") / "out"
    cats = sorted({p.rsplit("_", 1)[0] for p in BEDROOM_PACKAGES})
    job = {"job": {"name": "wardrobe", "seed": 0, "out": str(out), "executor": "inline", "workers": 1},
           "step": [{"name": "catalog", "kind": "default_catalog", "config": {"variants": 5, "categories": cats}},
                    {"name": "assets", "kind": "ingest", "config": {"catalog_step": "catalog", "only": list(BEDROOM_PACKAGES)}},
                    {"name": "layouts", "kind": "layout", "config": {"house": [
                        {"id": "flat", "count": 9, "spec": {"rooms": {"living_room": 1, "kitchen": 1, "bedroom": 1}}}]}},
                    {"name": "scenes", "kind": "scene", "config": {
                        "assets_step": "assets", "layouts_step": "layouts", "rules": str(HOUSEHOLD_TASK_RULES),
                        "looks": 1, "validate_usd": False, "settle": True,
                        "group": [{"id": "flat", "layouts": ["flat_008"], "rooms": ["bedroom"]}]}}]}
    summary = run_job(build_job(job, source="<test>", base_dir=out.parent), progress=False)
    assert {s.name: s.failed for s in summary.steps} == {"catalog": 0, "assets": 0, "layouts": 0, "scenes": 0}
    scene = out / "scenes" / "flat_008_p0"
    return house_bedroom(scene, tmp_path_factory.mktemp("task"), out / "catalog" / "default" / "generated.json",
                         scene_id=scene.name, multiccd=True)


@pytest.mark.slow  # ~1 min on 2 shared cores (the catalog, 9 layouts, flat_008's bedroom, one episode)
def test_wardrobe_facts_and_the_door_opens_in_a_generated_bedroom(bedroom, tmp_path):
    """The world's rail lies inside the wardrobe at its ``low_rail`` height; the episode's hanger lies on
    the blanket with its apex over the near edge; the real open_wardrobe expert opens the door on the
    batched engine (its predicate: past 75% of the travel)."""
    from stages.demos.multistage import sample_task
    from stages.demos.skill_wardrobe import OVERHANG
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    w = bedroom
    wr, rail = w.placed["wardrobe"], w.rail
    x0, y0, x1, y1 = wr.footprint()
    for p in (rail.p0, rail.p1):
        assert x0 < p[0] < x1 and y0 < p[1] < y1
        assert p[2] == pytest.approx(wr.position[2] + wr.asset.params["low_rail"], abs=1e-6)
    inst = sample_task("organize_wardrobe", w, 1)
    h = w.placed["hanger"]
    x, y, z, _ = inst.objects[h.body()]
    apex_y = y - h.asset.params["shoulder_height"]
    assert apex_y == pytest.approx(w.blanket_edge - OVERHANG, abs=1e-6) and z > w.table_z
    rows = []
    eng = BatchEngine(w, panda_root=None, work_dir=tmp_path / "engine",
                      config=EngineConfig(worlds=1, layout="per_world", record_images=False, subtasks=True))
    eng.run(Listed(w, {0: [("open_wardrobe", 1, None)]}), begin=lambda *_: None,
            end=lambda _w, t, r: rows.append((t.task, r.success, r.reason)))
    assert rows == [("open_wardrobe", True, "")]


@pytest.mark.slow  # ~1 min more on 2 shared cores (one hang_on_rail episode, the door preset open)
def test_hanger_hung_on_the_rail_in_a_generated_bedroom(bedroom, tmp_path):
    """The real hang_on_rail expert (the door preset open, the hanger on the blanket's edge) picks the
    hanger by its neck under the boss, carries it to the wardrobe and hooks it over the lower rail on the
    batched engine: the predicate holds (the hook on the rail, the neck near vertical, released)."""
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    rows = []
    eng = BatchEngine(bedroom, panda_root=None, work_dir=tmp_path / "engine",
                      config=EngineConfig(worlds=1, layout="per_world", record_images=False, subtasks=True))
    eng.run(Listed(bedroom, {0: [("hang_on_rail", 1, None)]}), begin=lambda *_: None,
            end=lambda _w, t, r: rows.append((t.task, r.success, r.reason)))
    assert rows == [("hang_on_rail", True, "")]


@pytest.mark.slow  # ~1 min more on 2 shared cores (two idle episodes of 8 s)
def test_the_hanger_stays_put_on_the_blanket_with_multiccd(bedroom, tmp_path, monkeypatch):
    """With the robot idle, the hanger lying on the blanket's near edge stays put on the engine with the
    bedroom's multi-CCD contacts (MuJoCo's one contact point per convex pair let it creep 7.4 mm/s
    towards the bed's middle in flat_008: ~6 cm in 8 s)."""
    from dataclasses import replace

    import stages.demos.experts as experts
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed
    from stages.simulate.state import read_state

    def drift(world) -> float:
        body, track = world.placed["hanger"].body(), []

        def idle(inst, d):  # the expert: the robot stands still while the hanger's position is read
            for _ in range(9):
                track.append(np.asarray(read_state(d.sim).objects[body].position, float))
                d.step(1.0)

        monkeypatch.setitem(experts.EXPERTS, "hang_on_rail", idle)
        eng = BatchEngine(world, panda_root=None, work_dir=tmp_path / f"engine_{world.multiccd}",
                          config=EngineConfig(worlds=1, layout="per_world", record_images=False, subtasks=True))
        eng.run(Listed(world, {0: [("hang_on_rail", 1, None)]}), begin=lambda *_: None, end=lambda *_: None)
        return float(np.linalg.norm(track[-1][:2] - track[1][:2]))  # over 8 s, after 1 s of settling

    assert bedroom.multiccd
    still, crept = drift(bedroom), drift(replace(bedroom, multiccd=False))
    assert still < 0.003, f"the hanger moved {still * 1000:.1f} mm in 8 s with multi-CCD"
    assert crept > 0.02, f"without multi-CCD it moved {crept * 1000:.1f} mm in 8 s (it crept ~7 mm/s)"


def test_floor_to_front_needs_a_gap_the_base_fits():
    """house_bedroom._floor_to_front on a synthetic room (4 x 3.5 m, a wardrobe against the south wall facing
    +Y, a bed whose corner leaves a diagonal gap to the wardrobe's corner): flat_013's 0.76 m gap keeps the
    base (the planner's 0.8 m disc) from the bed's side to the wardrobe's front; a 1.1 m gap does not."""
    from types import SimpleNamespace

    from stages.demos.house_bedroom import _floor_to_front
    from stages.demos.packages import Placed

    walls = ((-0.2, -0.2, 4.2, 0.0), (-0.2, 3.5, 4.2, 3.7), (-0.2, -0.2, 0.0, 3.7), (4.0, -0.2, 4.2, 3.7))
    rf = SimpleNamespace(area=(0.0, 0.0, 4.0, 3.5), walls=walls)
    # the wardrobe's asset frame: +X its front; yaw pi/2 turns it to +Y; footprint x 0.36-1.34, y 0.08-0.74
    wp = Placed("Objects/wardrobe_01", SimpleNamespace(hi=(0.33, 0.49, 2.0)), (0.85, 0.41, 0.0), math.pi / 2)
    pick = (2.6, 0.9, math.pi / 2)  # before the bed's near edge, east of the wardrobe
    for corner, ok in (((1.66, 1.43), False), ((1.9, 1.7), True)):
        bed = (corner[0], corner[1], 3.68, 3.07)
        assert math.dist(corner, (1.34, 0.74)) < 0.8 or ok
        assert _floor_to_front(rf, [(0.36, 0.08, 1.34, 0.74), bed], wp, pick) is ok, corner


def test_back_out_runs_along_the_open_leaf():
    """skill_wardrobe._back_out: with the leaf at its stop (90 deg) the way out is the wardrobe's front normal
    (as before); at 78 deg it runs along the leaf (hinge to free edge, leaning 12 deg over the open half), so the
    chassis beside it does not push it open; under 45 deg it falls back on the front normal."""
    import dataclasses

    from stages.demos.parts import ArticulatedPart
    from stages.demos.skill_wardrobe import _back_out

    # a wardrobe facing +Y, the door hinged at x = 2.48 (its east side), its handle 0.48 m west at closed
    part = ArticulatedPart(asset_id="w", category="wardrobe", role="door", joint_path="/j", link="door_0",
                           kind="revolute", axis=(0.0, 0.0, 1.0), origin=(2.48, 0.71, 1.0), lower=0.0,
                           upper=math.pi / 2, closed=0.0, handle=(2.0, 0.74, 1.05), bar_axis=(0.0, 0.0, 1.0),
                           grip_width=0.02, clearance=0.03, front=(0.0, 1.0, 0.0))
    # positive q opens: the free edge swings out (+Y) from the west: turning about -Z (check the axis sign)
    if part.handle_at(0.5)[1] < 0.74:
        part = dataclasses.replace(part, axis=(0.0, 0.0, -1.0))
    f = np.array([0.0, 1.0, 0.0])
    assert np.allclose(_back_out(part, math.pi / 2, f), [0.0, 1.0], atol=0.05)
    way = _back_out(part, math.radians(78.0), f)
    assert way[1] > 0.95 and way[0] < -0.15  # out and away from the hinge, along the leaf
    assert np.allclose(_back_out(part, math.radians(30.0), f), [0.0, 1.0])


def test_withdraw_backs_the_open_hand_out_in_small_steps():
    """skill_wardrobe._withdraw: the open hand under the hung hook is held, then moved out along the front
    normal in 5 mm steps (each its own move) to 6 cm, then on to 0.15 m, its rotation kept (a single 0.15 m
    move knocked the hook off the rail, flat_037 s2). The moves are recorded from a stand-in driver."""
    from stages.demos import skill_wardrobe as sw

    class Recorder:  # records the driver's move targets (the arm is not under test here)
        def __init__(self):
            self.moves = []

        def move(self, target, seconds, **kw):
            self.moves.append((np.asarray(target, float), float(seconds)))

    low, f = np.array([0.4, 0.7, 0.99]), np.array([1.0, 0.0, 0.0])
    rot = np.array([[0.09, 0.04, -0.995], [-0.08, -0.995, -0.05], [-0.993, 0.08, -0.09]])
    d = Recorder()
    sw._withdraw(d, low, f, rot)
    pts = np.array([t[:3, 3] for t, _ in d.moves])
    assert np.allclose(pts[0], low) and d.moves[0][1] == sw.WITHDRAW_HOLD
    out = (pts - low) @ f
    assert np.allclose(pts - low - np.outer(out, f), 0.0)  # straight out along f
    steps = np.diff(out)
    n = int(round(sw.WITHDRAW_SLOW / sw.WITHDRAW_STEP))
    assert np.allclose(steps[:n], sw.WITHDRAW_STEP) and out[n] == pytest.approx(sw.WITHDRAW_SLOW)
    assert out[-1] == pytest.approx(sw.WITHDRAW_OUT) and len(d.moves) == n + 2
    assert all(np.allclose(t[:3, :3], rot) for t, _ in d.moves)


def test_drive_clear_turns_the_held_hanger_clear_of_the_open_leaf():
    """base_approach.plan_turn on flat_018's geometry (a leaf from its hinge at (1.93, 0.70) out to its free
    edge at (1.87, 1.21); the base backed off the bed at (2.08, 1.67) facing +Y, a 0.4 m wide hanger held
    0.4 m ahead; the staging point (1.50, 1.55) facing -Y): the follower's own drive turns the short way
    (through +X) while passing the free edge, the hanger sweeping within TURN_MARGIN of the leaf (in the
    simulation it swept the door half shut); the plan turns on the spot the long way (through -X), with
    every leg clear; a leaf 3 m away leaves the follower's drive as it is."""
    from stages.demos.base_approach import (TURN_MARGIN, chassis_outline, clearance, plan_turn, rollout,
                                            spin)

    leaf = np.array([(1.933 + t * (1.866 - 1.933), 0.70 + t * (1.21 - 0.70)) for t in np.linspace(0, 1, 40)])
    held = np.array([(0.4, y) for y in np.linspace(-0.2, 0.2, 9)])
    body = np.vstack([chassis_outline(), held])
    start, goal_yaw, dt = (2.077, 1.672, 1.561), -1.571, 1.0 / 30.0
    path = np.array([start[:2], (1.504, 1.555)])
    direct = rollout(path, goal_yaw, start, dt)
    assert np.allclose(direct[-1, :2], path[-1], atol=0.02) and direct[-1, 2] == pytest.approx(goal_yaw, abs=0.02)
    assert direct[5, 2] < start[2]  # the follower turns the short way: clockwise, through +X
    assert clearance(direct, body, leaf) < TURN_MARGIN
    i, p, turn = plan_turn(path, start, goal_yaw, held, leaf, dt)
    assert turn == pytest.approx(goal_yaw - start[2] + 2 * math.pi, abs=1e-6)  # the long way, through -X
    legs = np.vstack([rollout(np.vstack([path[: i + 1], p]), start[2], start, dt), spin(p, start[2], turn),
                      rollout(np.vstack([p, path[i + 1:]]), goal_yaw, (*p, goal_yaw), dt)])
    assert clearance(legs, body, leaf) >= TURN_MARGIN
    assert plan_turn(path, start, goal_yaw, held, leaf + [3.0, 0.0], dt) is None


def test_roll_limited_leaves_the_hand_at_most_the_limit_off_square():
    """wardrobe_arm.roll_limited: a hanger rolled 25 deg about its neck in the pinch (the hand's approach 25 deg
    off its plane) is taken as rolled 10 deg (ROLL_LIMIT): the hand set square to the taken hanger turns 10 deg, the
    hanger keeps 15 deg (flat_014 s2: turned 30 deg, the hand met the closed door); a 6 deg roll is kept whole; the
    result is a rotation whose neck axis (local X) is the measured one's."""
    from stages.demos.wardrobe_arm import ROLL_LIMIT, roll_limited

    def about_x(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])

    pinch = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])[:, [2, 0, 1]]  # a rotation, approach +Y
    assert np.allclose(pinch[:, 2], [0.0, 1.0, 0.0]) and np.isclose(np.linalg.det(pinch), 1.0)

    def roll_of(r):
        return math.atan2(-r[2, 2], r[1, 2])

    for deg, want in ((25.0, math.degrees(ROLL_LIMIT)), (-25.0, -math.degrees(ROLL_LIMIT)), (6.0, 6.0)):
        measured = about_x(-math.radians(deg)) @ pinch
        assert math.degrees(roll_of(measured)) == pytest.approx(deg)
        taken = roll_limited(measured)
        assert math.degrees(roll_of(taken)) == pytest.approx(want)
        assert np.allclose(taken.T @ taken, np.eye(3)) and np.allclose(taken[0], measured[0])


def test_forearm_off_tells_a_forearm_by_the_wardrobes_middle(tmp_path):
    """wardrobe_arm.forearm_off on the Panda's Pinocchio model, the base at the world's origin facing +X, the
    wardrobe's middle (the closed door's edge) 5.5 cm to its right, the open half to its left (flat_018's
    staging): the two staged postures IK gave there, both within NARROW_MAX, differ in their forearm: seed 1's
    (hung) lies ~0.19 m on the open side, seed 5's mirrored wrist branch ~2 cm (its drive in stopped 11 cm short
    against the closed door): the second is under BESIDE_CLEAR, the first not."""
    from types import SimpleNamespace

    from stages.demos.experts import timed_clik
    from stages.demos.wardrobe_arm import BESIDE_CLEAR, NARROW_MAX, arm_width, forearm_off
    from stages.simulate.robot import find_panda_description, write_robot_urdf

    desc = write_robot_urdf(tmp_path / "robot", panda_root=find_panda_description(None))
    d = SimpleNamespace(ik=timed_clik(desc), sim=SimpleNamespace(spawn=(0.0, 0.0, 0.0)))
    mid, open_side = (0.0, -0.055), (0.0, 1.0)
    hung = d.ik.with_arm(d.ik.neutral(), np.radians([-57, -39, 51, -111, 121, 159, 147]))
    stuck = d.ik.with_arm(d.ik.neutral(), np.radians([59, -30, -46, -112, -89, 172, -51]))
    assert arm_width(d, hung) < NARROW_MAX and arm_width(d, stuck) < NARROW_MAX
    assert forearm_off(d, hung, mid, open_side) > BESIDE_CLEAR + 0.05
    assert forearm_off(d, stuck, mid, open_side) < BESIDE_CLEAR - 0.03
