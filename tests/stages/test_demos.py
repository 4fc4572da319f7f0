"""Scripted demonstrations: planner, the kitchen task world from the default catalog, sampling, and
one recorded episode through the dataset stage.

The catalog fixture generates the default catalog's kitchen categories and ingests one package of
each (the graspable mug variant among them) through the real job steps. The recorded-episode tests
build one kitchen world, run the press-button expert while recording 3 cameras at 96x72 into a
shard, then a second episode that times out (counted, not written), merge the shard, load it with
``LeRobotDataset`` and compare every frame against what the simulation produced.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from kitchen_testutil import PACKAGES, kitchen_job

from stages.demos.planner import NavGrid, NoPathError, PathFollower, plan_path



# -- planner ----------------------------------------------------------------------------------


def _wall_grid() -> NavGrid:
    """A 4 x 3 m room with a wall across x = 2 m, open only for y in [2.2, 3.0]."""
    return NavGrid.from_boxes((0.0, 0.0, 4.0, 3.0), np.array([[1.95, 0.0, 2.05, 2.2]]), cell=0.05)


def test_astar_goes_through_the_gap_and_keeps_the_footprint_clear():
    grid = _wall_grid()
    path = plan_path(grid, (0.5, 0.5), (3.5, 0.5), robot_radius=0.3)
    blocked = grid.inflate(0.3)
    dense = np.concatenate([np.linspace(a, b, 50) for a, b in zip(path[:-1], path[1:])])
    assert not any(blocked[grid.cell_of(x, y)] for x, y in dense), "the path enters the inflated wall"
    assert max(y for _, y in dense) > 2.2 + 0.3 - 0.05, "the path does not pass through the gap"
    assert len(path) <= 6, f"the cell path was not shortcut: {len(path)} waypoints"
    length = float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
    assert length < 1.15 * (2 * math.hypot(1.5, 2.0)), length  # near the shortest way round the wall end


def test_astar_reports_a_closed_room():
    grid = NavGrid.from_boxes((0.0, 0.0, 4.0, 3.0), np.array([[1.95, 0.0, 2.05, 3.0]]))
    with pytest.raises(NoPathError):
        plan_path(grid, (0.5, 0.5), (3.5, 0.5), robot_radius=0.3)


def test_follower_drives_a_holonomic_base_to_the_goal_pose():
    grid = _wall_grid()
    path = plan_path(grid, (0.5, 0.5), (3.5, 0.8), robot_radius=0.3)
    f = PathFollower(path, goal_yaw=math.pi / 2)
    x, y, th, dt = 0.5, 0.5, -2.0, 1 / 30
    blocked = grid.inflate(0.25)
    v_prev, w_prev = np.zeros(2), 0.0
    for step in range(2000):
        (vx, vy, w), done = f.command(x, y, th)
        if done:
            break
        assert math.hypot(vx, vy) <= f.v_max + 1e-9 and abs(w) <= f.w_max + 1e-9
        # acceleration-limited: the world-frame velocity and the turn rate change smoothly
        v_world = np.array([math.cos(th) * vx - math.sin(th) * vy, math.sin(th) * vx + math.cos(th) * vy])
        assert np.linalg.norm(v_world - v_prev) <= f.accel * dt + 1e-9
        assert abs(w - w_prev) <= f.alpha * dt + 1e-9
        v_prev, w_prev = v_world, w
        x += (math.cos(th) * vx - math.sin(th) * vy) * dt
        y += (math.sin(th) * vx + math.cos(th) * vy) * dt
        th += w * dt
        assert not blocked[grid.cell_of(x, y)], f"the base cut the corner at ({x:.2f}, {y:.2f})"
    assert done and step < 600, step
    assert math.hypot(x - 3.5, y - 0.8) < 0.01
    assert abs((th - math.pi / 2 + math.pi) % (2 * math.pi) - math.pi) < 0.01


# -- the kitchen world and sampling -------------------------------------------------------------


@pytest.fixture(scope="module")
def catalog(kitchen_catalog) -> Path:
    """The kitchen packages generated and ingested by the real job steps (tests/stages/conftest.py,
    shared by the session); the work dir."""
    return kitchen_catalog


@pytest.fixture(scope="module")
def worlds(kitchen_library, tmp_path_factory):
    from stages.demos.kitchen import write_kitchen

    d = tmp_path_factory.mktemp("worlds")
    return [write_kitchen(d / name, kitchen_library, scene_id=name, rng=np.random.default_rng(seed))
            for name, seed in (("a", 5), ("b", 5), ("c", 6))]


def test_the_kitchen_references_the_ingested_packages_and_places_them_from_the_seed(worlds, catalog):
    from pxr import Sdf, Usd, UsdGeom

    a, b, c = worlds
    def poses(w):
        return {k: (p.position, p.yaw) for k, p in w.placed.items()}

    assert poses(a) == poses(b) and a.materials == b.materials
    assert poses(a) != poses(c) and a.materials != c.materials
    assert a.asset_ids() == {"counter": "kitchen_counter_00", "microwave": "microwave_00",
                             "fridge": "fridge_00",
                             "oven": "oven_00", "door": "door_00", "table": "dining_table_00",
                             "mug": "mug_04", "bowl": "bowl_00", "pusher": "can_00"}
    layer = Sdf.Layer.FindOrOpen(str(a.usd))
    refs = {str(p.path): [r.assetPath for r in p.referenceList.prependedItems]
            for p in layer.rootPrims[0].nameChildren if p.referenceList.prependedItems}
    # relative references to the ingest step's packages, no copies
    assert len(refs) == 9 and all(r[0].startswith(".") for r in refs.values())
    assert not list(a.usd.parent.glob("**/*.usdc"))
    stage = Usd.Stage.Open(str(a.usd))
    for path in (a.placed["microwave"].joint("button_joint"), a.placed["door"].joint("leaf_joint"),
                 a.placed["mug"].body(), "/World/WallSouthW", "/World/Lights/Ceiling"):
        assert stage.GetPrimAtPath(path), path
    cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), ["default", "render"])
    # the microwave stands on the counter top, inside its footprint; the mug on the table top
    mw = cache.ComputeWorldBound(stage.GetPrimAtPath("/World/Microwave")).ComputeAlignedRange()
    assert mw.GetMin()[2] == pytest.approx(a.counter_z, abs=0.005)
    x0, y0, x1, y1 = a.placed["counter"].footprint()
    assert x0 <= mw.GetMin()[0] and mw.GetMax()[0] <= x1
    assert y0 <= mw.GetMin()[1] and mw.GetMax()[1] <= y1 + 0.01
    mug = cache.ComputeWorldBound(stage.GetPrimAtPath("/World/Mug")).ComputeAlignedRange()
    assert mug.GetMin()[2] == pytest.approx(a.table_z, abs=0.005)
    assert 2 * a.mug_radius <= 0.076  # the Franka hand's stroke is 80 mm
    # the button face and the cavity are where the microwave's package puts them
    assert a.cavity[0] < a.cavity[2] and a.cavity[1] < a.cavity[3] and a.cavity_z > a.counter_z
    assert y0 - 0.01 < a.button[1] < a.cavity[1] + 0.05 and a.counter_z < a.button[2] < a.counter_z + 0.3


def test_instances_come_from_their_seeds_and_start_clear(worlds):
    from stages.demos.sampling import sample_instance
    from stages.demos.tasks import BASIC_TASKS

    a = worlds[0]
    i1, i2 = sample_instance("close_drawer", a, 11), sample_instance("close_drawer", a, 11)
    assert i1 == i2 and i1 != sample_instance("close_drawer", a, 12)
    assert i1.part is not None and i1.joints[i1.part.joint_path] > 0.5 * i1.part.travel  # starts open
    mw = sample_instance("pick_from_microwave", a, 3)
    door = a.placed["microwave"].joint("door_joint")
    assert mw.joints[door] > 1.4
    x, y, z, _ = mw.objects[a.placed["mug"].body()]
    x0, y0, x1, y1 = a.cavity
    assert x0 < x < x1 and y0 < y < y1 and z == pytest.approx(a.cavity_z, abs=0.005)
    grid = a.grid()
    starts = [sample_instance("open_door", a, s).start_base for s in range(20)]
    assert not any(grid.inflate(0.45)[grid.cell_of(x, y)] for x, y, _ in starts)
    assert len({s[:2] for s in starts}) == 20
    for t in BASIC_TASKS:  # every basic task samples in the world, with an instruction naming its things
        inst = sample_instance(t, a, 1)
        assert inst.instruction and "{" not in inst.instruction and inst.asset_ids


# -- one recorded episode through the dataset stage ---------------------------------------------


@pytest.fixture(scope="module")
def recorded(worlds, tmp_path_factory):
    pytest.importorskip("newton")
    pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")
    pytest.importorskip("lerobot")
    from stages.dataset import EpisodeInfo, merge_datasets, open_shard
    from stages.demos.sampling import sample_instance
    from stages.demos.session import DemoSettings, DemoWorld
    from stages.simulate.state import read_state

    d = tmp_path_factory.mktemp("demos")
    room = worlds[0]
    settings = DemoSettings(width=96, height=72)
    world = DemoWorld(room, panda_root=None, work_dir=d, settings=settings)
    inst = sample_instance("press_button", room, 3)
    frames = []
    with open_shard(d / "shards", "s0", settings.dataset_spec()) as shard:
        def tee(frame):
            frames.append(frame)
            shard.add_frame(frame)

        shard.begin_episode(EpisodeInfo(task=inst.instruction, task_kind=inst.task, scene_id=room.scene_id,
                                        seed=inst.seed, asset_ids=inst.asset_ids))
        result = world.run_episode(inst, sink=tee)
        end_state = read_state(world.sim)
        peak = dict(world.peaks.peak)
        end_ee = world.recorder.ee_in_base(np.asarray(end_state.robot.q[3:10]))
        shard.end_episode(success=result.success, reason=result.reason)
        short = dataclasses.replace(sample_instance("press_button", room, 4))
        shard.begin_episode(EpisodeInfo(task=short.instruction, task_kind=short.task, scene_id=room.scene_id,
                                        seed=short.seed))
        failed = world.run_episode(short, sink=shard.add_frame, max_seconds=1.0)
        shard.end_episode(success=failed.success, reason=failed.reason)
    merged = merge_datasets([d / "shards" / "s0"], d / "merged", repo_id="agentworld/demos_test")
    return dict(inst=inst, result=result, failed=failed, frames=frames, merged=merged, end_state=end_state,
                end_ee=end_ee, room=room, peak=peak)


def test_the_expert_presses_the_button_and_a_timed_out_episode_is_counted_not_written(recorded):
    r, f = recorded["result"], recorded["failed"]
    assert r.success, r.detail
    room = recorded["room"]
    assert recorded["peak"][room.placed["microwave"].joint("button_joint")] >= 0.6 * room.button_travel
    assert r.frames == len(recorded["frames"]) == pytest.approx(r.sim_seconds * 30, abs=2)
    assert not f.success and f.reason == "timeout" and f.frames == 30
    m = recorded["merged"]
    assert (m.episodes, m.frames, m.failures) == (1, r.frames, {"timeout": 1})


def test_recorded_state_and_action_follow_the_simulation(recorded):
    frames, end = recorded["frames"], recorded["end_state"]
    state = np.stack([f.state() for f in frames])
    action = np.stack([f.action() for f in frames])
    mode = action[:, -1]
    # the base sets off at once (locomotion: base commands, base moving) while the hand is raised
    # from home (the arm targets move during the first second), then manipulation with the base
    # mostly still
    assert mode[0] == 0 and mode[-1] == 1 and set(np.unique(mode)) == {0.0, 1.0}
    drive = mode == 0
    assert np.abs(action[drive, 14:17]).max() > 0.2
    assert np.abs(action[30, :7] - action[0, :7]).max() > 0.1 and drive[30]
    start = recorded["inst"].start_base
    np.testing.assert_allclose(state[0, 14:16], start[:2], atol=1e-3)
    assert abs(state[0, 16] - start[2]) < 1e-3 or abs(abs(state[0, 16] - start[2]) - 2 * np.pi) < 1e-3
    # the base pose integrates the commanded base velocity (world frame, over one frame)
    th = state[:-1, 16]
    vx, vy = action[:-1, 14], action[:-1, 15]
    v_world = np.stack([np.cos(th) * vx - np.sin(th) * vy, np.sin(th) * vx + np.cos(th) * vy], 1)
    pred = state[:-1, 14:16] + v_world / 30
    err = np.linalg.norm(pred - state[1:, 14:16], axis=1)
    assert np.median(err[drive[:-1]]) < 0.01, np.median(err[drive[:-1]])
    # the hand closes to press and opens at the end; arm targets are tracked
    assert action[:, 17].max() == 1.0 and action[-1, 17] == 0.0
    assert np.abs(state[-1, :7] - action[-1, :7]).max() < 0.05
    # the last recorded state is the simulation's (recorded one physics step earlier at most)
    np.testing.assert_allclose(state[-1, 14:16], [end.robot.base.x, end.robot.base.y], atol=2e-3)
    np.testing.assert_allclose(state[-1, :7], end.robot.q[3:10], atol=5e-3)
    # the end-effector pose in the base frame (Pinocchio FK) agrees with Newton's world pose
    base = end.robot.base
    c, s = np.cos(base.theta), np.sin(base.theta)
    ee_w = np.asarray(end.robot.ee_pose.position)
    d = ee_w[:2] - [base.x, base.y]
    ee_b = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], ee_w[2]])
    np.testing.assert_allclose(recorded["end_ee"][:3], ee_b, atol=2e-3)


def _psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return 99.0 if mse == 0 else 10 * np.log10(255.0**2 / mse)


def test_the_dataset_loads_and_matches_the_recorded_frames(recorded):
    import torch

    from stages.dataset import decode_depth, load_dataset, read_episode_columns

    frames, inst, room = recorded["frames"], recorded["inst"], recorded["room"]
    ds = load_dataset(recorded["merged"].root)
    assert len(ds) == len(frames) and ds.num_episodes == 1 and ds.fps == 30
    loader = torch.utils.data.DataLoader(ds, batch_size=64, shuffle=False, num_workers=2)
    psnr, seen, depth_hits = [], 0, 0
    for batch in loader:
        for j in range(len(batch["index"])):
            i = int(batch["frame_index"][j])
            want = frames[i]
            np.testing.assert_array_equal(batch["observation.state"][j].numpy(), want.state())
            np.testing.assert_array_equal(batch["action"][j].numpy(), want.action())
            assert batch["task"][j] == inst.instruction
            for cam in ("wrist", "head", "third_person"):
                depth = decode_depth(batch[f"depth.{cam}"][j])
                assert depth.shape == (72, 96)
                np.testing.assert_array_equal(depth, want.depth_mm[cam])
                depth_hits += int((want.depth_mm[cam] > 0).sum())
                got = batch[f"observation.images.{cam}"][j].permute(1, 2, 0).numpy() * 255.0
                psnr.append(_psnr(got, want.rgb[cam]))
            seen += 1
    assert seen == len(frames)
    assert depth_hits > 0.9 * 3 * 72 * 96 * len(frames), "the cameras see mostly nothing"
    assert min(psnr) > 25.0 and np.mean(psnr) > 30.0, (min(psnr), np.mean(psnr))
    state = np.stack([f.state() for f in frames])
    st = ds.meta.stats["observation.state"]
    np.testing.assert_allclose(st["min"], state.min(0), rtol=1e-6)
    np.testing.assert_allclose(st["max"], state.max(0), rtol=1e-6)
    np.testing.assert_allclose(st["mean"], state.mean(0, dtype=np.float64), rtol=1e-5, atol=1e-6)
    depth = np.stack([f.depth_mm["head"] for f in frames]).astype(np.float64)
    dst = ds.meta.stats["depth.head"]  # image stats come from sampled frames
    assert depth.min() <= float(np.squeeze(dst["min"])) <= float(np.squeeze(dst["max"])) <= depth.max()
    assert float(np.squeeze(dst["mean"])) == pytest.approx(depth.mean(), rel=0.1)
    (row,) = read_episode_columns(recorded["merged"].root)
    assert (row["scene_id"], row["seed"], row["task_kind"], row["success"]) == (room.scene_id, inst.seed,
                                                                                "press_button", True)
    assert list(row["asset_ids"]) == list(inst.asset_ids)


# -- the job ----------------------------------------------------------------------------------


def test_the_job_plans_from_the_catalog_and_ingest_steps(catalog, tmp_path):
    from pipeline import load_results
    from pipeline.types import PlanContext, PlannedFailure
    from stages.demos.job import DemosConfig, plan_demos

    prev = {"catalog": load_results(catalog, "catalog"), "assets": load_results(catalog, "assets")}
    ctx = PlanContext(job_file=tmp_path / "job.toml", job_dir=tmp_path, work_dir=catalog, seed=0,
                      previous=prev)
    items = plan_demos(DemosConfig(tasks=("press_button", "open_fridge"), worlds=2), ctx)
    assert [i.item_id for i in items] == ["press_button_w000", "press_button_w001", "open_fridge_w000",
                                          "open_fridge_w001"]
    p = items[0].params
    assert set(p.packages) == set(PACKAGES) and Path(p.generated).name == "generated.json"
    assert p.world_seed != items[1].params.world_seed and p.world_seed == items[2].params.world_seed
    assert all(Path(f).is_file() for f in items[0].input_files)
    missing = plan_demos(DemosConfig(assets_step="ingest", tasks=("press_button",)),
                         PlanContext(job_file=tmp_path / "job.toml", job_dir=tmp_path, work_dir=catalog,
                                     seed=0, previous={"catalog": prev["catalog"]}))
    assert isinstance(missing[0], PlannedFailure) and "assets_step 'ingest'" in missing[0].reason
    assert str(tmp_path / "job.toml") in missing[0].reason


@pytest.mark.slow
def test_demos_job_records_every_task_and_reports_success(tmp_path):
    """default catalog -> ingest -> demos (every task, 1 episode, 64x48) in one job, as the main job."""
    import json

    from pipeline import build_job, run_job
    from stages.dataset import load_dataset, read_episode_columns
    from stages.demos.tasks import BASIC_TASKS

    out = tmp_path / "out"
    demos = {"name": "demos", "kind": "demos", "config": {"episodes_per_shard": 1, "width": 64, "height": 48}}
    data = kitchen_job(out, [demos], name="demos_catalog")
    data["job"].update(executor="local", workers=2)
    summary = run_job(build_job(data, source="<test>", base_dir=tmp_path), progress=False)
    assert summary.status == "ok", summary
    report = json.loads((out / "reports" / "demos.json").read_text())
    assert set(report["tasks"]) == set(BASIC_TASKS)
    assert report["successes"] >= 0.8 * len(BASIC_TASKS), report
    ds = load_dataset(Path(report["dataset"]["root"]))
    assert ds.num_episodes == report["successes"] and len(ds) == report["dataset"]["frames"]
    kinds = {r["task_kind"] for r in read_episode_columns(Path(report["dataset"]["root"]))}
    assert kinds == {t for t, v in report["tasks"].items() if v["successes"]}


def test_importing_the_job_kind_loads_no_heavy_module():
    import subprocess
    import sys

    code = ("import sys, pipeline, stages.demos.job, stages.demos.planner, stages.demos.tasks; "
            "print(sorted(m for m in ('pxr', 'warp', 'torch', 'newton', 'lerobot') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=Path(__file__).resolve().parents[2])
    assert out.stdout.strip() == "[]", out.stdout + out.stderr
