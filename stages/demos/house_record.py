"""Record the multistage tasks of generated houses (issue 16): each house task world's episodes
on the batched engine with its cameras, one LeRobot shard per (task, house), merged into one
dataset per task, and a contact sheet per task.

Used by ``tests/benchmarks/bench_house_tasks.py --record OUT``; writes

- ``OUT/shards/<task>/<house>``: the shard of a task's episodes in one house (successful episodes
  only; failed ones are counted in the shard's sidecar with their reason);
- ``OUT/datasets/<task>``: the task's shards merged (:func:`stages.dataset.merge_shards`); it loads
  with ``LeRobotDataset`` (:func:`stages.dataset.load_dataset`), each frame with its stage
  (``subtask_index``) and each episode with the stages' instructions (``agentworld/subtasks``);
- ``OUT/sheets/<task>.png``: its contact sheet (:func:`stages.dataset.render.render_contact_sheet`).
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Any


@dataclass(frozen=True, kw_only=True)
class HouseRecordConfig:
    """cameras: the engine's recorded cameras (``stages.engine.engine.CAMERAS``); width, height:
    image size [px]; fps: recorded frames per second."""

    cameras: tuple[str, ...] = ("wrist", "head", "third_person")
    width: int = 128
    height: int = 96
    fps: int = 30


def engine_config(record: HouseRecordConfig | None):
    """The one-world engine config of a house task world: cameras when ``record``, else none."""
    from stages.engine import EngineConfig

    if record is None:
        return EngineConfig(worlds=1, layout="per_world", record_images=False, subtasks=True)
    return EngineConfig(worlds=1, layout="per_world", record_images=True, subtasks=True, cameras=record.cameras,
                        width=record.width, height=record.height, fps=record.fps)


def run_world(world: Any, scene_id: str, plan: list[tuple[str, int, Any]], work_dir: Path,
              end: Callable[[Any, Any], None], *, out: Path | None = None,
              record: HouseRecordConfig | None = None) -> None:
    """Run ``plan`` ((task, seed, None) in order) in the task world ``world`` on a one-world engine
    (``work_dir``: its files); ``end(instance, EpisodeResult)`` after each episode. With ``out``
    and ``record``, each task's episodes go to the shard ``out/shards/<task>/<scene_id>``."""
    from stages.dataset import EpisodeInfo, open_shard
    from stages.engine import BatchEngine
    from stages.engine.programs import Listed

    cfg = engine_config(record if out is not None else None)
    eng = BatchEngine(world, panda_root=None, work_dir=work_dir, config=cfg)
    with ExitStack() as stack:
        shards = {}
        if out is not None and record is not None:
            spec = cfg.dataset_spec()
            shards = {t: stack.enter_context(open_shard(Path(out) / "shards" / t, scene_id, spec))
                      for t in dict.fromkeys(t for t, _, _ in plan)}

        def begin(_w: int, inst: Any):
            shard = shards.get(inst.task)
            if shard is None:
                return None
            shard.begin_episode(EpisodeInfo(task=inst.instruction, task_kind=inst.task, scene_id=scene_id,
                                            seed=inst.seed, asset_ids=inst.asset_ids, subtasks=inst.subtasks))
            return shard.add_frame

        def finish(_w: int, inst: Any, res: Any) -> None:
            shard = shards.get(inst.task)
            if shard is not None:
                shard.end_episode(success=res.success, reason=res.reason)
            end(inst, res)

        eng.run(Listed(world, {0: plan}), begin=begin, end=finish)


def merge_and_sheet(out: Path, tasks: list[str]) -> dict[str, dict]:
    """Merge each task's shards under ``out/shards/<task>`` into ``out/datasets/<task>`` and draw
    ``out/sheets/<task>.png``; returns per task the dataset, its episodes and frames and the sheet
    (a task with no successful episode: its ``error``, no dataset)."""
    from stages.dataset import merge_shards
    from stages.dataset.merge import MergeError
    from stages.dataset.render import render_contact_sheet

    out = Path(out)
    res: dict[str, dict] = {}
    for t in tasks:
        shards = out / "shards" / t
        if not shards.is_dir():
            res[t] = {"error": f"{shards}: no shard recorded"}
            continue
        try:
            m = merge_shards(shards, out / "datasets" / t, repo_id=f"agentworld/house_{t}")
        except MergeError as e:
            res[t] = {"error": str(e)}
            continue
        sheet = render_contact_sheet(m.root, out / "sheets" / f"{t}.png", frames=6, max_episodes=4)
        res[t] = {"dataset": str(m.root), "episodes": m.episodes, "frames": m.frames, "sheet": str(sheet),
                  "failures": m.failures}
    return res
