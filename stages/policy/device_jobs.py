"""Subprocess jobs and the archive of ``stages/policy/scripts/gpu_policies.py all`` (issue 17 on the
device): the data job under a wall limit, the kernel warm-up job beside the training, and the one
tgz a device call brings back."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def data_job(job: Path, out: Path, seconds: float, log: Path) -> int:
    """``agentworld run JOB --out OUT`` for at most ``seconds`` (its process group stopped then)."""
    log.parent.mkdir(parents=True, exist_ok=True)
    with log.open("w") as f:
        p = subprocess.Popen([sys.executable, "-m", "pipeline.cli", "run", str(job), "--no-progress", "--out", str(out)],
                             cwd=REPO, stdout=f, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            return p.wait(timeout=max(1.0, seconds))
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, 15)  # the job's own process group (its workers)
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, 9)
                p.wait()
            return 124


def policy_importable(pol: str) -> str | None:
    """None if lerobot's ``pol`` policy and what it needs import, else the last line of the error
    (lerobot's diffusion module imports without diffusers; its training then fails)."""
    mods = {"act": "lerobot.policies.act.modeling_act",
            "diffusion": "lerobot.policies.diffusion.modeling_diffusion, diffusers"}
    r = subprocess.run([sys.executable, "-c", f"import {mods[pol]}"], capture_output=True, text=True, cwd=REPO)
    return None if r.returncode == 0 else ((r.stderr.strip().splitlines() or ["exit %d" % r.returncode])[-1])


EVAL_MODULES = ("greenlet", "av", "lerobot", "warp", "newton", "pxr")  # engine programs, videos, policy, sim, scenes


def eval_preflight(python: str = sys.executable, modules: tuple[str, ...] = EVAL_MODULES) -> list[str]:
    """What the closed-loop eval processes need and ``python`` lacks, one line each, [] when nothing:
    ``modules`` (default :data:`EVAL_MODULES`) and example-robot-data's Panda description (the engine's
    robot). Checked in a subprocess with the eval's environment before any training: session 21
    trained for 12 minutes, then every eval process stopped in its first seconds for want of the
    Panda description (and the kernel warm-up job beside the training had failed on it unseen)."""
    code = ("import importlib.util as u\n"
            "from stages.simulate.robot import find_panda_description\n"
            f"bad = ['python module ' + m + ' is not installed' for m in {tuple(modules)!r} if u.find_spec(m) is None]\n"
            "try:\n    find_panda_description(None)\nexcept Exception as e:\n    bad.append(str(e))\n"
            "print('\\n'.join(bad))")
    r = subprocess.run([python, "-c", code], cwd=REPO, capture_output=True, text=True)
    if r.returncode != 0:
        return [f"the eval's preflight failed: {(r.stderr.strip().splitlines() or ['exit %d' % r.returncode])[-1]}"]
    return [line for line in r.stdout.splitlines() if line.strip()]


def warm_job(work: Path, device: str, base: Path = REPO / "jobs" / "policies_gpu1.toml") -> Path:
    """A tiny demos job (``base``'s catalog and assets steps, one kitchen, two push_object worlds for
    at most 2 s, no merge) written to ``WORK/warm/job.toml``: run beside the training, it fills Warp's
    kernel cache (``WARP_CACHE_PATH``) with the engine's kernels, which the eval processes then load
    instead of each compiling them at once (session 19: 54 modules, ~4.5 min in each of 16 processes)."""
    import tomllib

    steps = [st for st in tomllib.loads(base.read_text())["step"] if st["kind"] in ("default_catalog", "ingest")]

    def val(v) -> str:
        return json.dumps(v) if not isinstance(v, bool) else str(v).lower()

    lines = ['[job]', 'name = "warm_kernels"', 'seed = 0', f'out = {json.dumps(str(work / "warm" / "out"))}',
             'executor = "inline"', 'workers = 1', 'retries = 0']
    for st in [*steps, {"name": "warm", "kind": "demos", "config": {
            "tasks": ["push_object"], "worlds": 1, "batch_worlds": 2, "episodes_per_shard": 2, "device": device,
            "record_depth": False, "max_seconds": 2.0, "merge": False}}]:
        lines += ["", "[[step]]", f"name = {json.dumps(st['name'])}", f"kind = {json.dumps(st['kind'])}", "[step.config]"]
        lines += [f"{k} = {val(v)}" for k, v in st.get("config", {}).items()]
    job = work / "warm" / "job.toml"
    job.parent.mkdir(parents=True, exist_ok=True)
    job.write_text("\n".join(lines) + "\n")
    return job


def pack(work: Path, runs: Path, results: Path, dst: Path, limit_mb: float = 15.0,
          data: Path | None = None) -> Path:
    """One tgz of what a device call brings back: the table, each run's train.json / curve / eval.json
    (merged and per kitchen) and logs, the data job's reports, the driver's log; rollout videos
    only while the archive stays under ``limit_mb`` MiB."""
    import tarfile

    files = [p for p in (work / "all.log", work / "all.json", runs / "plan.json") if p.is_file()]
    files += sorted(results.rglob("*")) + sorted((work / "logs").glob("*.log")) + sorted((runs / "logs").glob("*.log"))
    files += sorted(((data or work / "data") / "reports").glob("*.json"))
    for run in sorted(runs.glob("*_*")):
        files += [run / n for n in ("train.json", "curve.csv", "curve.png", "train.log") if (run / n).is_file()]
        files += sorted((run / "eval").rglob("eval.json")) + sorted((run / "eval").rglob("eval.log"))
    videos = sorted(runs.glob("*/eval/*/videos/*/*.mp4"))
    size = sum(p.stat().st_size for p in files if p.is_file())
    for v in videos:  # compressed logs shrink; videos do not
        if size + v.stat().st_size < limit_mb * 2**20 * 0.8:
            files.append(v)
            size += v.stat().st_size
    dst.parent.mkdir(parents=True, exist_ok=True)
    tmp = dst.with_suffix(".tmp")
    with tarfile.open(tmp, "w:gz") as tar:
        for f in dict.fromkeys(files):
            if f.is_file():
                tar.add(f, arcname=str(f.relative_to(work)) if f.is_relative_to(work) else f.name)
    tmp.rename(dst)
    return dst
