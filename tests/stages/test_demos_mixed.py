"""The demos job's mixed-task mode (``mixed = true``): one engine per kitchen runs every task.

The catalog fixture is the session's kitchen catalog (tests/stages/conftest.py: the kitchen
categories of the default catalog, one package of each ingested by the real job steps); each demos
step runs in a copy of it. The fast job test runs one kitchen's engine of 2 worlds
(CPU, MuJoCo C per world, no cameras) over 3 tasks with a 1 s episode limit and a 1.5 s bound on
simulated time: world 0 runs episodes 0 and 2 (the second one cut), world 1 episode 1, so the
report counts timeouts and an unfinished episode. The slow test runs 2 tasks to success in 2 worlds,
loads the merged dataset and every shard with ``LeRobotDataset``, and records the same item again
from the same seeds: the same episodes, outcomes and frames.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from kitchen_testutil import copy_kitchen_catalog, kitchen_job


def _job(out: Path, demos: dict | None = None) -> dict:
    extra = None if demos is None else [{"name": "demos", "kind": "demos", "config": demos}]
    return kitchen_job(out, extra, name="demos_mixed")


def _run(out: Path, demos: dict | None = None):
    from pipeline import build_job, run_job

    return run_job(build_job(_job(out, demos), source="<test>", base_dir=out.parent), progress=False)


@pytest.fixture(scope="module")
def catalog(kitchen_catalog) -> Path:
    """The job's work dir after its catalog and ingest steps (the session's, tests/stages/conftest.py;
    the demos steps of the tests run in copies of it)."""
    pytest.importorskip("newton")
    pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")
    return kitchen_catalog


# -- configuration and planning (no simulation) -------------------------------------------------


@pytest.mark.parametrize("config, message", [
    ({"mixed": True, "episodes_per_shard": 3}, "with mixed = true set episodes_per_task"),
    ({"episodes_per_task": 3}, "episodes_per_task needs mixed = true"),
    ({"max_sim_seconds": 10.0}, "max_sim_seconds needs mixed = true"),
    ({"mixed": True, "program_procs": 4}, "program_procs needs device = 'cuda'"),
    ({"mixed": True, "device": "gpu"}, "device must be 'cpu' or 'cuda[:n]'"),
    ({"mixed": True, "tasks": ["press_button", "press_button"]}, "without repeats"),
    ({"mixed": True, "episodes_per_task": 0}, "episodes_per_task"),
])
def test_a_bad_mixed_config_is_one_line_naming_the_job_file(config, message):
    from pipeline import build_job
    from pipeline import JobError

    with pytest.raises(JobError) as e:
        build_job(_job(Path("out"), config), source="jobs/bad.toml", base_dir=Path("."))
    text = str(e.value)
    assert text.startswith("jobs/bad.toml: step 'demos'") and message in text and "\n" not in text, text


def test_episodes_interleave_the_tasks_and_their_seeds_come_from_the_item_seed():
    from pipeline.types import derive_seed
    from stages.demos.mixed import plan_episodes

    tasks = ("push_object", "press_button", "open_drawer")
    item_seed = derive_seed(0, "demos", "mixed_w000")
    plan = plan_episodes(tasks, 2, item_seed)
    assert [t for t, _ in plan] == list(tasks) * 2
    assert [s for _, s in plan] == [derive_seed(item_seed, "episode", str(e)) % 2**62 for e in range(6)]
    assert len({s for _, s in plan}) == 6
    assert plan == plan_episodes(tasks, 2, item_seed) and plan != plan_episodes(tasks, 2, item_seed + 1)
    # a longer run extends the same episodes
    assert plan_episodes(tasks, 3, item_seed)[:6] == plan


# -- the job on the CPU engine ------------------------------------------------------------------


def test_one_engine_runs_every_task_and_the_report_counts_timeouts_and_unfinished(catalog, tmp_path):
    from pipeline import load_results
    from pipeline.types import derive_seed
    from stages.demos.mixed import MixedResult, plan_episodes

    out = copy_kitchen_catalog(catalog, tmp_path / "out")
    tasks = ["push_object", "press_button", "open_drawer"]
    summary = _run(out, {"mixed": True, "tasks": tasks, "batch_worlds": 2, "episodes_per_task": 1,
                         "record_images": False, "max_seconds": 1.0, "max_sim_seconds": 1.5})
    assert summary.status == "ok", summary
    (iid, res), = load_results(out, "demos").items()
    assert iid == "mixed_w000" and isinstance(res, MixedResult) and res.worlds == 2
    plan = plan_episodes(tuple(tasks), 1, derive_seed(0, "demos", iid))
    assert [(e.index, e.task, e.seed, e.world) for e in res.episodes] == [
        (k, t, s, k % 2) for k, (t, s) in enumerate(plan)]
    first, second, third = res.episodes
    assert first.ended and second.ended and not third.ended  # world 0's second episode was cut
    for e in (first, second):
        assert (e.success, e.reason) == (False, "timeout")
        assert e.frames == 31 and e.sim_seconds == pytest.approx(1.0, abs=0.01), e  # frames 0 .. 30
    assert 1.5 <= res.sim_seconds < 1.6
    report = json.loads((out / "reports" / "demos.json").read_text())
    assert report["mode"] == "mixed" and report["failed_items"] == {} and report["dataset"] is None
    assert (report["attempts"], report["successes"], report["unfinished"]) == (2, 0, 1)
    assert report["tasks"]["push_object"] == {"attempts": 1, "successes": 0, "unfinished": 0,
                                              "failures": {"timeout": 1}, "frames": 0, "success_rate": 0.0,
                                              "success_rate_of_planned": 0.0, "median_frames": None}
    assert report["tasks"]["open_drawer"]["unfinished"] == 1 and report["tasks"]["open_drawer"]["attempts"] == 0
    assert report["min_success_rate"] == 0.0
    assert report["contacts"]["overflows"] == 0 and report["contacts"]["overflowed_items"] == {}
    # every captured frame is counted, the cut episode's too (it started at a sync point after 1.0 s)
    assert report["frames_recorded"] == res.timings["frames"] > 62


@pytest.mark.slow
def test_mixed_episodes_succeed_load_with_lerobot_and_replay_from_their_seeds(catalog, tmp_path):
    """2 worlds, push_object and pick_place_bowl to success (~2 min on 2 cores); the item recorded
    again from the same params and seed gives the same episodes and frames."""
    from pipeline import load_results
    from pipeline.types import ItemContext, PlanContext, derive_seed
    from stages.dataset import load_dataset, read_episode_columns
    from stages.demos.job import DemosConfig, plan_demos
    from stages.demos.mixed import record_mixed

    out = copy_kitchen_catalog(catalog, tmp_path / "out")
    demos = {"mixed": True, "tasks": ["push_object", "pick_place_bowl"], "batch_worlds": 2, "episodes_per_task": 1,
             "record_images": False}
    summary = _run(out, demos)
    assert summary.status == "ok", summary
    report = json.loads((out / "reports" / "demos.json").read_text())
    assert report["successes"] == report["attempts"] == 2, report
    assert all(t["success_rate"] == 1.0 and t["median_frames"] > 100 for t in report["tasks"].values()), report
    (iid, res), = load_results(out, "demos").items()
    ds = load_dataset(Path(report["dataset"]["root"]))
    assert ds.num_episodes == 2 and len(ds) == report["dataset"]["frames"] == sum(e.frames for e in res.episodes)
    rows = read_episode_columns(Path(report["dataset"]["root"]))
    assert sorted((r["task_kind"], r["seed"]) for r in rows) == sorted((e.task, e.seed) for e in res.episodes)
    shards = [load_dataset(Path(d)) for d in res.datasets]
    assert [s.num_episodes for s in shards] == [1, 1]

    # the same item again, from the planned params and the runner's item seed
    prev = {"catalog": load_results(out, "catalog"), "assets": load_results(out, "assets")}
    ctx = PlanContext(job_file=tmp_path / "job.toml", job_dir=tmp_path, work_dir=out, seed=0, previous=prev)
    (item,) = plan_demos(DemosConfig(**demos), ctx)
    again = tmp_path / "again"
    res2 = record_mixed(item.params, ItemContext(item_id=iid, stage="demos", seed=derive_seed(0, "demos", iid),
                                                 out_dir=again, final_dir=again, work_dir=out))
    assert res2.episodes == res.episodes
    for a, b in zip(res.datasets, res2.datasets, strict=True):
        x, y = load_dataset(Path(a)), load_dataset(Path(b))
        for col in ("observation.state", "action"):
            np.testing.assert_array_equal(np.stack(x.hf_dataset[col]), np.stack(y.hf_dataset[col]), err_msg=col)


@pytest.mark.slow
def test_the_contact_summary_of_a_batched_engine_reports_peaks_within_capacity(catalog, tmp_path):
    """MuJoCo-Warp (the GPU layout, here on CPU): 2 worlds stepped 0.6 s; the monitor's peaks are
    real counts below the per-world capacities (~40 s on 2 cores)."""
    from stages.demos.kitchen import AssetLibrary, write_kitchen
    from stages.demos.mixed import contact_summary
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    lib = AssetLibrary.from_folder(catalog / "assets", catalog / "catalog" / "default" / "generated.json")
    room = write_kitchen(tmp_path / "kitchen", lib, scene_id="k", rng=np.random.default_rng(5))
    eng = BatchEngine(room, panda_root=None, work_dir=tmp_path,
                      config=EngineConfig(worlds=2, layout="batched", record_images=False))
    eng.run(Listed(room, {0: [("push_object", 1, None)], 1: [("press_button", 2, None)]}), max_steps=300)
    c = contact_summary(eng)
    assert c["solver"] == "mujoco_warp" and c["overflows"] == 0
    assert 0 < c["peak_contacts_per_world"] <= c["nconmax"], c
    assert 0 < c["peak_constraint_rows_per_world"] <= c["njmax"], c
    assert c["peak_contacts_per_world"] <= c["peak_contacts_all_worlds"] <= c["naconmax"] == 2 * c["nconmax"], c
