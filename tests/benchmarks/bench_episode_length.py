"""Episode length per basic task: recorded frames (30 fps) and success of the scripted experts, CPU.

Run: ``.venv/bin/python tests/benchmarks/bench_episode_length.py --seeds 1 2`` or
``.venv/bin/python -m pytest -q -m benchmark tests/benchmarks/bench_episode_length.py -s``
(environment: ``BENCH_EPLEN_SEEDS`` comma-separated instance seeds, ``BENCH_EPLEN_TASKS``,
``BENCH_EPLEN_CATALOG``).

The kitchen's packages are generated from the default catalog and ingested first (~20 s, not
timed; ``--catalog DIR`` reuses a work dir holding ``assets/`` and
``catalog/default/generated.json``, and one that does not exist yet is built there). One kitchen
(``--kitchen`` seed) runs on the batched engine (``layout="per_world"``, MuJoCo C, one world,
no cameras: frames are counted as the recorder captures them), every task with every seed, each
episode to its end or the task's time limit. Prints a table (task, seed, frames, seconds,
success, reason) and per task the median frames; writes ``bench_results/episode_length.json``.
Issue 12's target: median at most 450 frames (15 s) for every basic task.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

TARGET_FRAMES = 450  # issue 12: median episode length per basic task [frames at 30 fps]


def _catalog(out: Path) -> Path:
    """The kitchen packages in work dir ``out`` (built there by the real job steps if absent)."""
    if (out / "catalog" / "default" / "generated.json").is_file():
        return out
    sys.path.insert(0, str(Path(__file__).parent))
    from bench_demos import build_catalog

    return build_catalog(out)


def _motion(frames, phases=None) -> dict:
    """Peaks of an episode's recorded motion (30 fps): arm joint speed [rad/s] (the Panda's limits
    are 2.175-2.61 rad/s; with ``phases``, the expert phase of each frame, also the joint and the
    phase of the peak and of the peak base command change), base speed command [m/s] and its
    change [m/s^2] (base frame), base turn rate
    command [rad/s]."""
    import numpy as np

    if len(frames) < 2:
        return {}
    q = np.stack([f.arm_joint_pos for f in frames])
    v = np.stack([f.base_velocity for f in frames])
    fps = 30.0
    dq = np.abs(np.diff(q, axis=0))
    k, j = np.unravel_index(int(np.argmax(dq)), dq.shape)
    acc = np.linalg.norm(np.diff(v[:, :2], axis=0), axis=1) * fps
    where = {"peak_joint": int(j) + 1, "peak_phase": phases[k + 1],
             "peak_accel_phase": phases[int(np.argmax(acc)) + 1]} if phases else {}
    return {**where, "peak_joint_speed": round(float(dq.max() * fps), 3),
            "peak_base_speed": round(float(np.linalg.norm(v[:, :2], axis=1).max()), 3),
            "peak_base_accel": round(float(acc.max()), 3),
            "peak_turn_rate": round(float(np.abs(v[:, 2]).max()), 3)}


class PhaseClock:
    """Simulated seconds per expert phase: wraps the :class:`~stages.demos.driver.Driver`'s motion
    methods so that each outermost call adds the simulated time it took under the key
    ``method@caller`` (e.g. ``move@_side_pick``, ``step@_settle_part``); :meth:`take` returns and
    clears the sums of the episode."""

    METHODS = ("move", "grip", "home", "follow", "step")

    def __init__(self) -> None:
        from stages.demos.driver import Driver

        self.sums: dict[str, float] = {}
        self.current: str | None = None  # the outermost phase running now
        self._depth = 0
        for name in self.METHODS:
            setattr(Driver, name, self._wrap(getattr(Driver, name), name))

    def _wrap(self, fn, name):
        clock = self

        def wrapped(d, *args, **kwargs):
            if clock._depth:
                return fn(d, *args, **kwargs)
            key = f"{name}@{sys._getframe(1).f_code.co_name}"
            t0 = d.sim.time
            clock._depth += 1
            clock.current = key
            try:
                return fn(d, *args, **kwargs)
            finally:
                clock._depth -= 1
                clock.current = None
                clock.sums[key] = clock.sums.get(key, 0.0) + d.sim.time - t0

        return wrapped

    def take(self) -> dict[str, float]:
        out = {k: round(v, 2) for k, v in sorted(self.sums.items(), key=lambda kv: -kv[1])}
        self.sums = {}
        return out


def run(seeds=(1, 2), tasks=None, catalog: Path | None = None, kitchen: int = 5, phases: bool = False,
        name: str = "episode_length") -> dict:
    """Run every (task, seed) episode; returns (and writes to ``bench_results/<name>.json``) the
    figures. ``phases``: also the simulated seconds per expert phase (:class:`PhaseClock`)."""
    import numpy as np

    from stages.demos.kitchen import AssetLibrary, write_kitchen
    from stages.demos.tasks import BASIC_TASKS
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    tasks = tuple(tasks or BASIC_TASKS)
    with tempfile.TemporaryDirectory(prefix="bench-eplen-") as tmp:
        cat = _catalog(Path(catalog) if catalog else Path(tmp) / "out")
        lib = AssetLibrary.from_folder(cat / "assets", cat / "catalog" / "default" / "generated.json")
        room = write_kitchen(Path(tmp) / "kitchen", lib, scene_id="eplen", rng=np.random.default_rng(kitchen))
        eng = BatchEngine(room, panda_root=None, work_dir=Path(tmp) / "kitchen",
                          config=EngineConfig(worlds=1, layout="per_world", record_images=False))
        rows: list[dict] = []
        clock = PhaseClock() if phases else None
        seen: list = []
        phase_of: list = []

        def sink(frame):
            seen.append(frame)
            phase_of.append(clock.current if clock is not None else None)

        def begin(w, ticket):
            seen.clear()
            phase_of.clear()
            return sink
        t_wall = [time.perf_counter()]

        def end(w, ticket, res):
            now = time.perf_counter()
            rows.append({"task": ticket.task, "seed": ticket.seed, "frames": res.frames,
                         "sim_s": round(res.sim_seconds, 2), "success": res.success, "reason": res.reason,
                         "wall_s": round(now - t_wall[0], 1), **_motion(seen, phase_of if clock else None)})
            if clock is not None:
                rows[-1]["phases_s"] = clock.take()
                print("   ", rows[-1]["phases_s"], flush=True)
            t_wall[0] = now
            r = rows[-1]
            print(f"{ticket.task:22s} seed {ticket.seed:3d} {res.frames:5d} frames {res.sim_seconds:6.1f} s "
                  f"{'ok' if res.success else 'FAILED ' + res.reason}  ({r['wall_s']} s wall; peaks: joint "
                  f"{r.get('peak_joint_speed')} rad/s, base {r.get('peak_base_speed')} m/s "
                  f"{r.get('peak_base_accel')} m/s^2{' in ' + str(r['peak_accel_phase']) if clock else ''}; "
                  f"joint peak in {r.get('peak_phase')})", flush=True)

        eng.run(Listed(room, {0: [(t, s, None) for t in tasks for s in seeds]}), begin=begin, end=end)
    per_task = {}
    for t in tasks:
        rs = [r for r in rows if r["task"] == t]
        per_task[t] = {"median_frames": statistics.median(r["frames"] for r in rs),
                       "max_frames": max(r["frames"] for r in rs),
                       "successes": sum(r["success"] for r in rs), "episodes": len(rs)}
    out = {"fps": 30, "target_median_frames": TARGET_FRAMES, "kitchen_seed": kitchen, "seeds": list(seeds),
           "cpu_count": os.cpu_count(), "tasks": per_task, "episodes": rows}
    print(f"\n{'task':22s} {'median':>7s} {'max':>6s} success")
    for t, v in per_task.items():
        flag = "" if v["median_frames"] <= TARGET_FRAMES else f"  > {TARGET_FRAMES}"
        print(f"{t:22s} {v['median_frames']:7.0f} {v['max_frames']:6d} "
              f"{v['successes']}/{v['episodes']}{flag}")
    ok = sum(r["success"] for r in rows)
    print(f"{ok}/{len(rows)} episodes succeeded; median frames over tasks "
          f"{statistics.median(v['median_frames'] for v in per_task.values()):.0f}")
    dest = REPO / "bench_results" / f"{name}.json"
    dest.parent.mkdir(exist_ok=True)
    dest.write_text(json.dumps(out, indent=2) + "\n")
    return out


@pytest.mark.benchmark
def test_bench_episode_length():
    res = run(seeds=tuple(int(s) for s in os.environ.get("BENCH_EPLEN_SEEDS", "1").split(",")),
              tasks=tuple(os.environ["BENCH_EPLEN_TASKS"].split(",")) if "BENCH_EPLEN_TASKS" in os.environ
              else None,
              catalog=(Path(os.environ["BENCH_EPLEN_CATALOG"]) if "BENCH_EPLEN_CATALOG" in os.environ
                       else None))
    assert all(r["frames"] > 0 for r in res["episodes"])


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, nargs="+", default=[1, 2], help="instance seeds per task")
    p.add_argument("--tasks", default=None, help="comma-separated tasks (default: every basic task)")
    p.add_argument("--catalog", type=Path, default=None,
                   help="work dir with assets/ and catalog/default/generated.json (built there if absent)")
    p.add_argument("--kitchen", type=int, default=5, help="the kitchen's seed")
    p.add_argument("--phases", action="store_true", help="also simulated seconds per expert phase")
    p.add_argument("--name", default="episode_length", help="writes bench_results/<name>.json")
    p.add_argument("--verbose", action="store_true", help="the experts' log (stages, re-plans)")
    a = p.parse_args()
    if a.verbose:
        import logging

        logging.basicConfig(level=logging.WARNING, format="%(name)s: %(message)s")
        logging.getLogger("stages.demos").setLevel(logging.INFO)
    run(tuple(a.seeds), a.tasks.split(",") if a.tasks else None, a.catalog, a.kitchen, a.phases, a.name)
