"""Scripted demonstrations: planner, sampling, and one recorded episode through the dataset stage.

The recorded-episode tests build one world (the demo room with bowl, block and randomized
materials), run the open-drawer expert while recording 3 cameras at 96x72 into a shard, then a
second episode that times out (counted, not written), merge the shard, load it with
``LeRobotDataset`` and compare every frame against what the simulation produced.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from stages.demos.planner import NavGrid, NoPathError, PathFollower, plan_path

PANDA = "robots/franka_panda__example_robot_data"


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
    for step in range(2000):
        (vx, vy, w), done = f.command(x, y, th)
        if done:
            break
        assert math.hypot(vx, vy) <= f.v_max + 1e-9 and abs(w) <= f.w_max + 1e-9
        x += (math.cos(th) * vx - math.sin(th) * vy) * dt
        y += (math.sin(th) * vx + math.cos(th) * vy) * dt
        th += w * dt
        assert not blocked[grid.cell_of(x, y)], f"the base cut the corner at ({x:.2f}, {y:.2f})"
    assert done and step < 600, step
    assert math.hypot(x - 3.5, y - 0.8) < 0.01
    assert abs((th - math.pi / 2 + math.pi) % (2 * math.pi) - math.pi) < 0.01


# -- sampling ---------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def rooms(shared_assets, tmp_path_factory):
    from stages.demos.sampling import write_task_room

    d = tmp_path_factory.mktemp("rooms")
    return [write_task_room(d / name, shared_assets=shared_assets, scene_id=name,
                            rng=np.random.default_rng(seed))
            for name, seed in (("a", 5), ("b", 5), ("c", 6))]


def test_worlds_and_instances_come_from_their_seeds(rooms):
    from pxr import Usd

    from stages.demos.sampling import sample_instance

    a, b, c = rooms
    assert (a.table_xy, a.materials, a.bowl_xy) == (b.table_xy, b.materials, b.bowl_xy)
    assert a.table_xy != c.table_xy and a.materials != c.materials
    stage = Usd.Stage.Open(str(a.usd))  # the overlay composes the room with the bowl, block and colours
    for p in ("/World/Cabinet/DrawerJoint", "/World/Bowl/Wall0", "/World/Block", "/World/ButtonJoint"):
        assert stage.GetPrimAtPath(p), p
    top = stage.GetPrimAtPath("/World/Table/Top").GetAttribute("primvars:displayColor").Get()[0]
    np.testing.assert_allclose(tuple(top), a.materials["table"], rtol=1e-6)
    i1, i2 = sample_instance("close_drawer", a, 11), sample_instance("close_drawer", a, 11)
    assert i1 == i2 and i1 != sample_instance("close_drawer", a, 12)
    assert i1.joints["/World/Cabinet/DrawerJoint"] < -0.1  # the close task starts with the drawer open
    starts = [sample_instance("open_door", a, s).start_base for s in range(20)]
    grid = NavGrid.from_boxes((-0.2, -0.2, a.size[0] + 0.2, a.size[1] + 0.2), a.nav_boxes())
    assert not any(grid.inflate(0.45)[grid.cell_of(x, y)] for x, y, _ in starts)
    assert len({s[:2] for s in starts}) == 20


# -- one recorded episode through the dataset stage ---------------------------------------------


@pytest.fixture(scope="module")
def recorded(rooms, shared_assets, tmp_path_factory):
    pytest.importorskip("newton")
    pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")
    pytest.importorskip("lerobot")
    from stages.dataset import EpisodeInfo, merge_datasets, open_shard
    from stages.demos.sampling import sample_instance
    from stages.demos.session import DemoSettings, DemoWorld
    from stages.simulate.state import read_state

    d = tmp_path_factory.mktemp("demos")
    room = rooms[0]
    settings = DemoSettings(width=96, height=72)
    world = DemoWorld(room, panda_root=shared_assets / PANDA, work_dir=d, settings=settings)
    inst = sample_instance("open_drawer", room, 3)
    frames = []
    with open_shard(d / "shards", "s0", settings.dataset_spec()) as shard:
        def tee(frame):
            frames.append(frame)
            shard.add_frame(frame)

        shard.begin_episode(EpisodeInfo(task=inst.instruction, task_kind=inst.task, scene_id=room.scene_id,
                                        seed=inst.seed, asset_ids=inst.asset_ids))
        result = world.run_episode(inst, sink=tee)
        end_state = read_state(world.sim)
        end_ee = world.recorder.ee_in_base(np.asarray(end_state.robot.q[3:10]))
        shard.end_episode(success=result.success, reason=result.reason)
        short = dataclasses.replace(sample_instance("open_drawer", room, 4))
        shard.begin_episode(EpisodeInfo(task=short.instruction, task_kind=short.task, scene_id=room.scene_id,
                                        seed=short.seed))
        failed = world.run_episode(short, sink=shard.add_frame, max_seconds=1.0)
        shard.end_episode(success=failed.success, reason=failed.reason)
    merged = merge_datasets([d / "shards" / "s0"], d / "merged", repo_id="agentworld/demos_test")
    return dict(inst=inst, result=result, failed=failed, frames=frames, merged=merged, end_state=end_state,
                end_ee=end_ee, room=room)


def test_the_expert_opens_the_drawer_and_a_timed_out_episode_is_counted_not_written(recorded):
    r, f = recorded["result"], recorded["failed"]
    assert r.success, r.detail
    opened = -recorded["end_state"].scene_joints["/World/Cabinet/DrawerJoint"]
    assert opened >= 0.75 * recorded["room"].drawer_travel
    assert r.frames == len(recorded["frames"]) == pytest.approx(r.sim_seconds * 30, abs=2)
    assert not f.success and f.reason == "timeout" and f.frames == 30
    m = recorded["merged"]
    assert (m.episodes, m.frames, m.failures) == (1, r.frames, {"timeout": 1})


def test_recorded_state_and_action_follow_the_simulation(recorded):
    frames, end = recorded["frames"], recorded["end_state"]
    state = np.stack([f.state() for f in frames])
    action = np.stack([f.action() for f in frames])
    mode = action[:, -1]
    # locomotion first (base commands, base moving), then manipulation with the base mostly still
    assert mode[0] == 0 and mode[-1] == 1 and set(np.unique(mode)) == {0.0, 1.0}
    drive = mode == 0
    assert np.abs(action[drive, 14:17]).max() > 0.2
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
    # the gripper closes on the handle and opens at the end; arm targets are tracked
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

    from stages.dataset import load_dataset, read_episode_columns

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
                depth = batch[f"observation.images.{cam}_depth"][j]
                assert depth.shape == (1, 72, 96)
                np.testing.assert_array_equal(depth[0].numpy(), want.depth_mm[cam].astype(np.float32))
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
    dst = ds.meta.stats["observation.images.head_depth"]  # image stats come from sampled frames
    assert depth.min() <= float(np.squeeze(dst["min"])) <= float(np.squeeze(dst["max"])) <= depth.max()
    assert float(np.squeeze(dst["mean"])) == pytest.approx(depth.mean(), rel=0.1)
    (row,) = read_episode_columns(recorded["merged"].root)
    assert (row["scene_id"], row["seed"], row["task_kind"], row["success"]) == (room.scene_id, inst.seed,
                                                                                "open_drawer", True)
    assert list(row["asset_ids"]) == list(inst.asset_ids)


# -- the job ----------------------------------------------------------------------------------


@pytest.mark.slow
def test_demos_job_records_every_task_and_reports_success(shared_assets, tmp_path):
    import json

    from pipeline import load_job, run_job
    from stages.dataset import load_dataset, read_episode_columns
    from stages.demos.tasks import TASKS

    job = tmp_path / "demos.toml"
    job.write_text(f'''
[job]
name = "demos_test"
seed = 1
out = "{tmp_path / 'out'}"
executor = "local"
workers = 2

[[step]]
name = "demos"
kind = "demos"
[step.config]
shared_assets = "{shared_assets}"
episodes_per_shard = 1
width = 64
height = 48
''')
    summary = run_job(load_job(job))
    assert summary.status == "ok", summary
    report = json.loads((tmp_path / "out" / "reports" / "demos.json").read_text())
    assert set(report["tasks"]) == set(TASKS)
    assert report["successes"] >= 5, report
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
