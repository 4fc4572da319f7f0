"""Device-side driver of issue 17's training and evaluation on a host of several GPUs.

Run from the repository root on the GPU machine after ``. tests/benchmarks/gpu_env.sh``, each phase
in its own call (a call may run 10 minutes; launch long phases with ``setsid nohup`` and poll)::

    python3 -m pipeline.cli run jobs/policies_gpu4.toml --no-progress --out $HOME/pol      # datasets
    python3 stages/policy/scripts/gpu_policies.py train --data $HOME/pol --runs $HOME/runs --seconds 900
    python3 stages/policy/scripts/gpu_policies.py eval --runs $HOME/runs --worlds 50
    python3 stages/policy/scripts/gpu_policies.py table --runs $HOME/runs --out $OUT

``train``: for every family dataset (``DATA/datasets/<family>``) and policy (ACT, Diffusion Policy),
one ``agentworld train-policy`` run, all at once, spread round robin over the GPUs. A probe of
``--probe-steps`` steps per run (same placement, so the same contention) measures seconds per step;
the real runs then get as many steps as fit in ``--seconds`` (start-up measured by the probe
subtracted). ``eval``: ``agentworld eval`` of every run's checkpoint on its family's task in held-out
kitchens (``--scenes`` x ``--seeds`` episodes, default 5 x 10 = 50), runs spread over the GPUs.
``table``: success per family and policy beside the paper's figures (``table.json``, ``table.md``),
plus each run's curve and train.json, copied to ``--out``.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]
FAMILIES = {"pick_place": "pick_place_bowl", "open_close": "open_drawer", "push_pull": "push_object"}
PAPER_ACT = {"pick_place": 0.66, "open_close": 0.84, "push_pull": 0.72}  # AgentWorld paper, ACT
POLICIES = ("act", "diffusion")


def _gpus(device: str = "cuda") -> list[str]:
    if device == "cpu":
        return ["cpu"]
    out = subprocess.run(["nvidia-smi", "-L"], capture_output=True, text=True).stdout
    n = sum(line.startswith("GPU ") for line in out.splitlines())
    return [f"cuda:{i}" for i in range(max(1, n))]


def _launch(argv: list[str], device: str, log: Path) -> subprocess.Popen:
    env = dict(os.environ)
    if device.startswith("cuda:"):
        env["CUDA_VISIBLE_DEVICES"] = device.split(":")[1]  # the run sees one GPU, as "cuda"
    log.parent.mkdir(parents=True, exist_ok=True)
    return subprocess.Popen([sys.executable, "-m", "pipeline.cli", *argv], cwd=REPO, env=env,
                            stdout=log.open("w"), stderr=subprocess.STDOUT)


def _runs(data: Path | None, runs: Path) -> list[tuple[str, str, Path]]:
    """(family, policy, run folder) of every family dataset present and every policy."""
    fams = [f for f in FAMILIES if data is None or (data / "datasets" / f / "meta" / "info.json").is_file()]
    return [(f, p, runs / f"{f}_{p}") for f in fams for p in POLICIES]


def _train_all(data: Path, runs: Path, steps: dict[str, int], probe: bool, gpus: list[str],
               extra: dict[str, list[str]]) -> dict[str, float]:
    """Start one train-policy per (family, policy) with ``steps[policy]`` steps (``probe``: into
    ``RUNS/.probe_<family>_<policy>``); wait; wall [s] per run folder."""
    procs = {}
    for k, (fam, pol, run) in enumerate(_runs(data, runs)):
        out = runs / f".probe_{fam}_{pol}" if probe else run
        shutil.rmtree(out, ignore_errors=True)
        argv = ["train-policy", str(data / "datasets" / fam), "--policy", pol, "--out", str(out),
                "--steps", str(steps[pol]), "--device", gpus[0].split(":")[0], "--num-workers", "3",
                "--log-freq", str(max(1, min(100, steps[pol] // 10))), *extra[pol]]
        procs[out] = (time.perf_counter(), _launch(argv, gpus[k % len(gpus)], runs / "logs" / f"{out.name}.log"))
    walls = {}
    for out, (t0, p) in procs.items():
        rc = p.wait()
        walls[str(out)] = time.perf_counter() - t0
        print(f"{out.name}: exit {rc} after {walls[str(out)]:.0f} s", flush=True)
    return walls


def _seconds_per_step(run: Path) -> tuple[float, float]:
    """(seconds per step, start-up seconds) from a run's curve.csv (wall_s at the logged steps)."""
    rows = list(csv.DictReader((run / "curve.csv").open()))
    if len(rows) < 2:
        raise RuntimeError(f"{run}: fewer than 2 curve rows: cannot time a step")
    (s0, w0), (s1, w1) = [(int(r["step"]), float(r["wall_s"])) for r in (rows[0], rows[-1])]
    per = (w1 - w0) / max(1, s1 - s0)
    return per, max(0.0, w0 - per * s0)


def train(a) -> int:
    gpus, runs = _gpus(a.device), a.runs
    runs.mkdir(parents=True, exist_ok=True)
    extra = {"act": [f"--lerobot-arg={x}" for x in a.act_arg],
             "diffusion": [f"--lerobot-arg={x}" for x in a.diffusion_arg]}
    t0 = time.perf_counter()
    walls = _train_all(a.data, runs, {p: a.probe_steps for p in POLICIES}, True, gpus, extra)
    plan = {}
    for fam, pol, _ in _runs(a.data, runs):
        probe = runs / f".probe_{fam}_{pol}"
        per, _ = _seconds_per_step(probe)
        startup = walls[str(probe)] - per * a.probe_steps  # process, dataset and model start-up [s]
        plan.setdefault(pol, []).append((per, startup))
    budget = a.seconds - (time.perf_counter() - t0)
    steps = {p: max(a.probe_steps, int((budget - max(s for _, s in v) - 30) / max(x for x, _ in v)))
             for p, v in plan.items()}
    if a.max_steps:
        steps = {p: min(n, a.max_steps) for p, n in steps.items()}
    print(f"probe: {json.dumps({p: [[round(x, 4), round(s, 1)] for x, s in v] for p, v in plan.items()})}; "
          f"steps {steps} in {budget:.0f} s", flush=True)
    (runs / "plan.json").write_text(json.dumps({"seconds_per_step_and_startup": plan, "steps": steps,
                                                "gpus": gpus, "budget_s": budget}, indent=2))
    _train_all(a.data, runs, steps, False, gpus, extra)
    ok = all((run / "train.json").is_file() for _, _, run in _runs(a.data, runs))
    print(f"train: {'ok' if ok else 'FAILED (see runs/logs)'} in {time.perf_counter() - t0:.0f} s", flush=True)
    return 0 if ok else 1


def evaluate(a) -> int:
    gpus, procs = _gpus(a.device), []
    for k, (fam, pol, run) in enumerate(_runs(None, a.runs)):
        if not (run / "train.json").is_file():
            print(f"{run.name}: no trained checkpoint, skipped", flush=True)
            continue
        out = run / "eval"
        shutil.rmtree(out, ignore_errors=True)
        argv = ["eval", str(run), "--tasks", FAMILIES[fam], "--scenes", a.scenes, "--seeds", a.seeds,
                "--worlds", str(a.worlds), "--device", gpus[0].split(":")[0], "--videos", "2", "--out", str(out),
                "--work", str(a.runs / "eval_work" / f"{k}")]
        if a.max_seconds:
            argv += ["--max-seconds", str(a.max_seconds)]
        procs.append((run, _launch(argv, gpus[k % len(gpus)], a.runs / "logs" / f"eval_{run.name}.log")))
    bad = [run.name for run, p in procs if p.wait() != 0]
    print(f"eval: {len(procs) - len(bad)} of {len(procs)} ok{'; failed: ' + ', '.join(bad) if bad else ''}", flush=True)
    return 1 if bad else 0


def table(a) -> int:
    rows = []
    a.out.mkdir(parents=True, exist_ok=True)
    for fam, pol, run in _runs(None, a.runs):
        ev = run / "eval" / "eval.json"
        tr = run / "train.json"
        if not tr.is_file():
            continue  # no dataset for this family, or its training failed (train's log says)
        r = {"family": fam, "task": FAMILIES[fam], "policy": pol, "paper_act": PAPER_ACT[fam]}
        if tr.is_file():
            t = json.loads(tr.read_text())
            r.update(steps=t["steps"], train_wall_s=t["wall_seconds"], last_loss=t["last_loss"])
        if ev.is_file():
            e = json.loads(ev.read_text())["overall"]
            r.update(episodes=e["episodes"], successes=e["successes"],
                     success_rate=round(e["successes"] / max(1, e["episodes"]), 3))
        rows.append(r)
        for name in ("curve.csv", "curve.png", "train.json"):
            if (run / name).is_file():
                shutil.copy(run / name, a.out / f"{run.name}_{name}")
        if ev.is_file():
            shutil.copy(ev, a.out / f"{run.name}_eval.json")
    md = ["| family | task | policy | steps | train wall [s] | held-out successes | rate | paper ACT |",
          "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        md.append(f"| {r['family']} | {r['task']} | {r['policy']} | {r.get('steps', '-')} | "
                  f"{r.get('train_wall_s', '-')} | {r.get('successes', '-')}/{r.get('episodes', '-')} | "
                  f"{r.get('success_rate', '-')} | {r['paper_act']} |")
    (a.out / "table.json").write_text(json.dumps(rows, indent=2) + "\n")
    (a.out / "table.md").write_text("\n".join(md) + "\n")
    print("\n".join(md))
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="gpu_policies.py", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("train")
    t.add_argument("--data", type=Path, required=True, help="the policies_gpu4 job's work dir")
    t.add_argument("--runs", type=Path, required=True)
    t.add_argument("--seconds", type=float, default=900.0, help="wall budget of the phase, probe included [s]")
    t.add_argument("--probe-steps", type=int, default=100)
    t.add_argument("--max-steps", type=int, default=None, help="at most this many steps per run")
    t.add_argument("--act-arg", action="append", default=[], help="a lerobot-train argument for ACT runs")
    t.add_argument("--diffusion-arg", action="append", default=[], help="... for Diffusion Policy runs")
    t.add_argument("--device", choices=("cuda", "cpu"), default="cuda", help="cpu: a dry run of the driver")
    e = sub.add_parser("eval")
    e.add_argument("--runs", type=Path, required=True)
    e.add_argument("--scenes", default="101-105")
    e.add_argument("--seeds", default="1000000-1000009")
    e.add_argument("--worlds", type=int, default=50)
    e.add_argument("--device", choices=("cuda", "cpu"), default="cuda")
    e.add_argument("--max-seconds", type=float, default=None, help="episode time limit [s] (default: the task's)")
    b = sub.add_parser("table")
    b.add_argument("--runs", type=Path, required=True)
    b.add_argument("--out", type=Path, required=True)
    a = p.parse_args(argv)
    return {"train": train, "eval": evaluate, "table": table}[a.cmd](a)


if __name__ == "__main__":
    sys.exit(main())
