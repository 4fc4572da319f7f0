"""Record humanoid demonstrations: a task kitchen, the humanoid engine (``stages.engine.humanoid``)
and its experts (``stages.demos.humanoid_experts``); success per task with failure reasons, the
successful episodes as a LeRobot dataset in the embodiment's schema, a contact sheet of its
cameras.

::

    python -m stages.demos.humanoid_run --work out/humanoid --world-seeds 5 --tasks close_drawer \\
        --episodes 30 [--cameras head,left_wrist,right_wrist] [--spec g1_29dof]

writes ``<work>/reports/humanoid_demos.json`` (attempts, successes, failure reasons, frames and
simulated / wall seconds per episode), with cameras ``<work>/datasets/humanoid/shards`` (one shard
per kitchen), the merged dataset ``<work>/datasets/humanoid/merged`` and
``<work>/reports/humanoid_contact_sheet.png``. Episode k of a task in a kitchen has seed
``seed0 + k`` (``stages.demos.sampling.sample_instance``: start pose, the part's opening).
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from collections import Counter
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)


@dataclass(frozen=True, kw_only=True)
class HumanoidRunConfig:
    """tasks; episodes per task and kitchen; world_seeds: kitchens (``teleop_kitchen`` world seeds);
    seed0: the first episode seed; spec: embodiment; cameras (empty: no dataset, the success rate
    only); width / height [px]; max_seconds: episode time limit [s]."""

    tasks: tuple[str, ...] = ("close_drawer",)
    episodes: int = 30
    world_seeds: tuple[int, ...] = (5,)
    seed0: int = 1
    spec: str = "g1_29dof"
    cameras: tuple[str, ...] = ()
    width: int = 128
    height: int = 96
    max_seconds: float = 40.0


def run_kitchen(kitchen: Any, cfg: HumanoidRunConfig, *, shards_dir: Path | None = None,
                shard_id: str = "") -> tuple[list[dict], Path | None]:
    """Every (task, episode) of ``cfg`` in one kitchen on one humanoid engine; with cameras and
    ``shards_dir`` the successful episodes go to shard ``shards_dir/shard_id``. Returns the episode
    records and the shard (None without one)."""
    from stages.dataset import EpisodeInfo, open_shard
    from stages.demos.humanoid_experts import humanoid_program
    from stages.demos.sampling import sample_instance
    from stages.engine.humanoid import HumanoidEngine, HumanoidEngineConfig

    eng = HumanoidEngine(kitchen, HumanoidEngineConfig(spec=cfg.spec, cameras=cfg.cameras, width=cfg.width,
                                                      height=cfg.height, max_seconds=cfg.max_seconds))
    queue = [sample_instance(t, kitchen, cfg.seed0 + k) for k in range(cfg.episodes) for t in cfg.tasks]
    episodes: list[dict] = []
    with ExitStack() as stack:
        shard = (stack.enter_context(open_shard(shards_dir, shard_id, eng.dataset_spec()))
                 if cfg.cameras and shards_dir is not None else None)

        def begin(w: int, inst: Any):
            if shard is None:
                return None
            shard.begin_episode(EpisodeInfo(task=inst.instruction, task_kind=inst.task,
                                            scene_id=kitchen.scene_id, seed=inst.seed,
                                            asset_ids=inst.asset_ids))
            return shard.add_frame

        def end(w: int, inst: Any, res: Any):
            if shard is not None:
                shard.end_episode(success=res.success, reason=res.reason)
            episodes.append({"scene_id": kitchen.scene_id, "task": inst.task, "seed": inst.seed,
                             "success": res.success, "reason": res.reason, "detail": res.detail,
                             "frames": res.frames, "sim_seconds": round(res.sim_seconds, 2),
                             "wall_seconds": round(res.wall_seconds, 1)})
            log.info("%s %s seed %d: %s %s (%.1f s simulated, %.0f s wall)", inst.task, kitchen.scene_id,
                     inst.seed, "success" if res.success else "failed", res.reason, res.sim_seconds,
                     res.wall_seconds)

        eng.run(lambda w: queue.pop(0) if queue else None, humanoid_program, begin=begin, end=end)
    path = shards_dir / shard_id if shard is not None else None
    return episodes, path


def record(work: Path, cfg: HumanoidRunConfig) -> dict[str, Any]:
    """Run every (kitchen, task, episode) of ``cfg`` in ``work``; returns the report (also written)."""
    from stages.dataset import merge_shards
    from stages.teleop.world import teleop_kitchen

    work = Path(work)
    (work / "reports").mkdir(parents=True, exist_ok=True)
    episodes: list[dict] = []
    shards_dir = work / "datasets" / "humanoid" / "shards"
    t_all = time.perf_counter()
    for ws in cfg.world_seeds:
        kitchen = teleop_kitchen(work / "kitchens", world_seed=ws, scene_id=f"kitchen_ws{ws}")
        eps, _ = run_kitchen(kitchen, cfg, shards_dir=shards_dir, shard_id=f"{cfg.spec}_ws{ws}")
        episodes += eps
    report = summarize(episodes, cfg.tasks, time.perf_counter() - t_all)
    report.update(spec=cfg.spec, world_seeds=list(cfg.world_seeds))
    if cfg.cameras and any(e["success"] for e in episodes):
        merged = work / "datasets" / "humanoid" / "merged"
        res = merge_shards(shards_dir, merged, repo_id=f"agentworld/humanoid_{cfg.spec}")
        report["dataset"] = str(res.root)
        sheet = contact_sheet(res.root, work / "reports" / "humanoid_contact_sheet.png")
        report["contact_sheet"] = str(sheet)
    (work / "reports" / "humanoid_demos.json").write_text(json.dumps(report, indent=1))
    return report


def contact_sheet(dataset: Path, out: Path) -> Path:
    """A PNG of the dataset's head and wrist views (and depth): 3 episodes x 6 frames."""
    from stages.dataset.render import render_contact_sheet

    return render_contact_sheet(dataset, out, frames=6, max_episodes=3)


def summarize(episodes: list[dict], tasks_run: tuple[str, ...], wall_s: float) -> dict[str, Any]:
    """Attempts, successes and failure reasons per task, and every episode."""
    tasks = {}
    for t in tasks_run:
        eps = [e for e in episodes if e["task"] == t]
        ok = [e for e in eps if e["success"]]
        frames = sorted(e["frames"] for e in ok) or [0]
        tasks[t] = {"attempts": len(eps), "successes": len(ok),
                    "rate": round(len(ok) / len(eps), 3) if eps else None,
                    "failures": dict(Counter(e["reason"] for e in eps if not e["success"])),
                    "median_sim_seconds": sorted(e["sim_seconds"] for e in ok)[len(ok) // 2] if ok else None,
                    "median_frames": frames[len(frames) // 2]}
    return {"attempts": len(episodes), "successes": sum(e["success"] for e in episodes),
            "wall_seconds": round(wall_s, 1), "tasks": tasks, "episodes": episodes}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m stages.demos.humanoid_run",
                                description=__doc__.splitlines()[0])
    p.add_argument("--work", type=Path, required=True)
    p.add_argument("--tasks", default="close_drawer")
    p.add_argument("--episodes", type=int, default=30)
    p.add_argument("--world-seeds", default="5")
    p.add_argument("--seed0", type=int, default=1)
    p.add_argument("--spec", default="g1_29dof")
    p.add_argument("--cameras", default="", help="comma-separated cameras of the spec (empty: no dataset)")
    p.add_argument("--size", default="128x96", help="camera image WxH [px]")
    a = p.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    w, h = (int(v) for v in a.size.split("x"))
    cfg = HumanoidRunConfig(tasks=tuple(a.tasks.split(",")), episodes=a.episodes,
                            world_seeds=tuple(int(s) for s in a.world_seeds.split(",")), seed0=a.seed0,
                            spec=a.spec,
                            cameras=tuple(c for c in a.cameras.split(",") if c), width=w, height=h)
    report = record(a.work, cfg)
    print(json.dumps(report["tasks"], indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
