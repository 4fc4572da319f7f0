"""The humanoid engine (``stages.engine.humanoid``): a G1 in the task kitchen (seed 5) walking by the
trained policy through the base interface, its right hand reaching by CLIK, frames recorded in the
G1's layout with head and wrist cameras; the close_drawer expert end to end (slow). Real scene,
real policy, MuJoCo C on the CPU."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("newton")
pytest.importorskip("pinocchio")
pytest.importorskip("torch")
pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")


def test_g1_stands_walks_to_a_pose_and_reaches_in_the_engine(kitchen_room):
    """One world: the G1 stands 1 s at the kitchen's spawn, walks (a straight path, the wheeled
    base's PathFollower) to a stance 0.45 m before the dining table, then holds its right hand at a
    point 0.25 m ahead and 0.15 m to the right, 8 cm higher than the table's top (its collision
    sphere clear of the table: over the top, a hand 0.3 m ahead sank onto it, the body turning by
    0.26 rad under the reaching arm). Frames: 25 fps, the G1's state and
    action layout (31 / 32), head and right-wrist images; the episode's predicate (close_drawer,
    drawer left open) reports drawer_not_closed.

    Measured (2-core shared CPU): stance within 3 cm after about 3 s, hand 5-10 mm from the point;
    about 40 s to build the engine and 30 s to run."""
    from stages.demos.humanoid_experts import MANIPULATION, WalkConfig, hand_to, walk_to
    from stages.demos.sampling import sample_instance
    from stages.engine.humanoid import HumanoidEngine, HumanoidEngineConfig

    k = kitchen_room
    eng = HumanoidEngine(k, HumanoidEngineConfig(worlds=1, cameras=("head", "right_wrist"), width=32,
                                                 height=24, max_seconds=15.0))
    inst = replace(sample_instance("close_drawer", k, 1), start_base=k.spawn)
    x0, y0, _, _ = k.table_rect
    stance = (k.spawn[0] - 0.15, y0 - 0.45, math.pi / 2)
    point = np.array([k.spawn[0], y0 - 0.2, k.table_z + 0.08])
    seen: dict = {}

    def program(h, inst):
        start = h.base_pose()
        heights = []
        for _ in range(int(1.0 / h.dt)):
            heights.append(h.base_height())
            yield 1
        seen["stand_drift"] = math.dist(start[:2], h.base_pose()[:2])
        seen["stand_min_height"] = min(heights)
        yield from walk_to(h, stance, WalkConfig(), path=np.array([start[:2], stance[:2]]))
        seen["stance_error"] = math.dist(h.base_pose()[:2], stance[:2])
        seen["walked"] = math.dist(start[:2], h.base_pose()[:2])
        h.set_mode(MANIPULATION)
        target = h.ee_pose("right").copy()
        target[:3, 3] = point
        yield from hand_to(h, "right", target, tol=0.005, timeout_s=3.0)
        errs = []
        for _ in range(int(1.0 / h.dt)):          # held for a second
            yield 1
            errs.append(float(np.linalg.norm(h.ee_pose("right")[:3, 3] - point)))
        seen["hand_error"] = float(np.mean(errs))

    frames, results = [], []
    queue = [inst]
    eng.run(lambda w: queue.pop() if queue else None, program, begin=lambda w, i: frames.append,
            end=lambda w, i, r: results.append(r))
    assert eng.fps == 25 and len(results) == 1
    res = results[0]
    steps = round(res.sim_seconds / 0.02)
    assert res.reason == "drawer_not_closed" and res.frames == len(frames) == (steps + 1) // 2
    assert seen["stand_drift"] < 0.03 and seen["stand_min_height"] > 0.7
    assert seen["stance_error"] < 0.05 and seen["walked"] > 0.4
    assert seen["hand_error"] < 0.015
    spec = eng.dataset_spec()
    assert spec.robot_type == "unitree_g1" and (spec.state_dim, spec.action_dim) == (31, 32)
    last = frames[-1]
    assert last.state().shape == (31,) and last.action().shape == (32,) and last.mode == MANIPULATION
    assert math.dist(last.state()[-3:-1], stance[:2]) < 0.06          # base pose in the state
    assert last.rgb["head"].shape == (24, 32, 3) and last.depth_mm["right_wrist"].shape == (24, 32)
    assert last.rgb["head"].std() > 0 and (last.depth_mm["head"] > 0).mean() > 0.9   # the scene is seen


@pytest.mark.slow
def test_close_drawer_episodes_are_recorded_and_load(kitchen_catalog, tmp_path):
    """Two close_drawer episodes (seeds 1, 2) by the humanoid recorder with head and wrist cameras:
    both succeed, the merged dataset loads with LeRobotDataset (robot type unitree_g1) and the
    contact sheet is written. Measured: 12.4 / 12.6 s simulated each; about 4 min on 2 shared cores."""
    from stages.dataset import load_dataset
    from stages.demos.humanoid_run import HumanoidRunConfig, record

    from kitchen_testutil import link_kitchen_catalog

    work = tmp_path / "w"
    link_kitchen_catalog(kitchen_catalog, work / "kitchens")
    rep = record(work, HumanoidRunConfig(episodes=2, cameras=("head", "left_wrist", "right_wrist"), width=32,
                                         height=24))
    assert rep["tasks"]["close_drawer"]["successes"] == 2, rep["episodes"]
    ds = load_dataset(rep["dataset"])
    assert ds.meta.robot_type == "unitree_g1" and ds.meta.total_episodes == 2
    cams = ("head", "left_wrist", "right_wrist")
    assert set(ds.meta.camera_keys) == {f"observation.images.{c}" for c in cams}
    assert (work / "reports" / "humanoid_contact_sheet.png").stat().st_size > 1000


def test_the_humanoid_job_file_validates():
    """jobs/demos_humanoid.toml loads through the job validation (the humanoid_demos kind, its tasks
    known to the humanoid experts); an unknown task is refused naming it."""
    from pathlib import Path

    from pipeline import load_job
    from stages.demos.humanoid_job import HumanoidDemosConfig

    job = load_job(Path(__file__).resolve().parents[2] / "jobs" / "demos_humanoid.toml")
    step = [s for s in job.steps if s.kind == "humanoid_demos"][0]
    assert step.config.spec == "g1_29dof" and "close_drawer" in step.config.tasks
    with pytest.raises(ValueError, match="pour_drink"):
        HumanoidDemosConfig(tasks=("pour_drink",))
