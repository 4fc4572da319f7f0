"""Crash-safe resume: kill -9 a running job (main process and workers) mid-way, run it again, and get
the same outputs as an uninterrupted run, one database row per item, no temporary leftovers."""

from __future__ import annotations

import contextlib
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

from pipeline_testutil import subprocess_env, text_job, tree_hashes

from pipeline import run_job

N = 8


def _n_done(out: Path) -> int:
    db = out / "state.sqlite"
    if not db.exists():
        return 0
    try:
        con = sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=5)
        try:
            return con.execute("SELECT COUNT(*) FROM items WHERE status='done'").fetchone()[0]
        finally:
            con.close()
    except sqlite3.OperationalError:   # tables not created yet
        return 0


def _start(job: Path, out: Path) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "pipeline.cli", "run", str(job), "--out", str(out), "--workers", "2",
           "--no-progress", "--log-level", "WARNING"]
    return subprocess.Popen(cmd, env=subprocess_env(), start_new_session=True, cwd=job.parent.parent,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def _children(pid: int) -> set[int]:
    """Live child processes of pid (Linux /proc)."""
    out = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid and fields[0] != "Z":
            out.add(int(stat.parent.name))
    return out


def _alive(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def _kill_when(proc: subprocess.Popen, out: Path, n_done: int, group: bool, timeout: float = 60.0) -> int:
    """SIGKILL the job once n_done items are done (its whole process group, or only the main process,
    whose pool workers must then die too); returns the count seen."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if proc.poll() is not None:
            raise AssertionError(f"job ended before it was killed: {proc.stderr.read().decode()[-2000:]}")
        seen = _n_done(out)
        if seen >= n_done:
            workers = _children(proc.pid)
            if group:
                os.killpg(proc.pid, signal.SIGKILL)
            else:
                proc.kill()
            proc.wait(timeout=30)
            deadline = time.monotonic() + 10
            while any(_alive(w) for w in workers) and time.monotonic() < deadline:
                time.sleep(0.05)
            assert not [w for w in workers if _alive(w)], "worker processes outlived the killed runner"
            if not group:
                with contextlib.suppress(ProcessLookupError):   # nothing should be left; be sure
                    os.killpg(proc.pid, signal.SIGKILL)
            return seen
        time.sleep(0.02)
    os.killpg(proc.pid, signal.SIGKILL)
    raise AssertionError("job made no progress")


def test_kill_9_then_resume_gives_identical_outputs(tmp_path):
    job = text_job(tmp_path, n=N, config="sleep_s = 0.2", direct=True, workers=2)
    reference = run_job(job, out=tmp_path / "ref", registry={}, progress=False, executor="local", workers=2)
    assert reference.done == N + 1
    out = tmp_path / "crashy"
    seen = []
    for n_done, group in ((2, False), (5, True)):     # two kills at different points
        seen.append(_kill_when(_start(job, out), out, n_done, group))
    assert seen[0] < N and seen[-1] < N + 1, seen
    con = sqlite3.connect(out / "state.sqlite")
    interrupted = con.execute("SELECT COUNT(*) FROM items WHERE status='running'").fetchone()[0]
    con.close()
    assert interrupted >= 1                  # killed mid-way: items were being computed
    resumed = run_job(job, out=out, registry={}, progress=False, executor="local", workers=2)
    assert resumed.failed == 0 and resumed.done + resumed.cached == N + 1
    assert resumed.cached >= seen[-1] - 1 and resumed.done >= 1      # finished work was not redone
    assert tree_hashes(out) == tree_hashes(tmp_path / "ref")
    assert len(tree_hashes(out)) == 2 * N + 1
    assert not (out / "texts" / ".tmp").exists() and not (out / "merged" / ".tmp").exists()
    con = sqlite3.connect(out / "state.sqlite")
    rows = con.execute("SELECT step, item_id, status FROM items").fetchall()
    runs = con.execute("SELECT status FROM runs ORDER BY run_id").fetchall()
    con.close()
    assert len(rows) == len({(s, i) for s, i, _ in rows}) == N + 1
    assert {s for _, _, s in rows} == {"done"}
    assert [r[0] for r in runs] == ["running", "running", "ok"]   # the two killed runs never finished
    # and the completed work dir is a no-op to run again
    again = run_job(job, out=out, registry={}, progress=False)
    assert (again.done, again.cached) == (0, N + 1)


_HOLD_TEMP = """
import os, secrets, sys, time
from pathlib import Path
tmp = Path(sys.argv[1]) / f".tmp-demos-{os.getpid()}-{secrets.token_hex(4)}"   # as a dataset merge names it
(tmp / "data" / "chunk-000").mkdir(parents=True)
(tmp / "data" / "chunk-000" / "file-000.parquet").write_bytes(b"partial" * 1000)
print(tmp, flush=True)
time.sleep(120)
"""


def _hold_temp(datasets: Path) -> tuple[subprocess.Popen, Path]:
    """A process that made a merge's temporary folder in ``datasets`` and is still writing it."""
    proc = subprocess.Popen([sys.executable, "-c", _HOLD_TEMP, str(datasets)], stdout=subprocess.PIPE,
                            text=True)
    return proc, Path(proc.stdout.readline().strip())


def test_resumed_run_removes_temporaries_of_a_killed_predecessor_only(tmp_path):
    """A merge killed mid-way leaves ``datasets/.tmp-demos-<pid>-<hex>/``: the next run removes it, and
    keeps a temporary of a process still alive and any other dot-folder."""
    job = text_job(tmp_path, n=3, direct=True, workers=1, executor="inline")
    out = tmp_path / "out"
    first = run_job(job, out=out, registry={}, progress=False)
    assert first.failed == 0
    killed, orphan = _hold_temp(out / "datasets")
    killed.kill()
    killed.wait(timeout=30)
    live, kept = _hold_temp(out / "datasets")
    other = out / "datasets" / ".tmp-notes"
    other.mkdir()
    try:
        assert orphan.is_dir() and kept.is_dir() and orphan != kept
        again = run_job(job, out=out, registry={}, progress=False)
        assert (again.done, again.cached, again.failed) == (0, first.done, 0)
        assert not orphan.exists(), "the killed run's temporary is left behind"
        assert kept.is_dir() and (kept / "data" / "chunk-000" / "file-000.parquet").is_file()
        assert other.is_dir()
        log = (out / "logs" / "job.log").read_text()
        assert f"removed {orphan}, left by process {killed.pid}" in log
    finally:
        live.kill()
        live.wait(timeout=30)
