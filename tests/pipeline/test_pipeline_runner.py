"""The runner on real (small) stage functions: outputs, seeds, caching, failures, retries."""

from __future__ import annotations

import fcntl
import json
import os
import sqlite3
import time

import pytest
from pipeline_testutil import text_job, tree_hashes, write_texts
from stagefns import MergeResult, TextResult

from pipeline import JobError, JobKind, PlanContext, WorkItem, derive_seed, load_job, load_results, run_job


def _rows(out):
    con = sqlite3.connect(out / "state.sqlite")
    try:
        return con.execute("SELECT step, item_id, status, outcome, error, error_kind, attempts FROM items "
                           "ORDER BY step, item_id").fetchall()
    finally:
        con.close()


def test_first_run_outputs_results_and_seeds(tmp_path, registry):
    job = load_job(text_job(tmp_path, n=5), registry=registry)
    s = run_job(job, registry=registry, progress=False)
    out = job.out
    assert s.status == "ok" and (s.done, s.cached, s.failed) == (6, 0, 0)
    assert s.step("texts").done == 5 and s.step("merged").done == 1
    for i in range(5):
        meta = json.loads((out / "texts" / f"t{i:02d}" / "meta.json").read_text())
        assert meta["seed"] == derive_seed(7, "texts", f"t{i:02d}") and meta["stage"] == "texts"
    results = load_results(out, "texts")
    assert list(results) == [f"t{i:02d}" for i in range(5)]
    assert all(isinstance(r, TextResult) for r in results.values())
    merged = load_results(out, "merged")["all"]
    assert isinstance(merged, MergeResult) and merged.total_words == sum(r.words for r in results.values()) + 5
    assert not (out / "texts" / ".tmp").exists()
    summary = json.loads((out / "reports" / "summary.json").read_text())
    assert summary["totals"] == {"done": 6, "cached": 0, "failed": 0}
    assert "step 'texts' (texts): done 5" in (out / "logs" / "job.log").read_text()
    index = json.loads((out / "reports" / "texts_index.json").read_text())   # written by finalize
    assert sorted(index["ok"]) == [f"t{i:02d}" for i in range(5)] and index["failed"] == {}


def test_second_run_does_no_work_and_changed_input_recomputes_only_it(tmp_path, registry):
    job = load_job(text_job(tmp_path, n=6), registry=registry)
    first = run_job(job, registry=registry, progress=False)
    before = tree_hashes(job.out)
    inode = (job.out / "texts" / "t00" / "text.txt").stat().st_ino
    t0 = time.perf_counter()
    second = run_job(job, registry=registry, progress=False)
    t_cached = time.perf_counter() - t0
    assert (second.done, second.cached, second.failed) == (0, 7, 0)
    assert tree_hashes(job.out) == before
    assert (job.out / "texts" / "t00" / "text.txt").stat().st_ino == inode   # not rewritten
    assert t_cached < max(first.seconds, 1.0), (t_cached, first.seconds)
    assert all(r[3] == "cached" for r in _rows(job.out))
    # change one input: that item and the merge (it depends on it) are recomputed, nothing else
    (tmp_path / "data" / "t03.txt").write_text("completely new words here\n")
    third = run_job(job, registry=registry, progress=False)
    assert (third.step("texts").done, third.step("texts").cached) == (1, 5)
    assert (third.step("merged").done, third.step("merged").cached) == (1, 0)
    assert "COMPLETELY NEW WORDS HERE" in (job.out / "texts" / "t03" / "text.txt").read_text()
    assert len(_rows(job.out)) == 7                                           # no duplicate rows


def test_seed_change_recomputes_everything(tmp_path, registry):
    path = text_job(tmp_path, n=3, merge=False, executor="inline")
    run_job(path, registry=registry, progress=False)
    a = tree_hashes(tmp_path / "out" / "t")
    path.write_text(path.read_text().replace("seed = 7", "seed = 8"))
    s = run_job(path, registry=registry, progress=False)
    assert (s.done, s.cached) == (3, 0)
    assert tree_hashes(tmp_path / "out" / "t") != a


def test_failures_are_isolated_reported_and_bad_input_is_not_recomputed(tmp_path, registry):
    path = text_job(tmp_path, n=5, config='bad = ["t01"]\nrejected = ["t02"]\ncrash = ["t03"]', retries=1,
                    executor="inline")
    s = run_job(path, registry=registry, progress=False)
    st = s.step("texts")
    assert (st.done, st.failed) == (2, 3) and s.status == "failed_items"
    reasons = {f.item_id: f.reason for f in st.failures}
    assert reasons["t01"].endswith("t01.txt: content is not acceptable (second line of detail)")
    assert reasons["t02"].endswith("t02.txt: rejected while planning")
    assert reasons["t03"] == "RuntimeError: boom in t03"
    assert all("\n" not in r for r in reasons.values())
    out = tmp_path / "out" / "t"
    assert sorted(p.name for p in (out / "texts").iterdir()) == ["t00", "t04"]
    rows = {r[1]: r for r in _rows(out) if r[0] == "texts"}
    assert rows["t01"][5:] == ("item", 1)            # ItemError: one attempt, never retried
    assert rows["t03"][5:] == ("exception", 2)       # retried once
    con = sqlite3.connect(out / "state.sqlite")
    tb = con.execute("SELECT traceback FROM items WHERE item_id='t03'").fetchone()[0]
    con.close()
    assert "Traceback" in tb and "boom in t03" in tb
    summary = json.loads((out / "reports" / "summary.json").read_text())
    assert {f["item_id"] for f in summary["steps"][0]["failures"]} == {"t01", "t02", "t03"}
    assert json.loads((out / "reports" / "texts_index.json").read_text())["failed"] == reasons
    # re-run: the ItemError is reused (no work), the unexpected exception is tried again
    s2 = run_job(path, registry=registry, progress=False)
    st2 = s2.step("texts")
    assert (st2.done, st2.cached, st2.failed, st2.failed_cached) == (0, 2, 3, 1)
    assert {f.item_id: f.reason for f in st2.failures} == reasons
    assert {r[1]: r[6] for r in _rows(out) if r[0] == "texts"}["t03"] == 2
    s3 = run_job(path, registry=registry, progress=False, retry_failed=True)
    assert s3.step("texts").failed_cached == 0


def test_retries_recover_a_transient_failure(tmp_path, registry):
    path = text_job(tmp_path, n=3, merge=False, config='flaky = ["t01"]\nflaky_dir = "flaky"', retries=1,
                    executor="inline")
    s = run_job(path, registry=registry, progress=False)
    assert (s.done, s.failed) == (3, 0)
    assert {r[1]: r[6] for r in _rows(tmp_path / "out" / "t")} == {"t00": 1, "t01": 2, "t02": 1}


def test_no_retries_fails_a_transient_failure(tmp_path, registry):
    path = text_job(tmp_path, n=3, merge=False, config='flaky = ["t01"]\nflaky_dir = "flaky"', retries=0,
                    executor="inline")
    s = run_job(path, registry=registry, progress=False)
    assert [(f.item_id, f.reason) for f in s.step("texts").failures] == [("t01", "ConnectionError: transient failure")]
    # not an ItemError: the next run tries again (and the marker now lets it pass)
    s2 = run_job(path, registry=registry, progress=False)
    assert (s2.step("texts").done, s2.step("texts").cached, s2.failed) == (1, 2, 0)


def test_dead_worker_process_fails_only_its_item(tmp_path, registry):
    path = text_job(tmp_path, n=6, merge=False, config='die = ["t02"]', retries=1, workers=2)
    s = run_job(path, registry=registry, progress=False)
    st = s.step("texts")
    assert st.failed == 1 and st.failures[0].item_id == "t02"
    assert "BrokenProcessPool" in st.failures[0].reason
    # innocent items caught in the broken pool are retried and succeed
    assert sorted(p.name for p in (tmp_path / "out" / "t" / "texts").iterdir()) == ["t00", "t01", "t03", "t04", "t05"]
    attempts = {r[1]: r[6] for r in _rows(tmp_path / "out" / "t")}
    assert attempts.pop("t02") == 2 and set(attempts.values()) == {1}    # only the culprit is charged


def test_item_that_fails_now_loses_its_old_output(tmp_path, registry):
    path = text_job(tmp_path, n=3, merge=False, executor="inline")
    run_job(path, registry=registry, progress=False)
    assert (tmp_path / "out" / "t" / "texts" / "t01").is_dir()
    path.write_text(path.read_text().replace('folder = "data"', 'folder = "data"\nbad = ["t01"]'))
    s = run_job(path, registry=registry, progress=False)
    assert s.step("texts").failed == 1
    assert not (tmp_path / "out" / "t" / "texts" / "t01").exists()


def test_stale_tmp_is_removed_and_executors_agree(tmp_path, registry):
    path = text_job(tmp_path, n=5)
    junk = tmp_path / "a" / "texts" / ".tmp" / "t00.deadbeef"
    junk.mkdir(parents=True)
    (junk / "half.txt").write_text("half-written")
    run_job(path, out=tmp_path / "a", executor="inline", registry=registry, progress=False)
    run_job(path, out=tmp_path / "b", executor="local", workers=2, registry=registry, progress=False)
    assert not (tmp_path / "a" / "texts" / ".tmp").exists()
    ha, hb = tree_hashes(tmp_path / "a"), tree_hashes(tmp_path / "b")
    assert len(ha) == 11 and ha == hb


def test_failed_dependency_fails_dependent_item(tmp_path, registry):
    write_texts(tmp_path / "data", 2)

    def plan_dep(cfg, pctx: PlanContext):
        from stagefns import MergeParams

        return [WorkItem(item_id="m", fn="stagefns:merge_texts", params=MergeParams(files=[]),
                         depends_on=("texts/t00", "texts/t01"))]

    from stagefns import MergeConfig

    reg = {**registry, "dep": JobKind(name="dep", config=MergeConfig, plan=plan_dep)}
    path = text_job(tmp_path, merge=False, config='bad = ["t01"]', executor="inline")
    path.write_text(path.read_text() + '\n[[step]]\nname = "d"\nkind = "dep"\n')
    s = run_job(path, registry=reg, progress=False)
    assert [(f.item_id, f.reason) for f in s.step("d").failures] == [
        ("m", "depends on failed item texts/t01: " + s.step("texts").failures[0].reason)]


def test_missing_input_file_fails_the_item(tmp_path, registry):
    from stagefns import TrivialConfig, TrivialParams

    def plan(cfg, pctx):
        return [WorkItem(item_id="x", fn="stagefns:trivial", params=TrivialParams(index=1),
                         input_files=(tmp_path / "gone.bin",))]

    reg = {"k": JobKind(name="k", config=TrivialConfig, plan=plan)}
    (tmp_path / "j.toml").write_text('[job]\nname = "j"\n[[step]]\nname = "s"\nkind = "k"\n[step.config]\nn = 1\n')
    s = run_job(tmp_path / "j.toml", registry=reg, progress=False, executor="inline")
    assert s.step("s").failures[0].reason == f"{tmp_path / 'gone.bin'}: input file not found"


def test_bad_plans_are_job_errors(tmp_path):
    from stagefns import TrivialConfig, TrivialParams

    def plan(cfg, pctx):
        return [WorkItem(item_id="a/b", fn="stagefns:trivial", params=TrivialParams(index=1))]

    (tmp_path / "j.toml").write_text('[job]\nname = "j"\n[[step]]\nname = "s"\nkind = "k"\n[step.config]\nn = 1\n')
    reg = {"k": JobKind(name="k", config=TrivialConfig, plan=plan)}
    with pytest.raises(JobError, match="planned item id 'a/b'"):
        run_job(tmp_path / "j.toml", registry=reg, progress=False)
    summary = json.loads((tmp_path / "out" / "j" / "reports" / "summary.json").read_text())
    assert summary["status"] == "error" and "a/b" in summary["error"]


def test_work_dir_lock(tmp_path, registry):
    path = text_job(tmp_path, n=1, merge=False)
    out = tmp_path / "out" / "t"
    out.mkdir(parents=True)
    fd = os.open(out / ".lock", os.O_RDWR | os.O_CREAT)
    fcntl.flock(fd, fcntl.LOCK_EX)
    try:
        with pytest.raises(JobError, match="another run is using this work directory"):
            run_job(path, registry=registry, progress=False)
    finally:
        os.close(fd)
    assert run_job(path, registry=registry, progress=False, executor="inline").done == 1


def test_finalize_failure_is_raised_after_the_summary(tmp_path, registry):
    from stagefns import TEXT_KIND

    def bad_finalize(cfg, pctx, results):
        assert pctx.step == "texts" and set(results) == set(pctx.previous["texts"])
        raise RuntimeError(f"index write failed for {len(results)} items")

    reg = {**registry, "texts": JobKind(name="texts", config=TEXT_KIND.config, plan=TEXT_KIND.plan,
                                        finalize=bad_finalize)}
    path = text_job(tmp_path, n=2, executor="inline")
    with pytest.raises(RuntimeError, match="index write failed for 2 items"):
        run_job(path, registry=reg, progress=False)
    summary = json.loads((tmp_path / "out" / "t" / "reports" / "summary.json").read_text())
    assert summary["status"] == "error" and summary["error"] == "RuntimeError: index write failed for 2 items"
    # the items themselves are done and cached for the next run
    s = run_job(path, registry=registry, progress=False)
    assert (s.step("texts").cached, s.step("merged").done) == (2, 1)


def test_incompatible_state_database_is_a_clear_error(tmp_path, registry):
    path = text_job(tmp_path, n=1, merge=False, executor="inline")
    out = tmp_path / "out" / "t"
    out.mkdir(parents=True)
    con = sqlite3.connect(out / "state.sqlite")
    con.execute("PRAGMA user_version=99")
    con.close()
    with pytest.raises(JobError, match="schema version 99"):
        run_job(path, registry=registry, progress=False)
