"""The device driver of issue 17 (stages/policy/scripts/gpu_policies.py): the step budget it derives
from a probe's training curve, and the table it writes from runs' train.json / eval.json."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "stages" / "policy" / "scripts" / "gpu_policies.py"


@pytest.fixture(scope="module")
def driver():
    spec = importlib.util.spec_from_file_location("gpu_policies", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_seconds_per_step_and_start_up_from_a_curve(driver, tmp_path):
    # logged every 10 steps, 0.5 s a step after 40 s of start-up
    rows = ["step,samples,epochs,loss,grad_norm,lr,update_s,data_s,wall_s"]
    rows += [f"{s},{16 * s},0.1,1.0,1.0,1e-5,0.4,0.1,{40 + 0.5 * s:.2f}" for s in (10, 20, 30, 40, 50)]
    (tmp_path / "curve.csv").write_text("\n".join(rows) + "\n")
    per, startup = driver._seconds_per_step(tmp_path)
    assert per == pytest.approx(0.5)
    assert startup == pytest.approx(40.0)
    (tmp_path / "curve.csv").write_text(rows[0] + "\n" + rows[1] + "\n")
    with pytest.raises(RuntimeError, match="fewer than 2 curve rows"):
        driver._seconds_per_step(tmp_path)


def test_table_lists_trained_runs_with_their_held_out_success(driver, tmp_path):
    runs, out = tmp_path / "runs", tmp_path / "out"
    act = runs / "push_pull_act"
    (act / "eval").mkdir(parents=True)
    (act / "train.json").write_text(json.dumps({"steps": 900, "wall_seconds": 812.5, "last_loss": 0.21}))
    (act / "eval" / "eval.json").write_text(json.dumps({"overall": {"episodes": 50, "successes": 31}}))
    (runs / "push_pull_diffusion").mkdir()  # no train.json: its training failed, not in the table
    assert driver.main(["table", "--runs", str(runs), "--out", str(out)]) == 0
    rows = json.loads((out / "table.json").read_text())
    assert rows == [{"family": "push_pull", "task": "push_object", "policy": "act", "paper_act": 0.72,
                     "steps": 900, "train_wall_s": 812.5, "last_loss": 0.21, "episodes": 50, "successes": 31,
                     "success_rate": 0.62}]
    assert "| push_pull | push_object | act | 900 | 812.5 | 31/50 | 0.62 | 0.72 |" in (out / "table.md").read_text()
    assert (out / "push_pull_act_eval.json").is_file()


def test_table_of_no_trained_run_is_written_empty(driver, tmp_path):
    assert driver.main(["table", "--runs", str(tmp_path / "none"), "--out", str(tmp_path / "out")]) == 0
    assert json.loads((tmp_path / "out" / "table.json").read_text()) == []


def _part(scene: str, results: list[tuple[bool, str]]) -> dict:
    """An eval.json of one kitchen as ``agentworld eval`` writes it (the keys the merge reads)."""
    eps = [{"task": "push_object", "scene": scene, "seed": k, "world": k, "success": ok, "reason": why,
            "frames": 30, "sim_seconds": 1.0, "video": ""} for k, (ok, why) in enumerate(results)]
    n, s = len(eps), sum(ok for ok, _ in results)
    fails: dict = {}
    for ok, why in results:
        if not ok:
            fails[why] = fails.get(why, 0) + 1
    row = {"episodes": n, "successes": s, "success_rate": round(s / n, 4), "failures": fails}
    return {"checkpoint": "/c", "policy": {"type": "act"}, "device": "cuda", "worlds": n, "scenes": [scene],
            "seeds": list(range(n)), "held_out": {"checked": True, "seen_scenes": [], "training_scenes": ["k0"]},
            "tasks": {"push_object": row}, "families": {"push_pull": row}, "overall": row, "episodes": eps,
            "runner": {"model_calls": 10, "chunks": 20}, "engine": [{"steps": 1}], "wall_seconds": 100.0 + n}


def test_per_kitchen_reports_merge_into_the_runs_report():
    from stages.policy.evalmerge import merge_reports

    a = _part("kitchen_ws101", [(True, ""), (False, "object not moved"), (False, "object not moved")])
    b = _part("kitchen_ws102", [(False, "object not moved"), (False, "fell over"), (True, "")])
    b["checkpoint"] = "/c"
    r = merge_reports([a, b])
    assert r["overall"] == {"episodes": 6, "successes": 2, "success_rate": 0.3333,
                            "failures": {"fell over": 1, "object not moved": 3}}
    assert r["tasks"]["push_object"] == r["families"]["push_pull"] == r["overall"]
    assert r["scenes"] == ["kitchen_ws101", "kitchen_ws102"] and len(r["episodes"]) == 6
    assert r["runner"] == {"model_calls": 20, "chunks": 40} and r["wall_seconds"] == 103.0
    assert [p["successes"] for p in r["parts"]] == [1, 1] and r["held_out"]["checked"]
    b["checkpoint"] = "/other"
    with pytest.raises(ValueError, match="different checkpoints"):
        merge_reports([a, b])
    with pytest.raises(ValueError, match="no eval.json parts"):
        merge_reports([])


def test_default_eval_limit_is_a_multiple_of_the_experts_median_episode(driver, tmp_path):
    """A dataset of three push_object episodes of 30, 60 and 150 frames at 30 fps (median 2 s): the
    default limit is 1.5 x 2 s, at most the task's 20 s; without a dataset, the task's limit."""
    from stages.dataset import DatasetSpec, EpisodeInfo, merge_shards, open_shard
    from stages.dataset.synthetic import synthetic_frame
    from stages.demos.tasks import task

    spec = DatasetSpec(cameras=())
    with open_shard(tmp_path / "shards", "s0", spec) as shard:
        for e, n in enumerate((30, 60, 150)):
            shard.begin_episode(EpisodeInfo(task="push the mug", task_kind="push_object", scene_id="k", seed=e))
            for i in range(n):
                shard.add_frame(synthetic_frame(spec, 0, e, i))
            shard.end_episode(success=True)
    ds = merge_shards(tmp_path / "shards", tmp_path / "ds").root
    run = tmp_path / "run"
    run.mkdir()
    (run / "train.json").write_text(json.dumps({"config": {"dataset": str(ds)}}))
    limit, why = driver._default_max_seconds(run, "push_object", 1.5)
    assert limit == pytest.approx(3.0) and "median episode 2.0 s (3 training episodes)" in why
    task_limit = task("push_object").max_seconds
    assert driver._default_max_seconds(run, "push_object", 100.0)[0] == pytest.approx(task_limit)
    assert driver._default_max_seconds(run, "open_drawer", 1.5)[0] is None  # no such episode: the task's
    (run / "train.json").write_text("{}")
    assert driver._default_max_seconds(run, "push_object", 1.5) == (
        None, f"the task's limit {task_limit:.0f} s (no training dataset in train.json)")


TINY_ACT = ("--policy.dim_model=32", "--policy.dim_feedforward=64", "--policy.n_heads=2",
            "--policy.n_encoder_layers=1", "--policy.latent_dim=8")


@pytest.mark.slow  # 86-149 s on 2 shared cores (data job, a training, 1 eval process), twice with --data
def test_all_records_rgb_only_trains_evaluates_and_packs_one_archive(tmp_path):
    """``all`` at CPU scale on a data job of one kitchen, two push_object episodes, RGB only
    (record_depth = false): every phase runs, the dataset has no depth column, ACT trains 3 steps,
    the held-out eval runs its checkpoint, and one tgz holds the table, eval.json and logs."""
    import subprocess
    import sys
    import tarfile

    pytest.importorskip("newton")
    pytest.importorskip("lerobot")
    from kitchen_testutil import KITCHEN, PACKAGES

    job = tmp_path / "tiny.toml"
    job.write_text(f"""[job]
name = "tiny_all"
seed = 0
out = "{tmp_path / 'unused'}"
executor = "inline"
workers = 1
[[step]]
name = "catalog"
kind = "default_catalog"
[step.config]
variants = 5
categories = {json.dumps(list(KITCHEN))}
[[step]]
name = "assets"
kind = "ingest"
[step.config]
catalog_step = "catalog"
only = {json.dumps(list(PACKAGES))}
[[step]]
name = "push_pull"
kind = "demos"
[step.config]
tasks = ["push_object"]
episodes_per_shard = 2
batch_worlds = 2
width = 64
height = 48
record_depth = false
""")
    work, out = tmp_path / "work", tmp_path / "out"
    cmd = [sys.executable, str(SCRIPT), "all", "--seconds", "1200", "--work", str(work), "--out", str(out),
           "--job", str(job), "--device", "cpu", "--policy", "act", "--probe-steps", "0", "--max-steps", "3",
           "--num-workers", "0", *(f"--act-arg={x}" for x in TINY_ACT), "--scenes", "6", "--seeds", "9",
           "--max-seconds", "0.5", "--jobs", "1", "--eval-seconds", "400", "--min-train-seconds", "100"]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=1500, env={**__import__("os").environ,
                                                                                  "OMP_NUM_THREADS": "1"})
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    info = json.loads((work / "data" / "datasets" / "push_pull" / "meta" / "info.json").read_text())
    assert not [k for k in info["features"] if k.startswith("depth.")]
    assert "observation.images.head" in info["features"]
    phases = json.loads((work / "all.json").read_text())["phases"]
    assert [phases[p]["exit"] for p in ("data", "train", "eval", "done")] == [0, 0, 0, 0]
    log = (work / "all.log").read_text()
    assert "eval [1/1] push_pull_act kitchen_ws6: 0/1 successes" in log or "1/1 successes" in log
    with tarfile.open(out / "policies_all.tgz") as tar:
        names = set(tar.getnames())
        rows = json.loads(tar.extractfile("results/table.json").read())
        merged = json.loads(tar.extractfile("runs/push_pull_act/eval/eval.json").read())
    assert {"all.log", "all.json", "runs/push_pull_act/train.json", "runs/push_pull_act/eval/ws6/eval.json",
            "results/table.md", "logs/data.log"} <= names
    assert [(r["policy"], r["steps"], r["episodes"]) for r in rows] == [("act", 3, 1)]
    (ep,) = merged["episodes"]
    assert (ep["scene"], ep["seed"], ep["frames"]) == ("kitchen_ws6", 9, 15)
    assert merged["overall"]["successes"] + sum(merged["overall"]["failures"].values()) == 1

    # --data: the datasets made elsewhere (a CPU data job): no data job, the same training and eval
    work2 = tmp_path / "work2"
    cmd2 = [str(work2) if c == str(work) else c for c in cmd]
    cmd2[cmd2.index("--out") + 1] = str(work2)
    cmd2[cmd2.index("--job"):cmd2.index("--job") + 2] = ["--data", str(work / "data")]
    run = subprocess.run([str(c) for c in cmd2], capture_output=True, text=True, timeout=1500,
                         env={**__import__("os").environ, "OMP_NUM_THREADS": "1"})
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    phases = json.loads((work2 / "all.json").read_text())["phases"]
    assert (phases["data"]["seconds"], phases["data"]["datasets"]) == (0, "push_pull")
    assert not (work2 / "data").exists() and not (work2 / "logs" / "data.log").exists()
    train = json.loads((work2 / "runs" / "push_pull_act" / "train.json").read_text())
    assert Path(train["config"]["dataset"]) == work / "data" / "datasets" / "push_pull"
    with tarfile.open(work2 / "policies_all.tgz") as tar:
        assert "push_pull.json" in tar.getnames()  # the data job's report, from --data


def test_data_loader_workers_share_the_cores_left_by_the_runs(driver, monkeypatch):
    monkeypatch.setattr(driver.os, "cpu_count", lambda: 16)
    assert [driver._num_workers(n, None) for n in (1, 3, 6, 12, 20)] == [8, 5, 2, 1, 1]
    assert driver._num_workers(6, 0) == 0  # asked: as asked


def test_eval_processes_run_capped_and_are_stopped_at_the_deadline(driver, monkeypatch, tmp_path, capsys):
    """The scheduler of ``eval``: at most ``cap`` processes at once, a line per finished one, those
    still running at the deadline stopped and those not started listed (real processes that sleep)."""
    import subprocess
    import sys
    import time

    started = []

    def launch(argv, device, log, threads=None):
        started.append((argv[0], time.perf_counter()))
        return subprocess.Popen([sys.executable, "-c", f"import time; time.sleep({argv[0]})"])

    monkeypatch.setattr(driver, "_launch", launch)
    jobs = [{"argv": [str(s)], "device": "cpu", "log": tmp_path / f"{k}.log", "name": f"job{k}",
             "out": tmp_path / f"o{k}"} for k, s in enumerate((0.1, 60, 0.1, 60))]
    t0 = time.perf_counter()
    done = driver._run_all(jobs, 2, deadline=t0 + 6.0)
    assert time.perf_counter() - t0 < 40
    rc = {j["name"]: j["rc"] for j in done}
    assert rc == {"job0": 0, "job1": "stopped at the deadline", "job2": 0, "job3": "stopped at the deadline"}
    assert [a for a, _ in started] == ["0.1", "60", "0.1", "60"]  # job2 waited for a free slot
    out = capsys.readouterr().out
    assert "eval [1/4] job0: no eval.json, exit 0" in out and "job3: no eval.json, exit stopped at the deadline" in out


def test_warm_job_is_a_tiny_demos_job_on_the_training_data_jobs_catalog(tmp_path):
    """The kernel warm-up job ``all`` starts beside the training on cuda: the data job's catalog and
    assets steps, then one kitchen of two push_object worlds for at most 2 s, unmerged."""
    import tomllib

    from pipeline import build_job
    from stages.policy.device_jobs import REPO, warm_job

    path = warm_job(tmp_path, "cuda")
    spec = build_job(tomllib.loads(path.read_text()), source=str(path), base_dir=tmp_path)
    base = tomllib.loads((REPO / "jobs" / "policies_gpu1.toml").read_text())["step"]
    assert [s.name for s in spec.steps] == ["catalog", "assets", "warm"]
    assert spec.steps[0].config.categories == tuple(base[0]["config"]["categories"])
    demos = spec.steps[2].config
    assert (demos.tasks, demos.worlds, demos.batch_worlds, demos.device, demos.max_seconds, demos.merge) == (
        ("push_object",), 1, 2, "cuda", 2.0, False)
    assert spec.out == tmp_path / "warm" / "out"


def test_training_runs_get_the_batch_size_asked_for(driver, monkeypatch, tmp_path):
    """``--batch-size`` reaches every run's train-policy command (none asked: train-policy's own
    default, the paper's 16); real processes stand in for the trainings (``true``)."""
    import subprocess

    ds = tmp_path / "data" / "datasets" / "push_pull" / "meta"
    ds.mkdir(parents=True)
    (ds / "info.json").write_text("{}")
    seen = []

    def launch(argv, device, log, threads=None):
        seen.append(argv)
        return subprocess.Popen(["true"])

    monkeypatch.setattr(driver, "_launch", launch)
    extra = {"act": [], "diffusion": []}
    driver._train_all(tmp_path / "data", tmp_path / "runs", {"act": 5, "diffusion": 5}, False, ["cuda:0"], extra,
                      batch_size=64)
    driver._train_all(tmp_path / "data", tmp_path / "runs", {"act": 5}, False, ["cuda:0"], extra)
    driver._train_all(tmp_path / "data", tmp_path / "runs", {"act": 5, "diffusion": 5}, False, ["cuda:0"], extra,
                      batch_size={"*": 64, "diffusion": 32})
    assert [a[a.index("--batch-size") + 1] for a in seen[:2]] == ["64", "64"]
    assert "--batch-size" not in seen[2]
    assert [a[a.index("--batch-size") + 1] for a in seen[3:5]] == ["64", "32"]  # act, diffusion


def test_runs_are_placed_on_the_gpus_their_policy_is_given(driver, monkeypatch, tmp_path):
    """``--place act=0,1,2 --place diffusion=3`` on four GPUs: one family's ACT per GPU, the three
    Diffusion Policy runs on the fourth (real stand-in processes); bad values fail in one line."""
    import subprocess

    from stages.policy.placement import parse_place, per_policy, run_devices

    for fam in ("pick_place", "open_close", "push_pull"):
        ds = tmp_path / "data" / "datasets" / fam / "meta"
        ds.mkdir(parents=True)
        (ds / "info.json").write_text("{}")
    seen = []

    def launch(argv, device, log, threads=None):
        seen.append((argv[argv.index("--policy") + 1], device))
        return subprocess.Popen(["true"])

    monkeypatch.setattr(driver, "_launch", launch)
    gpus = [f"cuda:{i}" for i in range(4)]
    place = parse_place(["act=0,1,2", "diffusion=3"], 4)
    driver._train_all(tmp_path / "data", tmp_path / "runs", {"act": 5, "diffusion": 5}, False, gpus,
                      {"act": [], "diffusion": []}, place=place)
    assert sorted(seen) == [("act", "cuda:0"), ("act", "cuda:1"), ("act", "cuda:2")] + [("diffusion", "cuda:3")] * 3
    assert run_devices(["act", "diffusion", "act"], gpus[:2]) == ["cuda:0", "cuda:1", "cuda:0"]  # none given
    assert run_devices(["act"], ["cpu"], place) == ["cpu"]
    assert per_policy(["64", "diffusion=32"], "--batch-size") == {"*": 64, "diffusion": 32}
    for bad, fn in ((["act=0,4"], lambda v: parse_place(v, 4)), (["act"], lambda v: parse_place(v, 4)),
                    (["0"], lambda v: per_policy(v, "--batch-size")), (["act=x"], lambda v: per_policy(v, "--b"))):
        with pytest.raises(ValueError, match="expected"):
            fn(bad)


def test_gpus_are_those_cuda_visible_devices_names(driver, monkeypatch):
    """Two drivers share a four-GPU machine with ``CUDA_VISIBLE_DEVICES=0,1`` and ``2,3``: each
    places its runs on its own (the ids are the machine's; each run then sees one)."""
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "2,3")
    assert driver._gpus("cuda") == ["cuda:2", "cuda:3"]
    assert driver._gpus("cpu") == ["cpu"]


def test_eval_preflight_names_what_the_eval_processes_would_lack():
    """Real subprocess checks with this interpreter: nothing lacking here; a module that is not
    installed is named in one line."""
    pytest.importorskip("lerobot")
    from stages.policy.device_jobs import eval_preflight

    assert eval_preflight() == []
    assert eval_preflight(modules=("agentworld_no_such_module",)) == [
        "python module agentworld_no_such_module is not installed"]


def test_all_stops_before_any_training_when_the_eval_would_fail(driver, monkeypatch, tmp_path):
    """Session 21: 12 minutes of training, then every eval process stopped at once (no Panda
    description on the device). ``all`` now checks first: nothing is trained, all.json says why
    under ``done`` (which a device poll waits for)."""
    import argparse

    monkeypatch.setattr(driver, "eval_preflight", lambda: ["robots/panda_description/urdf/panda.urdf: not found"])
    monkeypatch.setattr(driver, "data_job", lambda *a, **k: pytest.fail("the data job ran"))
    monkeypatch.setattr(driver, "train", lambda *a, **k: pytest.fail("training ran"))
    monkeypatch.setattr(driver.sys, "stdout", driver.sys.stdout)  # run_all tees stdout: restored after the test
    args = argparse.Namespace(seconds=100.0, work=tmp_path / "w", out=tmp_path, job=tmp_path / "job.toml", data=None,
                              eval_seconds=None)
    assert driver.run_all(args) == 2
    done = json.loads((tmp_path / "w" / "all.json").read_text())["phases"]["done"]
    assert done["exit"] == 2 and "panda.urdf: not found" in done["preflight"]
    assert not (tmp_path / "w" / "runs").exists()
