"""Benchmark: the batched demonstration engine, end to end and per component, over world counts.

For each world count N: a :class:`~stages.engine.BatchEngine` of N worlds of one default-catalog
kitchen runs the 15 basic tasks' scripted experts (round robin, seeds per world) with 3 cameras
(RGB + depth) at the given size for ``--sim-seconds`` of simulated time after a warm-up, and
prints

- recorded timesteps/s end to end: frames handed to the episode sinks per wall second. With
  ``--write`` the sinks are real dataset shards, one per world (the demos job's writer: RGB video
  encoded as frames arrive, depth as 16-bit PNG), and the wall time includes flushing them;
  without it the sinks keep the frames' arrays alive but do not encode,
- the split of the wall time (simulation, rendering, control: the experts' programs and resets,
  encoding: frame assembly and sinks),
- each component's standalone maximum in the same run, as recorded timesteps/s: simulation only
  (N worlds stepped, 1 / (fps dt) steps per frame), rendering only (3 cameras rendered, converted
  on the device and read back for all N worlds: ``CameraRig.render_compact``, what the engine
  records), encoding only (with ``--write``: the last recorded frame of every world written again
  into fresh shards by the same writers, N at a time), and the end-to-end rate as a fraction of
  the slowest of them;
- completed episodes, successes per hour and the median episode length per task [frames];
- with ``--writer-procs``: ``pool_wait_s``, the time the engine's hand-off waited for a free slot of
  the writer processes (part of "encoding"), and ``handoff_ms_per_frame``, the engine's encoding
  time less that wait per recorded frame: a large wait says the writers limit, a large hand-off the
  engine's own thread (per engine process with ``--procs``).

``--tasks`` replaces the basic tasks by any list of task names, e.g. the multistage tasks (issue 16:
episodes per hour of the multistage job on the batched engine; the kitchen then parks the household
objects or the drink they need, frames record the stage). A multistage episode is 1,000-1,500
frames (35-50 s at 30 fps): give ``--sim-seconds`` several times that.

Writes ``bench_results/engine.json``. Run on the GPU machine::

    python tests/benchmarks/bench_engine.py --device cuda --worlds 1 16 64 256 1024 --catalog DIR

``--catalog``: a work dir holding the kitchen categories of the default catalog, generated and
ingested (``catalog/default/generated.json`` and ``assets/``); without it the benchmark builds
one (about 20 s on 2 cores).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))


def _catalog(work: Path) -> Path:
    from pipeline import build_job, run_job
    from stages.demos.kitchen import KITCHEN_CATEGORIES

    out = work / "catalog_out"
    if not (out / "catalog" / "default" / "generated.json").is_file():
        job = {"job": {"name": "bench_engine", "seed": 0, "out": str(out), "executor": "inline", "workers": 1},
               "step": [{"name": "catalog", "kind": "default_catalog",
                         "config": {"variants": 5, "categories": list(KITCHEN_CATEGORIES)}},
                        {"name": "assets", "kind": "ingest", "config": {"catalog_step": "catalog"}}]}
        run_job(build_job(job, source="<bench>", base_dir=work), progress=False)
    return out


def _multistage(tasks) -> bool:
    from stages.demos.multistage import MULTISTAGE

    return any(t in MULTISTAGE for t in tasks)


def _kitchen(folder: Path, lib, tasks):
    """The benchmark's kitchen (world seed 5), with the household objects or the drink that
    ``tasks`` need (None: the basic tasks)."""
    from stages.demos.kitchen import write_kitchen
    from stages.demos.multistage import needs_drink, needs_household

    tasks = tasks or ()
    return write_kitchen(folder, lib, scene_id="kitchen_bench", rng=np.random.default_rng(5),
                         household=needs_household(tasks), drink=needs_drink(tasks))


def _sync(device: str) -> None:
    import warp as wp

    wp.synchronize_device(device)


def bench_worlds(room, work: Path, n: int, args, *, barrier=None, seed_base: int = 0) -> dict:
    """One engine of ``n`` worlds; with ``barrier`` (a process pool's), the timed run and the
    standalone measurements start together with the other processes'."""
    from stages.demos.sampling import sample_instance
    from stages.demos.tasks import BASIC_TASKS
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import RoundRobin

    tasks = list(args.tasks) if args.tasks else sorted(BASIC_TASKS)
    t0 = time.perf_counter()
    eng = BatchEngine(room, panda_root=args.panda_root, work_dir=work,
                      config=EngineConfig(worlds=n, device=args.device, width=args.width, height=args.height,
                                          record_images=not args.no_images,
                                          program_procs=args.program_procs, program_wait=args.program_wait,
                                          program_yield=args.program_yield, layout=args.layout,
                                          subtasks=_multistage(tasks)))
    build = time.perf_counter() - t0
    next_instance = RoundRobin(room, tasks, seed_base)

    held = {"frames": 0}

    shards = _Shards(eng, work / f"shards_{n}", args.writer_procs) if args.write else None

    def begin(w, inst):
        add = shards.begin(w, inst) if shards is not None else None
        if add is not None and args.writer_procs > 0 and w != 0:
            return add  # the pool's own sink: the engine hands a frame step's frames over in batches

        def sink(frame):  # world 0's keeps its last frame (the encoding-only measurement writes it)
            held["frames"] += 1
            held["last"] = frame  # keep one frame alive (its arrays are real copies)
            if add is not None:
                add(frame)
        # a pool's writers copy the frame at once: the engine may pass views of its render buffers
        sink.takes_views = shards is not None and args.writer_procs > 0
        return sink

    done: list[tuple[str, bool, int, str]] = []

    def end(w, inst, res):
        done.append((inst.task, res.success, res.frames, res.reason))
        if shards is not None:
            shards.end(w, res)

    # warm-up: compile kernels, capture the CUDA graphs, first resets
    eng.run(next_instance, begin=begin, end=end, max_steps=2 * eng.sync_period)
    _sync(args.device)
    if shards is not None:
        shards.stop(keep=False)
    done.clear()
    held["frames"] = 0
    s0 = eng.stats.to_json()["timings"]
    start0 = eng.stats.startup_seconds
    steps = int(args.sim_seconds * eng.steps_per_second)
    if barrier is not None:
        barrier.wait()
    prof = None
    if args.profile:
        import cProfile

        prof = cProfile.Profile()
        prof.enable()
    t0 = time.perf_counter()
    eng.run(next_instance, begin=begin, end=end, max_steps=steps)
    _sync(args.device)
    if prof is not None:
        prof.disable()
        _write_profile(prof, args.out.with_name(f"{args.out.stem}_profile_{n}.txt"))
    pool_wait = shards.wait_s() if shards is not None else None  # [s] the hand-off waiting for writers
    if shards is not None:
        shards.stop(keep=True, reopen=False)  # episodes cut by the window are written too: encoding counts
    wall = time.perf_counter() - t0 - (eng.stats.startup_seconds - start0)  # worker start-up excluded
    s1 = eng.stats.to_json()["timings"]
    split = {k: round(s1[k] - s0[k], 3) for k in ("simulation", "rendering", "control", "encoding")}
    world_steps = n * steps  # every world's steps in the window, held ones included
    frames = s1["frames"] - s0["frames"]  # every recording world has a sink: all are handed over
    e2e = frames / wall

    # standalone maxima, same engine, same worlds
    bank = eng.banks[0]
    steps_per_frame = eng.steps_per_second / args.fps
    k = max(eng.sync_period, 50)
    if barrier is not None:
        barrier.wait()
    bank.sim.step(k)
    _sync(args.device)
    t = time.perf_counter()
    bank.sim.step(k)
    _sync(args.device)
    sim_only = n * (k / (time.perf_counter() - t)) / steps_per_frame
    render_only = None
    if bank.rig is not None:
        bank.rig.render_compact()
        reps = []
        for _ in range(3):
            t = time.perf_counter()
            bank.rig.render_compact()
            reps.append(time.perf_counter() - t)
        render_only = n / statistics.median(reps)
    if barrier is not None:
        barrier.wait()
    render_split = _render_split(eng, bank, args) if (bank.rig is not None and args.render_split) else None
    maxima = {"simulation": round(sim_only, 1)}
    if render_only is not None:
        maxima["rendering"] = round(render_only, 1)
    if shards is not None and "last" in held:
        maxima["encoding"] = round(_encode_only(eng, work / f"encode_{n}", held["last"],
                                                procs=args.writer_procs), 1)
    slowest = min(maxima.values())
    lengths: dict[str, list[int]] = defaultdict(list)
    for task, ok, fr, _ in done:
        if ok:
            lengths[task].append(fr)
    res = {
        "worlds": n, "build_seconds": round(build, 2), "wall_seconds": round(wall, 2),
        "sim_seconds": args.sim_seconds, "recorded_timesteps_per_second": round(e2e, 1),
        "split_seconds": split, "standalone_timesteps_per_second": maxima,
        "fraction_of_slowest_component": round(e2e / slowest, 3) if slowest else None,
        "episodes_completed": len(done), "successes": sum(ok for _, ok, _, _ in done),
        "successful_episodes_per_hour": round(sum(ok for _, ok, _, _ in done) / wall * 3600, 1),
        "failures": dict(sorted(_count(r for _, ok, _, r in done if not ok).items())),
        "failures_by_task": {t: dict(sorted(_count(r for tt, ok, _, r in done if tt == t and not ok).items()))
                             for t in sorted({tt for tt, ok, _, _ in done if not ok})},
        "median_episode_frames": {t: int(statistics.median(v)) for t, v in sorted(lengths.items())},
        "frames": frames, "lengths": {t: v for t, v in lengths.items()},
        "render_split_seconds_per_frame": render_split,
        "holds": eng.stats.holds, "held_world_seconds": round(eng.stats.held_steps / eng.steps_per_second, 2),
        "yields": eng.stats.yields, "program_yield": args.program_yield,
        "control_ms_per_world_step": round(1000 * split["control"] / world_steps, 4),
        "pool_wait_s": None if pool_wait is None else round(pool_wait, 3),
        "handoff_ms_per_frame": round(1000 * (split["encoding"] - (pool_wait or 0.0)) / max(frames, 1), 4),
        "engine_steps": eng.stats.advances, "physics_steps": eng.stats.steps,
    }
    print(json.dumps(res), flush=True)
    return res


class _Shards:
    """One dataset shard per engine world (the demos job's writer), recreated per window."""

    def __init__(self, eng, root: Path, procs: int = 0) -> None:
        import shutil

        shutil.rmtree(root, ignore_errors=True)
        self.eng, self.root, self.k, self.procs = eng, root, 0, procs
        self.open()

    def open(self) -> None:
        from stages.dataset.pool import open_shards

        self.k += 1
        spec = self.eng.config.dataset_spec()
        self._ctx = open_shards(self.root / f"r{self.k}", [f"w{i:04d}" for i in range(self.eng.config.worlds)],
                                spec, self.procs)
        self.w = self._ctx.__enter__()
        self.live = set()

    def begin(self, w: int, inst):
        from stages.dataset import EpisodeInfo

        self.w[w].begin_episode(EpisodeInfo(task=inst.instruction, task_kind=inst.task, scene_id="kitchen_bench",
                                            seed=inst.seed, asset_ids=inst.asset_ids))
        self.live.add(w)
        return self.w[w].add_frame

    def wait_s(self) -> float:
        """[s] the engine waited for a free writer slot in this window's pool (0: inline writers)."""
        return self.w[0].pool.wait_s if self.procs > 0 and self.w else 0.0

    def end(self, w: int, res) -> None:
        self.w[w].end_episode(success=res.success, reason=res.reason)
        self.live.discard(w)

    def stop(self, *, keep: bool, reopen: bool = True) -> None:
        """End the episodes the window cut (written when ``keep``, else dropped), close every shard,
        and open fresh ones for the next window when ``reopen``."""
        for w in sorted(self.live):
            self.w[w].end_episode(success=keep, reason="" if keep else "benchmark_window")
        self._ctx.__exit__(None, None, None)
        if reopen:
            self.open()


def _encode_only(eng, root: Path, frame, frames_per_world: int = 30, procs: int = 0) -> float:
    """Encoding alone: ``frames_per_world`` copies of ``frame`` into one fresh shard per world,
    all worlds in turn per frame (as the engine hands them over), written by the engine's process
    or by ``procs`` writer processes (closing included). Returns timesteps/s."""
    import shutil

    from stages.dataset import EpisodeInfo
    from stages.dataset.pool import open_shards

    shutil.rmtree(root, ignore_errors=True)
    spec = eng.config.dataset_spec()
    n = eng.config.worlds
    ctx = open_shards(root, [f"w{i:04d}" for i in range(n)], spec, procs)
    ws = ctx.__enter__()
    if procs:
        ws[0].pool.wait_ready()  # process start-up and lerobot's import are not encoding
    t = time.perf_counter()
    for wr in ws:
        wr.begin_episode(EpisodeInfo(task="encode", task_kind="press_button", scene_id="kitchen_bench", seed=0,
                                     asset_ids=()))
    for _ in range(frames_per_world):
        for wr in ws:
            wr.add_frame(frame)
    for wr in ws:
        wr.end_episode(success=True)
    ctx.__exit__(None, None, None)
    rate = n * frames_per_world / (time.perf_counter() - t)
    shutil.rmtree(root, ignore_errors=True)
    return rate


def _child(args, n: int, k: int, barrier, queue) -> None:
    """Process ``k`` of a pool: its own kitchen copy and an engine of ``n`` worlds."""
    import usd_schemas  # noqa: F401
    from stages.demos.kitchen import AssetLibrary

    try:
        if args.devices:  # processes spread over the host's GPUs, round robin
            args.device = args.devices[k % len(args.devices)]
        work = args.work / f"proc{k:02d}"
        lib = AssetLibrary.from_folder(args.catalog / "assets", args.catalog / "catalog" / "default" / "generated.json")
        room = _kitchen(work / "kitchen", lib, args.tasks)
        from stages.engine import device_scope

        with device_scope(args.device):  # "cuda:N": every allocation of this engine on its GPU
            queue.put(bench_worlds(room, work, n, args, barrier=barrier, seed_base=k * n))
    except BaseException as e:  # noqa: BLE001
        barrier.abort()
        queue.put({"error": repr(e)})


def bench_pool(n: int, args) -> dict:
    """``args.procs`` processes, each an engine of n / procs worlds on the same device, timed
    together: the aggregate recorded timesteps/s is all frames over the longest wall time."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    k = args.procs
    barrier, queue = ctx.Barrier(k), ctx.Queue()
    procs = [ctx.Process(target=_child, args=(args, n // k, i, barrier, queue)) for i in range(k)]
    for pr in procs:
        pr.start()
    parts = [queue.get() for _ in procs]
    for pr in procs:
        pr.join()
    bad = [r["error"] for r in parts if "error" in r]
    if bad:
        raise RuntimeError(f"{len(bad)} of {k} processes failed: {bad[0]}")
    wall = max(r["wall_seconds"] for r in parts)
    frames = sum(r["frames"] for r in parts)
    lengths: dict[str, list[int]] = defaultdict(list)
    for r in parts:
        for t, v in r["lengths"].items():
            lengths[t] += v
    maxima = {c: round(sum(r["standalone_timesteps_per_second"].get(c, 0.0) for r in parts), 1)
              for c in parts[0]["standalone_timesteps_per_second"]}
    e2e = frames / wall
    res = {"worlds": n, "procs": k, "wall_seconds": round(wall, 2), "sim_seconds": args.sim_seconds,
           "recorded_timesteps_per_second": round(e2e, 1), "standalone_timesteps_per_second": maxima,
           "fraction_of_slowest_component": round(e2e / min(maxima.values()), 3),
           "split_seconds_per_process": [r["split_seconds"] for r in parts],
           "pool_wait_s_per_process": [r["pool_wait_s"] for r in parts],
           "handoff_ms_per_frame_per_process": [r["handoff_ms_per_frame"] for r in parts],
           "control_ms_per_world_step_median": statistics.median(r["control_ms_per_world_step"]
                                                                 for r in parts),
           "episodes_completed": sum(r["episodes_completed"] for r in parts),
           "successes": sum(r["successes"] for r in parts),
           "successful_episodes_per_hour": round(sum(r["successes"] for r in parts) / wall * 3600, 1),
           "median_episode_frames": {t: int(statistics.median(v)) for t, v in sorted(lengths.items())}}
    print(json.dumps(res), flush=True)
    return res


def _render_split(eng, bank, args) -> dict:
    """Seconds per frame (all worlds, 3 cameras) of the render's parts: BVH refit, camera poses,
    ray tracing (device, synchronised), read-back and unpacking; and of whole renders without
    shadows and without textures (other rigs on the same Sim, with --render-variants)."""
    import warp as wp

    from stages.simulate.sensors import CameraRig

    rig, dev = bank.rig, args.device

    def timed(fn, reps=3):
        fn()
        wp.synchronize_device(dev)
        out = []
        for _ in range(reps):
            t = time.perf_counter()
            fn()
            wp.synchronize_device(dev)
            out.append(time.perf_counter() - t)
        return round(statistics.median(out), 4)

    state = bank.sim.state_0
    poses = {c.name: rig._transforms(c) for c in rig.cameras}

    def trace():
        for c in rig.cameras:
            img = rig._images[c.name]
            rig._sensor.update(state, poses[c.name][0], rig._rays[c.name], color_image=img["color"],
                               forward_depth_image=img["depth"], shape_index_image=img["shape"],
                               world_indices=rig._world_ids)

    def readback():
        for c in rig.cameras:
            rig._frame(c, rig._images[c.name], poses[c.name][1])

    out = {"refit": timed(lambda: bank.sim.model.bvh_refit_shapes(state)),
           "poses": timed(lambda: [rig._transforms(c) for c in rig.cameras]),
           "trace": timed(trace), "readback_unpack": timed(readback), "whole": timed(rig.render),
           "whole_compact": timed(rig.render_compact)}
    # how long the host is held by launching a compact render (the engine runs the programs after it)
    launch, wait = [], []
    for _ in range(3):
        wp.synchronize_device(dev)
        t = time.perf_counter()
        r = rig.render_compact_async()
        launch.append(time.perf_counter() - t)
        r.wait()
        wait.append(time.perf_counter() - t - launch[-1])
    out["compact_launch"] = round(statistics.median(launch), 4)
    out["compact_wait"] = round(statistics.median(wait), 4)
    for name, fn in (("refit_only_host", lambda: bank.sim.model.bvh_refit_shapes(state)), ("trace_host", trace)):
        wp.synchronize_device(dev)
        t = time.perf_counter()
        fn()
        out[name] = round(time.perf_counter() - t, 4)  # host time of the call, no synchronisation
        wp.synchronize_device(dev)
    for name, kw in ((("no_shadows", {"shadows": False}), ("no_textures", {"textures": False}))
                     if args.render_variants else ()):
        other = CameraRig(bank.sim, rig.cameras, segmentation=False, **kw)
        out[f"whole_{name}"] = timed(other.render)
    return out


def _write_profile(prof, path: Path) -> None:
    """The engine process's profile of the timed window: functions by cumulative and own time."""
    import io
    import pstats

    buf = io.StringIO()
    st = pstats.Stats(prof, stream=buf)
    st.sort_stats("cumulative").print_stats(70)
    st.sort_stats("tottime").print_stats(40)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(buf.getvalue())
    print(f"profile: {path}", flush=True)


def _count(it) -> dict:
    out: dict[str, int] = defaultdict(int)
    for x in it:
        out[x] += 1
    return out


def main(argv=None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--device", default=os.environ.get("AGENTWORLD_BENCH_DEVICE", "cpu"))
    p.add_argument("--worlds", type=int, nargs="+", default=[1, 2])
    p.add_argument("--tasks", nargs="+", default=None,
                   help="task names, basic or multistage (default: the 15 basic tasks), round robin over the worlds")
    p.add_argument("--width", type=int, default=320)
    p.add_argument("--height", type=int, default=240)
    p.add_argument("--fps", type=int, default=30)
    p.add_argument("--sim-seconds", type=float, default=2.0)
    p.add_argument("--no-images", action="store_true")
    p.add_argument("--render-split", action="store_true", help="time the render's parts too")
    p.add_argument("--render-variants", action="store_true",
                   help="with --render-split: whole renders without shadows and without textures too "
                        "(two more rigs: minutes of kernel compilation on a fresh machine)")
    p.add_argument("--ab-render-stream", action="store_true",
                   help="each world count twice: render on the simulation's CUDA stream, then on its own")
    p.add_argument("--profile", action="store_true",
                   help="profile the engine process over the timed window (cProfile; written beside --out)")
    p.add_argument("--write", action="store_true", help="record into real dataset shards (encoding included)")
    p.add_argument("--writer-procs", type=int, default=0,
                   help="with --write: processes writing the shards (stages.dataset.pool; 0: the engine's)")
    p.add_argument("--catalog", type=Path, default=None)
    p.add_argument("--panda-root", type=Path, default=None)
    p.add_argument("--procs", type=int, default=1, help="engine processes sharing the device (worlds split)")
    p.add_argument("--devices", nargs="+", default=None,
                   help="with --procs: spread the engine processes over these devices (e.g. cuda:0 cuda:1)")
    p.add_argument("--program-procs", type=int, default=0,
                   help="worker processes for the world programs of each engine (0: threads)")
    p.add_argument("--layout", default="auto", choices=("auto", "batched", "per_world"))
    p.add_argument("--program-wait", type=float, default=None,
                   help="seconds to wait for planning programs before holding their worlds (None: wait for all)")
    p.add_argument("--program-yield", type=lambda v: None if v == "none" else float(v), default=0.002,
                   help="seconds a program plans before it parks at a checkpoint and its world is held at "
                        "once (EngineConfig.program_yield; 'none': never)")
    p.add_argument("--ab-program-yield", action="store_true",
                   help="each world count twice: programs never park (--program-yield none), then as given")
    p.add_argument("--work", type=Path, default=REPO / "bench_results" / "engine_work")
    p.add_argument("--out", type=Path, default=REPO / "bench_results" / "engine.json")
    args = p.parse_args(argv)
    import usd_schemas  # noqa: F401
    from stages.demos.kitchen import AssetLibrary

    args.work.mkdir(parents=True, exist_ok=True)
    cat = args.catalog = (args.catalog or _catalog(args.work)).resolve()
    args.work = args.work.resolve()
    args.panda_root = args.panda_root.resolve() if args.panda_root else None
    lib = AssetLibrary.from_folder(cat / "assets", cat / "catalog" / "default" / "generated.json")
    room = _kitchen(args.work / "kitchen", lib, args.tasks)
    results = []
    from stages.simulate import compact

    runs = [(n, s) for n in args.worlds for s in ((False, True) if args.ab_render_stream else (None,))]
    if args.ab_program_yield:
        runs = [(n, ("yield", y)) for n in args.worlds for y in (None, args.program_yield)]
    for n, stream in runs:
        if isinstance(stream, tuple):
            args.program_yield = stream[1]
            print(f"worlds {n}: program_yield {stream[1]}", flush=True)
        elif stream is not None:
            compact.OWN_STREAM = stream
            print(f"worlds {n}: render on its own CUDA stream: {stream}", flush=True)
        try:
            results.append(bench_pool(n, args) if args.procs > 1 else bench_worlds(room, args.work, n, args))
            if stream is not None and not isinstance(stream, tuple):
                results[-1]["render_own_stream"] = stream
        except Exception as e:  # noqa: BLE001 (out of memory at large N: report and go on)
            print(f"worlds {n}: failed: {e!r}", flush=True)
            results.append({"worlds": n, "error": repr(e)})
    doc = {"device": args.device, "devices": args.devices, "procs": args.procs, "program_procs": args.program_procs, "size": [args.height, args.width], "cameras": 3,
           "images": not args.no_images, "results": results}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    prev = json.loads(args.out.read_text()) if args.out.is_file() else {}
    prev[f"{args.device}_{args.height}x{args.width}_p{args.procs}_w{args.program_procs}"
         f"{'_noimg' if args.no_images else ''}{'_ab_yield' if args.ab_program_yield else ''}"] = doc
    args.out.write_text(json.dumps(prev, indent=1))
    return doc


@pytest.mark.benchmark
def test_bench_engine():
    doc = main(["--worlds", "1", "2", "--sim-seconds", "1", "--width", "64", "--height", "48"])
    assert all(r.get("recorded_timesteps_per_second", 0) > 0 for r in doc["results"])


if __name__ == "__main__":
    main()
