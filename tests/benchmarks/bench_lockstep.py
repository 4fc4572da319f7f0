"""Benchmark: the engine's cost of resuming a world program (:class:`stages.engine.Lockstep`).

``--worlds`` programs each ask for one physics step at a time; per round the engine resumes every
one of them (``resume_ready``) and counts the step off (``advance``), as the engine does between
physics steps. Prints the median wall time per resume [us] over ``--reps`` timed blocks. With
``--reference FILE`` (another version's ``stages/engine/lockstep.py``, e.g. the main checkout's)
both are timed in the same process, blocks alternating. Writes ``bench_results/lockstep.json``::

    python tests/benchmarks/bench_lockstep.py --reference ../main/stages/engine/lockstep.py
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import statistics
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))


def _module(path: Path):
    spec = importlib.util.spec_from_file_location(f"lockstep_{abs(hash(str(path)))}", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod  # dataclasses look their module up there
    spec.loader.exec_module(mod)
    return mod


def time_resumes(lockstep_cls, worlds: int, rounds: int) -> float:
    """Seconds per program resume: ``rounds`` rounds of ``worlds`` resumes."""
    ls = lockstep_cls(worlds)

    def program(w):
        def fn():
            while True:
                ls.wait_steps(w, 1)
        return fn

    for w in range(worlds):
        ls.start(w, program(w))
    ls.resume_ready()  # every program runs to its first request
    t = time.perf_counter()
    for _ in range(rounds):
        ls.advance(1)
        ls.resume_ready()
    dt = (time.perf_counter() - t) / (rounds * worlds)
    ls.shutdown()
    return dt


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--worlds", type=int, default=16)
    p.add_argument("--rounds", type=int, default=200)
    p.add_argument("--reps", type=int, default=7)
    p.add_argument("--reference", type=Path, default=None, help="another lockstep.py, timed alongside")
    p.add_argument("--out", type=Path, default=REPO / "bench_results" / "lockstep.json")
    args = p.parse_args(argv)
    from stages.engine.lockstep import Lockstep

    impls = {"this": Lockstep}
    if args.reference is not None:
        impls["reference"] = _module(args.reference.resolve()).Lockstep
    times: dict[str, list[float]] = {k: [] for k in impls}
    for _ in range(args.reps):
        for name, cls in impls.items():
            times[name].append(time_resumes(cls, args.worlds, args.rounds))
    res = {"worlds": args.worlds, "rounds": args.rounds, "reps": args.reps,
           "us_per_resume_median": {k: round(1e6 * statistics.median(v), 2) for k, v in times.items()},
           "us_per_resume_all": {k: [round(1e6 * x, 2) for x in v] for k, v in times.items()}}
    if args.reference is not None:
        m = res["us_per_resume_median"]
        res["reference_over_this"] = round(m["reference"] / m["this"], 2)
    print(json.dumps(res), flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(res, indent=1))
    return res


@pytest.mark.benchmark
def test_bench_lockstep(tmp_path):
    res = main(["--worlds", "4", "--rounds", "20", "--reps", "1", "--out", str(tmp_path / "l.json")])
    assert res["us_per_resume_median"]["this"] > 0


if __name__ == "__main__":
    main()
