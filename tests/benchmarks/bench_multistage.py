"""Benchmark: successful episodes per hour of the multistage house tasks on the batched engine (issue 16).

For each task of ``--tasks`` (default: the six recorded house tasks, :data:`TASKS`): the task world of
the first generated flat (``--houses`` 3-room flats of job seed 0, built as
``tests/benchmarks/bench_house_tasks.py`` builds them: its room populated with the household-task
rules) whose room converts and samples the task (:data:`ROOM_OF`: store_food and heat_food in the
kitchen, organize_books and clean_table_living in the living room, make_bed in the bedroom,
set_alarm_clock at the bedroom's nightstand); a :class:`~stages.engine.BatchEngine` of ``--worlds``
copies of it runs the task's scripted multistage expert in every world, episode after episode (world
``w``'s ``k``-th episode: seed ``1000 w + k + 1``), for ``--sim-seconds`` of simulated time after a
warm-up (kernels compiled, CUDA graphs captured), with the engine's 3 cameras (RGB + depth,
``--width`` x ``--height``; ``--no-images``: state and action only). Frames go to sinks that count them
(nothing is encoded: ``bench_house_tasks.py --record`` writes datasets). Episodes still running when
the window closes are not counted (a window of several episode lengths keeps that small).
The tasks' engines run one after another, or with ``--parallel`` each in a process of its own,
their windows started together (one GPU and the host's cores shared, as a job's engines would).

Prints one JSON line per task and writes ``--out`` (default
``tests/benchmarks/results/multistage_<device>_w<worlds>[_par].json``): per task the flat, episodes
completed and successful, **successful episodes per hour** (successes / wall of the window; the
episodes the window cuts are lost), ``..._steady`` (the success rate x worlds x simulated seconds
per wall second / the mean completed episode: no cut episodes, but biased high as completed
episodes are the shorter ones), median episode frames, failure reasons
(``s<stage>_<skill>.<reason>``), recorded timesteps/s, the engine's wall split (simulation,
rendering, control, encoding) and build time; overall: all successes over the summed walls of the
tasks' windows (``--parallel``: over the longest window).

CPU (``layout`` auto = one MuJoCo C model per world)::

    PYTHONPATH=. .venv/bin/python tests/benchmarks/bench_multistage.py --worlds 2 --sim-seconds 60

GPU (``layout`` auto = one MuJoCo-Warp model of all worlds, CUDA graphs)::

    python tests/benchmarks/bench_multistage.py --device cuda --parallel --worlds 16 --sim-seconds 90

``--work DIR`` keeps the flats and task worlds (a second run reuses them); ``--program-procs`` /
``--program-wait`` as in ``bench_engine.py`` (worker processes for the experts; batched layout).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
for _p in (REPO, HERE):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

#: the recorded multistage house tasks (the default)
TASKS = ("store_food", "heat_food", "organize_books", "clean_table_living", "make_bed", "set_alarm_clock")
#: the house room each multistage house task runs in
ROOM_OF = {"store_food": "kitchen", "heat_food": "kitchen", "organize_books": "living_room",
           "clean_table_living": "living_room", "serve_drinks": "living_room", "make_bed": "bedroom",
           "organize_wardrobe": "bedroom", "set_alarm_clock": "bedroom"}


def flats(room: str, work: Path, houses: int) -> tuple[list[Path], Path]:
    """The populated flats' scene folders of ``room`` (``houses`` flats, the job in ``work/<room>/out``)
    and the catalog's generated.json."""
    from bench_house_tasks import build_houses

    out = work / room / "out"
    return build_houses(out, houses, room)[:houses], out / "catalog" / "default" / "generated.json"


def task_world(task: str, scenes: list[Path], generated: Path, work: Path):
    """The task world of ``task`` (written under ``work/<room>/task_<task>``) in the first of
    ``scenes`` whose room converts and samples the task (seed 1): (world, flat name, the flats
    before it and their reasons)."""
    from stages.demos.house import house_kitchen
    from stages.demos.house_bedroom import house_bedroom
    from stages.demos.house_bedside import house_bedside
    from stages.demos.house_living import house_living
    from stages.demos.multistage import needs_clock, needs_drink, sample_task

    room = ROOM_OF[task]
    if room == "kitchen":
        make = house_kitchen
    elif room == "living_room":
        drink = needs_drink([task])

        def make(*a, **k):
            return house_living(*a, **k, drink=drink)
    else:
        make = house_bedside if needs_clock([task]) else house_bedroom
    why = []
    for scene in scenes:
        try:
            w = make(scene, work / room / f"task_{task}" / scene.name, generated, scene_id=scene.name)
            sample_task(task, w, 1)
        except Exception as e:  # noqa: BLE001 - the next flat is tried; every reason is reported
            why.append(f"{scene.name}: {e}")
            continue
        return w, scene.name, why
    raise SystemExit(f"bench_multistage: {task}: none of {len(scenes)} flats becomes a task world: {why}")


class Endless:
    """An instance source (picklable): world ``w``'s ``k``-th episode is ``task`` with seed
    ``1000 w + k + 1`` in ``world``; a seed the task cannot sample is skipped (the next is tried,
    up to 20)."""

    def __init__(self, world, task: str) -> None:
        self.world, self.task = world, task
        self.count: dict[int, int] = {}

    def __call__(self, w: int):
        from stages.demos.multistage import sample_task

        for _ in range(20):
            k = self.count.get(w, 0)
            self.count[w] = k + 1
            try:
                return sample_task(self.task, self.world, 1000 * w + k + 1)
            except Exception:  # noqa: BLE001, S112 - an unsampleable seed: the next one
                continue
        raise RuntimeError(f"bench_multistage: {self.task}: 20 seeds in a row cannot be sampled in world {w}")


def bench_task(task: str, world, flat: str, work: Path, args, barrier=None) -> dict:
    """One engine of ``args.worlds`` copies of ``world`` running ``task`` for ``args.sim_seconds``
    (with ``barrier``, a process pool's: the timed window starts with the other processes')."""
    from stages.engine import BatchEngine, EngineConfig, device_scope

    cfg = EngineConfig(worlds=args.worlds, device=args.device, width=args.width, height=args.height,
                       record_images=not args.no_images, layout=args.layout, subtasks=True,
                       program_procs=args.program_procs, program_wait=args.program_wait)
    with device_scope(args.device):
        t0 = time.perf_counter()
        eng = BatchEngine(world, panda_root=None, work_dir=work / "engine" / task, config=cfg)
        build = time.perf_counter() - t0
        source = Endless(world, task)
        frames = {"n": 0}

        def begin(_w, _inst):
            def sink(_frame):
                frames["n"] += 1
            return sink

        done: list[tuple[bool, int, str]] = []

        def end(_w, _inst, res):
            done.append((res.success, res.frames, res.reason))

        eng.run(source, begin=begin, end=end, max_steps=2 * eng.sync_period)  # warm-up, abandoned
        _sync(args.device)
        done.clear()
        frames["n"] = 0
        s0 = eng.stats.to_json()["timings"]
        start0 = eng.stats.startup_seconds
        if barrier is not None:
            barrier.wait()
        t0 = time.perf_counter()
        eng.run(source, begin=begin, end=end, max_steps=int(args.sim_seconds * eng.steps_per_second))
        _sync(args.device)
        wall = time.perf_counter() - t0 - (eng.stats.startup_seconds - start0)
    s1 = eng.stats.to_json()["timings"]
    ok = [fr for s, fr, _ in done if s]
    res = {"task": task, "flat": flat, "worlds": args.worlds, "build_seconds": round(build, 1),
           "sim_seconds": args.sim_seconds, "wall_seconds": round(wall, 1),
           "episodes_completed": len(done), "successes": len(ok),
           "successful_episodes_per_hour": round(len(ok) / wall * 3600, 1),
           "successful_episodes_per_hour_steady": _steady(done, args, wall, cfg.fps),
           "median_episode_frames": int(statistics.median(ok)) if ok else None,
           "episode_frames": sorted(ok),
           "failures": dict(sorted(Counter(r for s, _, r in done if not s).items())),
           "recorded_timesteps_per_second": round(frames["n"] / wall, 1),
           "split_seconds": {k: round(s1[k] - s0[k], 2) for k in ("simulation", "rendering", "control", "encoding")},
           "holds": eng.stats.holds}
    print(json.dumps(res), flush=True)
    return res


def _steady(done: list[tuple[bool, int, str]], args, wall: float, fps: int) -> float | None:
    """Successful episodes/h were every world always busy with episodes like those completed: the
    success rate x worlds x simulated seconds per wall second / the mean completed episode [s] (no
    loss to the episodes the window cuts; completed episodes are the shorter ones, so it runs high)."""
    if not done:
        return None
    mean_s = statistics.mean(fr for _, fr, _ in done) / fps
    rate = sum(s for s, _, _ in done) / len(done)
    return round(rate * args.worlds * (args.sim_seconds / wall) * 3600 / mean_s, 1)


def _sync(device: str) -> None:
    if device.startswith("cuda"):
        import warp as wp

        wp.synchronize_device(device)


def _child(task: str, scenes: list[Path], generated: Path, work: Path, args, barrier, queue) -> None:
    """One process of ``--parallel``: ``task``'s world and engine, timed with the others."""
    import usd_schemas  # noqa: F401

    try:
        world, flat, why = task_world(task, scenes, generated, work)
        queue.put((task, why, bench_task(task, world, flat, work, args, barrier=barrier)))
    except BaseException as e:  # noqa: BLE001 - reported by the parent
        barrier.abort()
        queue.put((task, [], {"error": repr(e)}))


def run_parallel(tasks: list[str], rooms: dict, work: Path, args) -> tuple[list[dict], dict]:
    """Every task's engine in a process of its own (spawned), their timed windows started together."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    barrier, queue = ctx.Barrier(len(tasks)), ctx.Queue()
    procs = [ctx.Process(target=_child, args=(t, *rooms[ROOM_OF[t]], work, args, barrier, queue)) for t in tasks]
    for pr in procs:
        pr.start()
    got = {t: (why, r) for t, why, r in (queue.get() for _ in procs)}
    for pr in procs:
        pr.join()
    bad = {t: r["error"] for t, (_, r) in got.items() if "error" in r}
    if bad:
        raise RuntimeError(f"bench_multistage: {len(bad)} of {len(tasks)} processes failed: {bad}")
    return [got[t][1] for t in tasks], {t: got[t][0] for t in tasks}


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--device", default="cpu", help="cpu, cuda or cuda:N")
    p.add_argument("--tasks", nargs="+", default=list(TASKS), choices=sorted(ROOM_OF), metavar="TASK")
    p.add_argument("--worlds", type=int, default=2, help="engine worlds (copies of the task world) per task")
    p.add_argument("--sim-seconds", type=float, default=60.0, help="the timed window [s of simulated time]")
    p.add_argument("--houses", type=int, default=8, help="flats generated per room (the first that converts runs)")
    p.add_argument("--parallel", action="store_true",
                   help="every task's engine in a process of its own, all timed together (else one after another)")
    p.add_argument("--width", type=int, default=128)
    p.add_argument("--height", type=int, default=96)
    p.add_argument("--no-images", action="store_true", help="no cameras: state and action only")
    p.add_argument("--layout", default="auto", choices=("auto", "batched", "per_world"))
    p.add_argument("--program-procs", type=int, default=0, help="expert worker processes per engine (batched layout)")
    p.add_argument("--program-wait", type=float, default=None, help="with --program-procs: [s] before holding")
    p.add_argument("--work", type=Path, default=None, help="keep (and reuse) the flats and task worlds here")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    if args.worlds < 1 or args.sim_seconds <= 0:
        p.error("--worlds must be >= 1 and --sim-seconds > 0")
    import usd_schemas  # noqa: F401

    t0 = time.time()
    work = (args.work or Path(tempfile.mkdtemp(prefix="bench_multistage_"))).resolve()
    rooms = {room: flats(room, work, args.houses) for room in dict.fromkeys(ROOM_OF[t] for t in args.tasks)}
    if args.parallel:
        results, unconverted = run_parallel(args.tasks, rooms, work, args)
    else:
        results, unconverted = [], {}
        for task in args.tasks:
            world, flat, why = task_world(task, *rooms[ROOM_OF[task]], work)
            unconverted[task] = why
            results.append(bench_task(task, world, flat, work, args))
    # one after another the walls add up; in parallel the longest window is the whole run's
    wall = max(r["wall_seconds"] for r in results) if args.parallel else sum(r["wall_seconds"] for r in results)
    ok = sum(r["successes"] for r in results)
    frames = sorted(f for r in results for f in r["episode_frames"])
    doc = {"device": args.device, "layout": args.layout, "worlds": args.worlds, "sim_seconds": args.sim_seconds,
           "parallel": args.parallel, "images": None if args.no_images else [args.height, args.width],
           "program_procs": args.program_procs,
           "overall": {"successes": ok, "episodes_completed": sum(r["episodes_completed"] for r in results),
                       "wall_seconds": round(wall, 1),
                       "successful_episodes_per_hour": round(ok / wall * 3600, 1) if wall else 0.0,
                       "median_episode_frames": int(statistics.median(frames)) if frames else None},
           "per_task": {r["task"]: r for r in results}, "flats_before": unconverted,
           "total_wall_seconds": round(time.time() - t0, 1)}
    print("overall:", json.dumps(doc["overall"]), flush=True)
    out = args.out or HERE / "results" / (f"multistage_{args.device.replace(':', '')}_w{args.worlds}"
                                          f"{'_par' if args.parallel else ''}.json")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=1))
    print("wrote", out)
    return doc


@pytest.mark.benchmark
def test_bench_multistage(tmp_path):
    """The CPU layout (one MuJoCo C model per world): a whole set_alarm_clock episode (~550 frames)."""
    doc = main(["--tasks", "set_alarm_clock", "--worlds", "1", "--sim-seconds", "25", "--houses", "3",
                "--no-images", "--work", str(tmp_path), "--out", str(tmp_path / "m.json")])
    r = doc["per_task"]["set_alarm_clock"]
    assert r["episodes_completed"] >= 1 and r["recorded_timesteps_per_second"] > 0
    assert doc["overall"]["successes"] == r["successes"] == len(r["episode_frames"])


@pytest.mark.slow
@pytest.mark.benchmark
def test_bench_multistage_batched_layout_on_cpu(tmp_path):
    """The GPU's layout (one MuJoCo-Warp model of all worlds, expert worker processes) on the CPU: a
    house task world's copies step and record with the 3 cameras (a short window: no episode ends)."""
    doc = main(["--tasks", "set_alarm_clock", "--worlds", "2", "--sim-seconds", "0.5", "--houses", "3",
                "--layout", "batched", "--program-procs", "1", "--program-wait", "0.05", "--width", "32",
                "--height", "24", "--work", str(tmp_path), "--out", str(tmp_path / "m.json")])
    r = doc["per_task"]["set_alarm_clock"]
    assert r["recorded_timesteps_per_second"] > 0 and r["split_seconds"]["rendering"] > 0


if __name__ == "__main__":
    main()
