"""CPU cost of the scripted experts' planning and IK (issue 12): ``part_planning.plan_stage``,
``part_planning.reach`` and ``Clik.solve`` on real task instances, the current code against the
code before issue 12 (``tests/stages/expert_reference.py``), alternating in one process.

Run: ``.venv/bin/python tests/benchmarks/bench_expert_cpu.py [--catalog DIR] [--repeats 3]`` or
``.venv/bin/python -m pytest -q -m benchmark tests/benchmarks/bench_expert_cpu.py -s``.

A kitchen (``--kitchen`` seed) is built from the default catalog as
``bench_episode_length.py`` does (the catalog is generated and ingested into ``--catalog``
first when it does not hold one, ~20 s, not timed) and simulated by a
:class:`~stages.demos.session.DemoWorld` (CPU, no cameras). For every door task (open and close
of the fridge, microwave, oven and room door) and seed, the world is reset to the instance and the
first stage of the expert's plan is computed as ``articulated._swing`` does: ``plan_stage`` over
the grid with the part's swept area. The ``reach`` calls it makes and the ``Clik.solve`` calls
those make are recorded and replayed. Each call runs ``--repeats`` times alternately with the
reference; the per-call medians (wall time, ms) are printed with the speed-ups and written to
``bench_results/expert_cpu.json``, with whether every result equals the reference's.
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
for p in (REPO, REPO / "tests" / "stages", REPO / "tests" / "benchmarks"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

DOOR_TASKS = ("open_fridge", "open_microwave", "open_oven", "open_door",
              "close_fridge", "close_microwave", "close_oven", "close_door")


def _stage_inputs(inst, d):
    """(part, grid, q0, qs, mode) of the first stage ``articulated._swing`` plans for ``inst``
    (the part at its initial joint value)."""
    import numpy as np

    from stages.demos import articulated as art
    from stages.demos.experts import _grid
    from stages.demos.part_planning import swept_grid

    part = inst.part
    q = float(inst.joints.get(part.joint_path, part.closed))
    vertical = abs(float(np.asarray(part.axis)[2])) > 0.7
    if inst.task.startswith("open"):
        q1, mode = part.closed + 0.9 * part.travel, "grasp"
    elif vertical:
        q1, mode = part.closed, "push"
    else:
        q1, mode = part.closed + art.EDGE_LIFT_TO, "edge"
    step = math.copysign(math.radians(6.0), q1 - q)
    qs = [float(v) for v in np.arange(q + step, q1 + 0.5 * step, step)]
    if mode == "push":
        qs.append(part.closed - art.PUSH_OVERSHOOT)
    grid = _grid(inst)
    return part, swept_grid(grid, part, min(q, q1), max(q, q1)), q, qs, mode


class Recorder:
    """Records the arguments of the ``reach`` and ``Clik.solve`` calls that the reference
    ``plan_stage`` (``tests/stages/expert_reference.py``) makes while it is on, by wrapping the
    reference module's functions (the calls run unchanged)."""

    def __init__(self) -> None:
        import expert_reference as ref

        self.reach_calls: list = []
        self.solve_calls: list = []
        reach, solve = ref.reach, ref.clik_solve
        self._undo = lambda: (setattr(ref, "reach", reach), setattr(ref, "clik_solve", solve))

        def rec_reach(d_, base, targets, **kw):
            self.reach_calls.append((base, [t.copy() for t in targets], kw))
            return reach(d_, base, targets, **kw)

        def rec_solve(ik, target, q0, **kw):
            kw2 = dict(kw)
            if kw2.get("rng") is not None:
                kw2["rng"] = copy.deepcopy(kw2["rng"])
            self.solve_calls.append((target.copy(), q0.copy(), kw2))
            return solve(ik, target, q0, **kw)

        ref.reach, ref.clik_solve = rec_reach, rec_solve

    def close(self) -> None:
        self._undo()


def _same_plan(a, b) -> bool:
    import numpy as np

    return (a[0] == b[0] and a[1] == b[1] and a[2] == b[2] and a[4] == b[4] and len(a[3]) == len(b[3])
            and all(np.array_equal(x, y) for x, y in zip(a[3], b[3], strict=True)))


def _same_ik(a, b) -> bool:
    import numpy as np

    return (np.array_equal(a.q, b.q) and a.position_error == b.position_error
            and a.rotation_error == b.rotation_error and a.iterations == b.iterations
            and a.success == b.success)


def _time(fn, *args, **kw):
    t0 = time.perf_counter()
    out = fn(*args, **kw)
    return time.perf_counter() - t0, out


def _kitchen_world(tmp: Path, catalog: Path | None, kitchen: int):
    import numpy as np

    from bench_episode_length import _catalog
    from stages.demos.kitchen import AssetLibrary, write_kitchen
    from stages.demos.session import DemoSettings, DemoWorld

    cat = _catalog(Path(catalog) if catalog else tmp / "out")
    lib = AssetLibrary.from_folder(cat / "assets", cat / "catalog" / "default" / "generated.json")
    room = write_kitchen(tmp / "kitchen", lib, scene_id="expert_cpu", rng=np.random.default_rng(kitchen))
    world = DemoWorld(room, panda_root=None, work_dir=tmp / "kitchen",
                      settings=DemoSettings(record_images=False))
    return room, world


def run(seeds=(1,), tasks=DOOR_TASKS, catalog: Path | None = None, kitchen: int = 5, repeats: int = 3,
        max_solves: int = 300, max_reaches: int = 120, name: str = "expert_cpu") -> dict:
    """Time plan_stage, reach and Clik.solve (current and reference) on the door tasks' first
    stages; returns (and writes to ``bench_results/<name>.json``) the figures."""
    import numpy as np

    import expert_reference as ref
    from stages.demos import part_planning
    from stages.demos.driver import Driver, ExpertFailure
    from stages.demos.sampling import sample_instance

    rows: dict[str, list] = {"plan_stage": [], "reach": [], "solve": []}
    same = {"plan_stage": True, "reach": True, "solve": True}
    with tempfile.TemporaryDirectory(prefix="bench-expert-cpu-") as tmp:
        room, world = _kitchen_world(Path(tmp), catalog, kitchen)
        reach_calls, solve_calls = [], []
        for task in tasks:
            for seed in seeds:
                inst = sample_instance(task, room, seed)
                world.reset(inst)
                d = Driver(world.sim, world.ctl, world.ik, world.cmd, world.recorder,
                           np.random.default_rng(seed))
                args = _stage_inputs(inst, d)
                rec = Recorder()  # an untimed run of the reference records the calls
                try:
                    ref.plan_stage(d, *args)
                except ExpertFailure:
                    pass
                finally:
                    rec.close()
                reach_calls += [(d, c) for c in rec.reach_calls]
                solve_calls += [(d, c) for c in rec.solve_calls]
                times_new, times_ref = [], []
                for _ in range(repeats):
                    try:
                        t_new, plan = _time(part_planning.plan_stage, d, *args)
                    except ExpertFailure as e:
                        t_new, plan = math.nan, e.reason
                    times_new.append(t_new)
                    try:
                        t_ref, plan_ref = _time(ref.plan_stage, d, *args)
                    except ExpertFailure as e:
                        t_ref, plan_ref = math.nan, e.reason
                    times_ref.append(t_ref)
                failed = isinstance(plan, str) or isinstance(plan_ref, str)
                ok = plan == plan_ref if failed else _same_plan(plan, plan_ref)
                same["plan_stage"] &= bool(ok)
                rows["plan_stage"].append({"task": task, "seed": seed, "mode": args[4], "steps": len(args[3]),
                                           "reached": plan[2] if not isinstance(plan, str) else plan,
                                           "new_ms": 1e3 * statistics.median(times_new),
                                           "ref_ms": 1e3 * statistics.median(times_ref), "same": bool(ok),
                                           "reach_calls": len(rec.reach_calls),
                                           "solve_calls": len(rec.solve_calls)})
                r_ = rows["plan_stage"][-1]
                print(f"plan_stage {task:16s} seed {seed}: {r_['new_ms']:8.1f} ms "
                      f"(reference {r_['ref_ms']:8.1f} ms)"
                      f" reached {r_['reached']} of {len(args[3])}, {r_['reach_calls']} reaches, "
                      f"{r_['solve_calls']} solves, same {ok}", flush=True)
        rng = np.random.default_rng(0)
        def pick(calls, k):
            return [calls[i] for i in sorted(rng.choice(len(calls), min(k, len(calls)), replace=False))]

        for d, (base, targets, kw) in pick(reach_calls, max_reaches):
            tn, tr = [], []
            for _ in range(repeats):
                t, a = _time(part_planning.reach, d, base, targets, **kw)
                tn.append(t)
                t, b = _time(ref.reach, d, base, targets, **kw)
                tr.append(t)
            ok = len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
            same["reach"] &= ok
            rows["reach"].append({"new_ms": 1e3 * statistics.median(tn),
                                  "ref_ms": 1e3 * statistics.median(tr),
                                  "targets": len(targets), "reached": len(a), "same": ok})
        for d, (target, q0, kw) in pick(solve_calls, max_solves):
            tn, tr = [], []
            for _ in range(repeats):
                k1, k2 = dict(kw), dict(kw)
                if kw.get("rng") is not None:
                    k1["rng"], k2["rng"] = copy.deepcopy(kw["rng"]), copy.deepcopy(kw["rng"])
                t, a = _time(d.ik.solve, target, q0, **k1)
                tn.append(t)
                t, b = _time(ref.clik_solve, d.ik, target, q0, **k2)
                tr.append(t)
            ok = _same_ik(a, b)
            same["solve"] &= ok
            rows["solve"].append({"new_ms": 1e3 * statistics.median(tn),
                                  "ref_ms": 1e3 * statistics.median(tr),
                                  "restarts": kw.get("restarts", 0), "iterations": a.iterations,
                                  "success": bool(a.success), "same": ok})
    # the recorded solves in lockstep (Clik.solve_many, 32 lanes), per call, against the reference
    by_kind: dict = {}
    for d, call in solve_calls:
        by_kind.setdefault((id(d), call[2].get("restarts", 0)), (d, []))[1].append(call)
    for (_, restarts), (d, calls) in by_kind.items():
        for s in range(0, len(calls), 64):
            group = calls[s:s + 64]
            rngs = [copy.deepcopy(c[2].get("rng")) for c in group]
            t_new, res = _time(d.ik.solve_many, [c[0] for c in group], [c[1] for c in group],
                               restarts=restarts, rngs=rngs)
            t0 = time.perf_counter()
            refs = [ref.clik_solve(d.ik, c[0], c[1], **{**c[2], "rng": copy.deepcopy(c[2].get("rng"))})
                    for c in group]
            t_ref = time.perf_counter() - t0
            ok = all(_same_ik(a, b) for a, b in zip(res, refs, strict=True))
            same.setdefault("solve_many", True)
            same["solve_many"] &= ok
            rows.setdefault("solve_many", []).append({"new_ms": 1e3 * t_new / len(group),
                                                      "ref_ms": 1e3 * t_ref / len(group),
                                                      "calls": len(group), "restarts": restarts, "same": ok})
    summary = {}
    for key, rs in rows.items():
        rs = [r for r in rs if not math.isnan(r["new_ms"])]
        if not rs:
            continue
        new, old = statistics.median(r["new_ms"] for r in rs), statistics.median(r["ref_ms"] for r in rs)
        tot_new, tot_old = sum(r["new_ms"] for r in rs), sum(r["ref_ms"] for r in rs)
        summary[key] = {"calls": len(rs), "median_new_ms": round(new, 3), "median_ref_ms": round(old, 3),
                        "mean_new_ms": round(tot_new / len(rs), 3),
                        "mean_ref_ms": round(tot_old / len(rs), 3),
                        "median_speedup": round(old / new, 2), "total_speedup": round(tot_old / tot_new, 2),
                        "all_same": same[key]}
    print(f"\n{'function':12s} {'calls':>5s} {'new ms':>9s} {'ref ms':>9s} {'mean new':>9s} {'mean ref':>9s} "
          f"{'median x':>8s} {'total x':>8s} same")
    for k, v in summary.items():
        print(f"{k:12s} {v['calls']:5d} {v['median_new_ms']:9.3f} {v['median_ref_ms']:9.3f} "
              f"{v['mean_new_ms']:9.3f} "
              f"{v['mean_ref_ms']:9.3f} {v['median_speedup']:8.2f} {v['total_speedup']:8.2f} {v['all_same']}")
    out = {"kitchen_seed": kitchen, "seeds": list(seeds), "tasks": list(tasks), "repeats": repeats,
           "cpu_count": os.cpu_count(), "summary": summary, "calls": rows}
    dest = REPO / "bench_results" / f"{name}.json"
    dest.parent.mkdir(exist_ok=True)
    dest.write_text(json.dumps(out, indent=2) + "\n")
    return out


@pytest.mark.benchmark
def test_bench_expert_cpu():
    res = run(seeds=(1,), repeats=1, max_solves=60, max_reaches=20,
              catalog=(Path(os.environ["BENCH_EPLEN_CATALOG"]) if "BENCH_EPLEN_CATALOG" in os.environ
                       else None))
    assert all(v["all_same"] for v in res["summary"].values())


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, nargs="+", default=[1])
    p.add_argument("--tasks", default=",".join(DOOR_TASKS), help="comma-separated door tasks")
    p.add_argument("--catalog", type=Path, default=None,
                   help="work dir with assets/ and catalog/default/generated.json (built there if absent)")
    p.add_argument("--kitchen", type=int, default=5, help="the kitchen's seed")
    p.add_argument("--repeats", type=int, default=3,
                   help="timed runs of each call (alternating with the reference)")
    p.add_argument("--max-solves", type=int, default=300, help="Clik.solve calls timed (a random sample)")
    p.add_argument("--max-reaches", type=int, default=120, help="reach calls timed (a random sample)")
    p.add_argument("--name", default="expert_cpu", help="writes bench_results/<name>.json")
    a = p.parse_args()
    run(tuple(a.seeds), tuple(a.tasks.split(",")), a.catalog, a.kitchen, a.repeats, a.max_solves,
        a.max_reaches, a.name)
