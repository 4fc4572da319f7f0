"""Device-side driver of issue 17's training and evaluation (one GPU or several).

Run from the repository root on the GPU machine after ``. tests/benchmarks/gpu_env.sh``. Everything
in one call, under one wall budget (launch it with ``setsid nohup`` and poll ``WORK/all.log``)::

    W=$HOME/pa; mkdir -p $W
    setsid nohup python3 stages/policy/scripts/gpu_policies.py all --seconds 1500 --work $W > $W.out 2>&1 < /dev/null &
    tail -n 20 $W/all.log; cat $W/all.json             # poll (later calls)
    cp $W/policies_all.tgz $OUT/                       # once all.json has the phase "done"

or phase by phase (a call may run 10 minutes)::

    python3 -m pipeline.cli run jobs/policies_gpu1.toml --no-progress --out $HOME/pol      # datasets
    python3 stages/policy/scripts/gpu_policies.py train --data $HOME/pol --runs $HOME/runs --seconds 900
    python3 stages/policy/scripts/gpu_policies.py eval --runs $HOME/runs
    python3 stages/policy/scripts/gpu_policies.py table --runs $HOME/runs --out $OUT

``train``: for every family dataset (``DATA/datasets/<family>``) and policy (ACT, Diffusion Policy;
``--policy`` picks), one ``agentworld train-policy`` run, all at once, spread round robin over the
GPUs (``--place POLICY=GPU,...`` puts a policy's runs on those: ``act=0,1,2 diffusion=3`` on four),
each with ``--num-workers`` data loader workers (default: the cores left after one per run, shared
by the runs, 1-8) and ``--batch-size`` (``N`` or ``POLICY=N``). A probe of ``--probe-steps`` steps
per run (same placement, so the same contention) measures seconds per step; the real runs then get
as many steps as fit in ``--seconds`` (start-up measured by the probe subtracted). ``--probe-steps 0`` (``all``'s default):
no probe; every run trains until ``--seconds`` - 30 s and saves the step it reached
(``train-policy --max-seconds``; at most ``--max-steps``, default 100,000, whose learning-rate
schedule Diffusion Policy's cosine follows), which saves the probe's start-up (~90 s on the GPU).

``eval``: every (run, held-out kitchen) is its own ``agentworld eval`` process with as many engine
worlds as the kitchen's episodes (``--seeds``), at most ``--jobs`` at once (all on the GPUs, round
robin); a line per finished process; the kitchens' ``eval.json`` are merged into ``RUN/eval/eval.json``
(:mod:`stages.policy.evalmerge`). Episodes end at ``--max-seconds``, by default ``--limit-factor``
(1.5) x the median length of the training dataset's episodes of the task (the scripted expert's),
at most the task's limit. The evaluation kitchens' catalog job is built once; each process gets a
work dir with its runner state copied and the catalog linked.

``table``: success per family and policy beside the paper's figures (``table.json``, ``table.md``),
plus each run's curve and train.json, copied to ``--out``.

``all``: the data job (``--job``, default jobs/policies_gpu1.toml, into ``WORK/data``; or ``--data DIR``, a
data job's folder made elsewhere, e.g. jobs/policies_cpu.toml on the CPU, and no data job; stopped when
less than the eval reserve ``--eval-seconds`` (default 0.3 x ``--seconds``, 240-900 s) +
``--min-train-seconds`` + 60 s would be left), then ``train`` (no probe) with what is left minus
the eval reserve (a policy whose lerobot module does not import is skipped with one line), ``eval``
(processes still running 60 s before the end are stopped; their kitchens are listed as missing),
``table`` into ``WORK/results`` (on cuda, beside the training, a tiny demos job fills Warp's kernel
cache for the eval processes: ``--no-warm-kernels`` skips it), and one ``policies_all.tgz`` in ``--out`` (default WORK: a later
device call copies it to its $OUT) with the table, each run's train.json / curve / eval.json (merged
and per kitchen) / logs, the data job's reports, ``all.log`` and ``all.json`` (each phase's
seconds); rollout videos while it stays under 12 MiB.
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
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))  # stages.* (light modules; heavy ones load in the subprocesses)
from stages.policy.device_jobs import data_job, eval_preflight, pack, policy_importable, warm_job  # noqa: E402
from stages.policy.placement import parse_place, per_policy, run_devices  # noqa: E402

FAMILIES = {"pick_place": "pick_place_bowl", "open_close": "open_drawer", "push_pull": "push_object"}
PAPER_ACT = {"pick_place": 0.66, "open_close": 0.84, "push_pull": 0.72}  # AgentWorld paper, ACT
POLICIES = ("act", "diffusion")


def _gpus(device: str = "cuda") -> list[str]:
    """The GPUs to use: those of ``CUDA_VISIBLE_DEVICES`` when set (two drivers can share a machine),
    else every GPU ``nvidia-smi -L`` lists."""
    if device == "cpu":
        return ["cpu"]
    seen = [x.strip() for x in os.environ.get("CUDA_VISIBLE_DEVICES", "").split(",") if x.strip()]
    if seen:
        return [f"cuda:{x}" for x in seen]
    out = subprocess.run(["nvidia-smi", "-L"], capture_output=True, text=True).stdout
    n = sum(line.startswith("GPU ") for line in out.splitlines())
    return [f"cuda:{i}" for i in range(max(1, n))]


def _launch(argv: list[str], device: str, log: Path, threads: int | None = None) -> subprocess.Popen:
    """``python -m pipeline.cli ARGV`` on ``device`` (``cuda:N``: the only GPU it sees), output to
    ``log``; ``threads``: its OMP / MKL threads (torch's CPU threads)."""
    env = dict(os.environ)
    if threads:
        env.update(OMP_NUM_THREADS=str(threads), MKL_NUM_THREADS=str(threads))
    if device.startswith("cuda:"):
        env["CUDA_VISIBLE_DEVICES"] = device.split(":")[1]  # the run sees one GPU, as "cuda"
    log.parent.mkdir(parents=True, exist_ok=True)
    return subprocess.Popen([sys.executable, "-m", "pipeline.cli", *argv], cwd=REPO, env=env,
                            stdout=log.open("w"), stderr=subprocess.STDOUT)


def _runs(data: Path | None, runs: Path, policies: tuple[str, ...] = POLICIES) -> list[tuple[str, str, Path]]:
    """(family, policy, run folder) of every family dataset present and every policy."""
    fams = [f for f in FAMILIES if data is None or (data / "datasets" / f / "meta" / "info.json").is_file()]
    return [(f, p, runs / f"{f}_{p}") for f in fams for p in policies]


def _num_workers(n_runs: int, asked: int | None) -> int:
    """Data loader workers per training run: ``asked``, or the cores left after one per run's main
    process, shared by the runs, rounded up (1-8: 16 cores, 6 runs -> 2; 3 runs -> 5). Through the
    frame cache a sample costs about 4 ms of a core (lerobot's own decoding about 18 ms); ``data_s``
    in a run's curve.csv says whether the GPU waited for data."""
    if asked is not None:
        return asked
    return max(1, min(8, -(-((os.cpu_count() or 1) - n_runs) // max(1, n_runs))))


def _train_all(data: Path, runs: Path, steps: dict[str, int], probe: bool, gpus: list[str],
               extra: dict[str, list[str]], workers: int | None = None,
               max_seconds: float | None = None, batch_size: int | dict[str, int] | None = None,
               place: dict[str, list[int]] | None = None) -> dict[str, float]:
    """Start one train-policy per (family, policy of ``steps``) with ``steps[policy]`` steps
    (``probe``: into ``RUNS/.probe_<family>_<policy>``; ``max_seconds``: each stops then [s],
    saving the step reached; ``batch_size``: every run's, or per policy with ``*`` for the rest;
    ``place``: the GPUs of a policy's runs, :func:`~stages.policy.placement.run_devices`); wait;
    wall [s] per run folder."""
    procs = {}
    todo = _runs(data, runs, tuple(steps))
    workers = _num_workers(len(todo), workers)
    devices = run_devices([pol for _, pol, _ in todo], gpus, place)
    sizes = batch_size if isinstance(batch_size, dict) else {} if batch_size is None else {"*": batch_size}
    for k, (fam, pol, run) in enumerate(todo):
        out = runs / f".probe_{fam}_{pol}" if probe else run
        shutil.rmtree(out, ignore_errors=True)
        argv = ["train-policy", str(data / "datasets" / fam), "--policy", pol, "--out", str(out),
                "--steps", str(steps[pol]), "--device", gpus[0].split(":")[0], "--num-workers", str(workers),
                "--log-freq", str(max(1, min(100 if max_seconds is None else 50, steps[pol] // 10))), *extra[pol]]
        if max_seconds is not None:
            argv += ["--max-seconds", f"{max_seconds:.0f}"]
        size = sizes.get(pol, sizes.get("*"))
        if size is not None:  # default: train-policy's (the paper's 16)
            argv += ["--batch-size", str(size)]
        argv += ["--frame-cache", str(runs / "frames" / fam)]  # a family's runs decode its videos once
        procs[out] = (time.perf_counter(), _launch(argv, devices[k], runs / "logs" / f"{out.name}.log"))
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
    policies = tuple(getattr(a, "policies", None) or POLICIES)
    workers = getattr(a, "num_workers", None)
    batch = per_policy(getattr(a, "batch_size", None), "--batch-size")
    place = parse_place(getattr(a, "place", None), len(gpus))
    runs.mkdir(parents=True, exist_ok=True)
    extra = {"act": [f"--lerobot-arg={x}" for x in a.act_arg],
             "diffusion": [f"--lerobot-arg={x}" for x in a.diffusion_arg]}
    for args in extra.values() if getattr(a, "cameras", None) is not None else ():
        args += ["--cameras", a.cameras]  # train-policy's: the cameras the policies take ("none": state only)
    t0 = time.perf_counter()
    if a.probe_steps == 0:  # no probe: every run trains until the budget's end, then saves
        cap, wall = a.max_steps or 100_000, max(10.0, a.seconds - 30.0)  # 30 s: the checkpoint, exit
        print(f"train: no probe; every run stops after {wall:.0f} s (at most {cap} steps)", flush=True)
        (runs / "plan.json").write_text(json.dumps({"mode": "deadline", "max_seconds": wall, "steps_cap": cap,
                                                    "gpus": gpus, "num_workers": _num_workers(
                                                        len(_runs(a.data, runs, policies)), workers)}, indent=2))
        _train_all(a.data, runs, {p: cap for p in policies}, False, gpus, extra, workers, max_seconds=wall,
                   batch_size=batch, place=place)
        ok = all((run / "train.json").is_file() for _, _, run in _runs(a.data, runs, policies))
        print(f"train: {'ok' if ok else 'FAILED (see runs/logs)'} in {time.perf_counter() - t0:.0f} s", flush=True)
        return 0 if ok else 1
    walls = _train_all(a.data, runs, {p: a.probe_steps for p in policies}, True, gpus, extra, workers,
                       batch_size=batch, place=place)
    plan: dict[str, list] = {}
    for fam, pol, _ in _runs(a.data, runs, policies):
        probe = runs / f".probe_{fam}_{pol}"
        try:
            per, _ = _seconds_per_step(probe)
        except (OSError, RuntimeError) as e:
            print(f"{probe.name}: the probe failed ({e}); see {runs / 'logs' / (probe.name + '.log')}", flush=True)
            continue
        startup = walls[str(probe)] - per * a.probe_steps  # process, dataset and model start-up [s]
        plan.setdefault(pol, []).append((per, startup))
    if not plan:
        print("train: every probe failed", flush=True)
        return 1
    budget = a.seconds - (time.perf_counter() - t0)
    steps = {p: max(a.probe_steps, int((budget - max(s for _, s in v) - 30) / max(x for x, _ in v)))
             for p, v in plan.items()}
    if a.max_steps:
        steps = {p: min(n, a.max_steps) for p, n in steps.items()}
    print(f"probe: {json.dumps({p: [[round(x, 4), round(s, 1)] for x, s in v] for p, v in plan.items()})}; "
          f"steps {steps} in {budget:.0f} s", flush=True)
    (runs / "plan.json").write_text(json.dumps({"seconds_per_step_and_startup": plan, "steps": steps,
                                                "gpus": gpus, "budget_s": budget,
                                                "num_workers": _num_workers(len(_runs(a.data, runs, tuple(steps))),
                                                                            workers)}, indent=2))
    _train_all(a.data, runs, steps, False, gpus, extra, workers, batch_size=batch, place=place)
    ok = all((run / "train.json").is_file() for _, _, run in _runs(a.data, runs, tuple(steps)))
    print(f"train: {'ok' if ok else 'FAILED (see runs/logs)'} in {time.perf_counter() - t0:.0f} s", flush=True)
    return 0 if ok else 1


def _default_max_seconds(run: Path, task: str, factor: float) -> tuple[float | None, str]:
    """The episode time limit [s] of ``run``'s evaluation: ``factor`` x the median length of the
    scripted expert's episodes of ``task`` in the run's training dataset (train.json), at most the
    task's own limit; (None, why) when the dataset is not found (the task's limit then applies)."""
    from stages.demos.tasks import task as task_spec
    from stages.policy.evalmerge import typical_seconds

    limit = float(task_spec(task).max_seconds)
    try:
        ds = Path(json.loads((run / "train.json").read_text())["config"]["dataset"])
    except (OSError, KeyError, json.JSONDecodeError):
        return None, f"the task's limit {limit:.0f} s (no training dataset in train.json)"
    typ = typical_seconds(ds, task)
    if typ is None:
        return None, f"the task's limit {limit:.0f} s (no {task} episode in {ds})"
    med, n = typ
    s = round(min(limit, factor * med), 1)
    return s, (f"{factor} x the expert's median episode {med:.1f} s ({n} training episodes)"
               + (f", capped at the task's limit {limit:.0f} s" if s >= limit else ""))


def _shared_catalog(work: Path, scene: int, log: Path) -> Path:
    """Build the evaluation kitchens' catalog job once (``build_kitchen`` of ``scene`` in
    ``work/kitchens``); returns its folder (``catalog_job``)."""
    code = ("import sys; from pathlib import Path; from stages.policy.evaluate import build_kitchen; "
            "build_kitchen(Path(sys.argv[1]), int(sys.argv[2]))")
    log.parent.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]))
    with log.open("w") as f:
        rc = subprocess.run([sys.executable, "-c", code, str(work / "kitchens"), str(scene)], cwd=REPO, env=env,
                            stdout=f, stderr=subprocess.STDOUT).returncode
    if rc != 0:
        raise RuntimeError(f"eval: building the evaluation kitchens' catalog failed (exit {rc}); see {log}")
    return work / "kitchens" / "catalog_job"


def _process_work(shared: Path, dst: Path) -> Path:
    """A work dir of its own for one eval process: the shared catalog job's runner state copied,
    its ``catalog`` and ``assets`` folders linked (every item cached: concurrent processes write
    nothing shared; the kitchen is written in ``dst``)."""
    job = dst / "kitchens" / "catalog_job"
    if job.is_dir():
        return dst
    job.mkdir(parents=True)
    for p in shared.iterdir():
        if p.name in ("catalog", "assets"):
            (job / p.name).symlink_to(p.resolve(), target_is_directory=True)
        elif p.is_dir():
            shutil.copytree(p, job / p.name, symlinks=True)
        else:
            shutil.copy2(p, job / p.name)
    return dst


def _result_of(out: Path) -> str:
    try:
        o = json.loads((out / "eval.json").read_text())["overall"]
    except (OSError, KeyError, json.JSONDecodeError):
        return "no eval.json"
    return f"{o['successes']}/{o['episodes']} successes"


def _run_all(jobs: list[dict], cap: int, deadline: float | None) -> list[dict]:
    """Run ``jobs`` (dicts with argv, device, log, name, out) ``cap`` at a time; a progress line per
    finished process; processes still running at ``deadline`` (perf_counter) are stopped (rc None)."""
    pending, running, done = list(jobs), [], []
    threads = max(1, (os.cpu_count() or 1) // max(1, min(cap, len(jobs))))
    while pending or running:
        while pending and len(running) < cap:
            j = pending.pop(0)
            j["t0"] = time.perf_counter()
            j["proc"] = _launch(j["argv"], j["device"], j["log"], threads=threads)
            running.append(j)
        time.sleep(1.0)
        late = deadline is not None and time.perf_counter() > deadline
        for j in list(running):
            rc = j["proc"].poll()
            if rc is None and late:
                j["proc"].terminate()
                try:
                    j["proc"].wait(timeout=20)
                except subprocess.TimeoutExpired:
                    j["proc"].kill()
                    j["proc"].wait()
                rc = "stopped at the deadline"
            if rc is None:
                continue
            running.remove(j)
            j["rc"], j["wall"] = rc, time.perf_counter() - j["t0"]
            done.append(j)
            print(f"eval [{len(done)}/{len(jobs)}] {j['name']}: {_result_of(j['out'])}, exit {rc}, "
                  f"{j['wall']:.0f} s ({len(running)} running, {len(pending)} waiting)"
                  f"{'' if rc == 0 else '; log ' + str(j['log'])}", flush=True)
        if late:
            for j in pending:
                j["rc"], j["wall"] = "not started before the deadline", 0.0
                done.append(j)
            pending = []
    return done


def evaluate(a) -> int:
    """Every (run, held-out kitchen) as its own ``agentworld eval`` process (see the module docstring);
    the kitchens' reports merged into ``RUN/eval/eval.json``."""
    from stages.policy.cli import _ints
    from stages.policy.evalmerge import merge_files

    gpus, scenes, seeds = _gpus(a.device), _ints(a.scenes), _ints(a.seeds)
    deadline = getattr(a, "deadline", None)
    runs = [(f, p, r) for f, p, r in _runs(None, a.runs) if (r / "train.json").is_file()]
    for _, _, run in _runs(None, a.runs):
        if (run / "lerobot").is_dir() and not (run / "train.json").is_file():
            print(f"{run.name}: no trained checkpoint, skipped", flush=True)
    if not runs:
        print("eval: no trained run", flush=True)
        return 1
    t0 = time.perf_counter()
    shared = _shared_catalog(a.runs / "eval_work" / "shared", scenes[0], a.runs / "logs" / "eval_catalog.log")
    print(f"eval: catalog of the evaluation kitchens built in {time.perf_counter() - t0:.0f} s", flush=True)
    jobs = []
    for fam, pol, run in runs:
        out = run / "eval"
        shutil.rmtree(out, ignore_errors=True)
        limit, why = (a.max_seconds, "given") if a.max_seconds else _default_max_seconds(run, FAMILIES[fam],
                                                                                        a.limit_factor)
        print(f"{run.name}: {len(scenes)} kitchens x {len(seeds)} episodes, episodes end at "
              f"{'the task limit' if limit is None else f'{limit} s'} ({why})", flush=True)
        for ws in scenes:
            argv = ["eval", str(run), "--tasks", FAMILIES[fam], "--scenes", str(ws), "--seeds", a.seeds,
                    "--worlds", str(len(seeds)), "--device", gpus[0].split(":")[0], "--videos", str(a.videos),
                    "--out", str(out / f"ws{ws}"),
                    "--work", str(_process_work(shared, a.runs / "eval_work" / f"{run.name}_ws{ws}"))]
            if limit is not None:
                argv += ["--max-seconds", str(limit)]
            jobs.append({"argv": argv, "device": gpus[len(jobs) % len(gpus)], "out": out / f"ws{ws}",
                         "log": a.runs / "logs" / f"eval_{run.name}_ws{ws}.log", "name": f"{run.name} kitchen_ws{ws}",
                         "run": run})
    print(f"eval: {len(jobs)} processes, at most {a.jobs} at once, on {', '.join(gpus)}", flush=True)
    done = _run_all(jobs, a.jobs, deadline)
    bad = []
    for _, _, run in runs:
        mine = [j for j in done if j["run"] == run]
        parts = [j["out"] / "eval.json" for j in mine if (j["out"] / "eval.json").is_file()]
        missing = [j["name"] for j in mine if not (j["out"] / "eval.json").is_file()]
        bad += missing
        if not parts:
            continue
        report = merge_files(parts, run / "eval" / "eval.json")
        if missing:
            report["missing"] = missing
            (run / "eval" / "eval.json").write_text(json.dumps(report, indent=2) + "\n")
        o = report["overall"]
        print(f"{run.name}: {o['successes']}/{o['episodes']} successes; failures {json.dumps(o['failures'])}"
              f"{'; missing ' + ', '.join(missing) if missing else ''}", flush=True)
    print(f"eval: {len(jobs) - len(bad)} of {len(jobs)} kitchens evaluated in {time.perf_counter() - t0:.0f} s"
          f"{'; not: ' + ', '.join(bad) if bad else ''}", flush=True)
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


class _Tee:
    """stdout to the console and a log file (``all``)."""

    def __init__(self, path: Path, stream) -> None:
        self.f, self.stream = path.open("a", buffering=1), stream

    def write(self, text: str) -> int:
        self.f.write(text)
        try:
            self.stream.write(text)
        except (OSError, ValueError):
            pass  # a closed console (nohup): the log file has it
        return len(text)

    def flush(self) -> None:
        self.f.flush()
        try:
            self.stream.flush()
        except (OSError, ValueError):
            pass


def run_all(a) -> int:
    """data job -> train -> eval -> table under one wall budget (see the module docstring)."""
    t_start = time.perf_counter()
    work = a.work.resolve()
    work.mkdir(parents=True, exist_ok=True)
    sys.stdout = _Tee(work / "all.log", sys.stdout)
    runs, results = work / "runs", work / "results"
    phases: dict[str, dict] = {}

    def left() -> float:
        return a.seconds - (time.perf_counter() - t_start)

    def status(phase: str, **kw) -> None:
        phases[phase] = {**phases.get(phase, {}), **kw, "at_s": round(time.perf_counter() - t_start, 1)}
        (work / "all.json").write_text(json.dumps({"budget_s": a.seconds, "phases": phases}, indent=2) + "\n")
        print(f"all [{time.perf_counter() - t_start:.0f} s, {left():.0f} s left] {phase}: "
              f"{' '.join(f'{k}={v}' for k, v in kw.items())}", flush=True)

    eval_s = a.eval_seconds if a.eval_seconds is not None else min(900.0, max(240.0, 0.3 * a.seconds))
    tail_s = 60.0  # table and the archive
    data = a.data.resolve() if a.data is not None else work / "data"
    status("start", job=str(a.job) if a.data is None else None, data=str(data), work=str(work), eval_reserve_s=eval_s)
    lack = eval_preflight()  # before any training: what the eval processes would stop on
    if lack:
        status("done", exit=2, preflight=" | ".join(lack))  # "done": a device poll waiting on all.json stops
        return 2
    t = time.perf_counter()
    if a.data is None:
        data_s = left() - eval_s - tail_s - a.min_train_seconds
        rc = data_job(a.job, data, data_s, work / "logs" / "data.log")
    else:  # datasets made elsewhere (jobs/policies_cpu.toml): no data job
        data_s, rc = 0.0, 0
    have = [f for f in FAMILIES if (data / "datasets" / f / "meta" / "info.json").is_file()]
    status("data", exit=rc, seconds=round(time.perf_counter() - t), limit_s=round(data_s), datasets=",".join(have) or "none")
    code = 1
    if have:
        policies = []
        for pol in a.policy:
            err = policy_importable(pol)
            if err:
                print(f"{pol}: skipped: its lerobot policy does not import ({err})", flush=True)
            else:
                policies.append(pol)
        t = time.perf_counter()
        warm = None
        if policies and a.device == "cuda" and a.warm_kernels:  # compile the engine's kernels beside the training
            job = warm_job(work, "cuda")
            log = (work / "logs" / "warm.log")
            log.parent.mkdir(parents=True, exist_ok=True)
            warm = (time.perf_counter(), subprocess.Popen(
                [sys.executable, "-m", "pipeline.cli", "run", str(job), "--no-progress", "--strict", "--out",
                 str(work / "warm" / "out")],
                cwd=REPO, stdout=log.open("w"), stderr=subprocess.STDOUT, start_new_session=True))
        if policies:
            train_s = left() - eval_s - tail_s
            targs = argparse.Namespace(data=data, runs=runs, seconds=train_s, probe_steps=a.probe_steps,
                                       max_steps=a.max_steps, act_arg=a.act_arg, diffusion_arg=a.diffusion_arg,
                                       device=a.device, policies=tuple(policies), num_workers=a.num_workers,
                                       batch_size=a.batch_size, place=a.place, cameras=a.cameras)
            rc = train(targs)
            status("train", exit=rc, seconds=round(time.perf_counter() - t), budget_s=round(train_s),
                   policies=",".join(policies))
            if warm is not None:  # the eval waits for the kernels (at most a third of its reserve)
                t_w, p = warm
                try:
                    rc_w = p.wait(timeout=max(1.0, min(eval_s / 3, left() - tail_s)))
                except subprocess.TimeoutExpired:
                    os.killpg(p.pid, 9)
                    rc_w = p.wait()
                status("warm", exit=rc_w, seconds=round(time.perf_counter() - t_w))
            t = time.perf_counter()
            eargs = argparse.Namespace(runs=runs, scenes=a.scenes, seeds=a.seeds, device=a.device,
                                       max_seconds=a.max_seconds, limit_factor=a.limit_factor, jobs=a.jobs,
                                       videos=a.videos, deadline=t_start + a.seconds - tail_s)
            rc = evaluate(eargs) if any((r / "train.json").is_file() for *_, r in _runs(None, runs)) else 1
            status("eval", exit=rc, seconds=round(time.perf_counter() - t), reserve_s=round(eval_s))
            code = rc
    table(argparse.Namespace(runs=runs, out=results))
    tgz = pack(work, runs, results, a.out / "policies_all.tgz", data=data)
    status("done", exit=code, archive=str(tgz), mib=round(tgz.stat().st_size / 2**20, 2))
    pack(work, runs, results, a.out / "policies_all.tgz", data=data)  # again, with the final all.json / all.log
    return code


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="gpu_policies.py", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    t = sub.add_parser("train")
    t.add_argument("--data", type=Path, required=True, help="the policies_gpu4 job's work dir")
    t.add_argument("--runs", type=Path, required=True)
    t.add_argument("--seconds", type=float, default=900.0, help="wall budget of the phase, probe included [s]")
    t.add_argument("--probe-steps", type=int, default=100,
                   help="steps of the probe that times a step (0: no probe; every run stops at --seconds)")
    t.add_argument("--max-steps", type=int, default=None, help="at most this many steps per run")
    t.add_argument("--act-arg", action="append", default=[], help="a lerobot-train argument for ACT runs")
    t.add_argument("--diffusion-arg", action="append", default=[], help="... for Diffusion Policy runs")
    t.add_argument("--device", choices=("cuda", "cpu"), default="cuda", help="cpu: a dry run of the driver")
    e = sub.add_parser("eval")
    e.add_argument("--runs", type=Path, required=True)
    e.add_argument("--scenes", default="101-105")
    e.add_argument("--seeds", default="1000000-1000009")
    e.add_argument("--worlds", type=int, default=None,
                   help="ignored (each process runs its kitchen's episodes in as many worlds)")
    e.add_argument("--device", choices=("cuda", "cpu"), default="cuda")
    e.add_argument("--max-seconds", type=float, default=None,
                   help="episode time limit [s] (default: --limit-factor x the expert's median episode)")
    e.add_argument("--limit-factor", type=float, default=1.5,
                   help="default time limit: this x the median length of the training dataset's episodes")
    e.add_argument("--jobs", type=int, default=16, help="eval processes at once (one per run and kitchen)")
    e.add_argument("--videos", type=int, default=1, help="rollout videos per process (kitchen)")
    b = sub.add_parser("table")
    b.add_argument("--runs", type=Path, required=True)
    b.add_argument("--out", type=Path, required=True)
    t.add_argument("--policy", dest="policies", action="append", choices=POLICIES, default=None,
                   help="train only this policy (repeatable; default both)")
    t.add_argument("--batch-size", action="append", default=None,
                   help="samples per step, N or POLICY=N (repeatable; default train-policy's: 16)")
    t.add_argument("--place", action="append", default=None,
                   help="POLICY=GPU[,GPU...]: the GPUs that policy's runs share (default: round robin over all)")
    t.add_argument("--cameras", default=None, help="the cameras the policies take, comma-separated or none")
    t.add_argument("--num-workers", type=int, default=None,
                   help="data loader workers per run (default: the cores left after one per run, shared)")
    al = sub.add_parser("all", help="data job, training, eval and table under one wall budget; one tgz in --out")
    al.add_argument("--seconds", type=float, required=True, help="wall budget of everything [s]")
    al.add_argument("--work", type=Path, required=True, help="work folder (data/, runs/, results/, all.log)")
    al.add_argument("--out", type=Path, default=None, help="where policies_all.tgz goes (default WORK)")
    al.add_argument("--job", type=Path, default=REPO / "jobs" / "policies_gpu1.toml", help="the data job")
    al.add_argument("--data", type=Path, default=None,
                    help="a data job's work dir made elsewhere (DATA/datasets/<family>): no data job here")
    al.add_argument("--policy", action="append", choices=POLICIES, default=None, help="default both")
    al.add_argument("--eval-seconds", type=float, default=None,
                    help="reserve of the eval phase [s] (default 0.3 x --seconds, 240-900 s)")
    al.add_argument("--no-warm-kernels", dest="warm_kernels", action="store_false",
                    help="no kernel warm-up job beside the training (cuda; see device_jobs.warm_job)")
    al.add_argument("--min-train-seconds", type=float, default=300.0,
                    help="the data job stops when less than this would be left to training [s]")
    for name, kw in (("--probe-steps", {"type": int, "default": 0}), ("--max-steps", {"type": int, "default": None}),
                     ("--num-workers", {"type": int, "default": None}),
                     ("--batch-size", {"action": "append", "default": None}),
                     ("--place", {"action": "append", "default": None}),
                     ("--act-arg", {"action": "append", "default": []}),
                     ("--diffusion-arg", {"action": "append", "default": []}),
                     ("--scenes", {"default": "101-105"}), ("--seeds", {"default": "1000000-1000009"}),
                     ("--max-seconds", {"type": float, "default": None}),
                     ("--limit-factor", {"type": float, "default": 1.5}), ("--jobs", {"type": int, "default": 16}),
                     ("--videos", {"type": int, "default": 1}), ("--cameras", {"default": None}),
                     ("--device", {"choices": ("cuda", "cpu"), "default": "cuda"})):
        al.add_argument(name, **kw)
    a = p.parse_args(argv)
    if a.cmd in ("train", "all"):
        try:  # bad values fail here, in one line, before any work
            named = {*per_policy(a.batch_size, "--batch-size"), *parse_place(a.place, len(_gpus(a.device)))}
            if named - {"*", *POLICIES}:
                raise ValueError(f"--batch-size / --place: unknown policies {sorted(named - {'*', *POLICIES})}")
        except ValueError as e:
            p.error(str(e))
    if a.cmd == "all":
        a.policy = tuple(a.policy or POLICIES)
        a.out = a.out or a.work
    return {"train": train, "eval": evaluate, "table": table, "all": run_all}[a.cmd](a)


if __name__ == "__main__":
    sys.exit(main())
