"""A multistage task on the batched engine (issue 16): heat_food (mug into the microwave, close
it, press its button) succeeds in the CPU test kitchen, every frame records its stage (0, 1, 2 in
order), and the episode lands in a dataset that ``LeRobotDataset`` loads with its subtasks.

Slow (one 36 s episode, ~1 min of CPU): run with ``-m slow``."""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def room(kitchen_room):
    """The kitchen of world seed 5 from the session's kitchen catalog (tests/stages/conftest.py)."""
    pytest.importorskip("newton")
    return kitchen_room


def test_heat_food_records_its_stages_and_succeeds(room, tmp_path):
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from stages.dataset import EpisodeInfo, EpisodeWriter
    from stages.dataset.schema import SUBTASK_KEY
    from stages.demos.multistage import MULTISTAGE
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    cfg = EngineConfig(worlds=1, layout="per_world", record_images=False, subtasks=True)
    eng = BatchEngine(room, panda_root=None, work_dir=tmp_path / "w", config=cfg)
    results = []
    with EpisodeWriter(tmp_path / "ds", cfg.dataset_spec()) as wr:
        def begin(w, t):
            assert t.subtasks == MULTISTAGE["heat_food"].subtasks
            wr.begin_episode(EpisodeInfo(task=t.instruction, task_kind=t.task, scene_id="k", seed=t.seed,
                                         asset_ids=t.asset_ids, subtasks=t.subtasks))
            return wr.add_frame

        def end(w, t, res):
            results.append(res)
            wr.end_episode(success=res.success, reason=res.reason)

        eng.run(Listed(room, {0: [("heat_food", 1, None)]}), begin=begin, end=end)
    assert results[0].success, results[0].detail
    ds = LeRobotDataset("agentworld/ms", root=tmp_path / "ds")
    idx = np.array([int(ds.hf_dataset[i][SUBTASK_KEY]) for i in range(len(ds))])
    assert len(idx) == results[0].frames > 300
    assert set(idx.tolist()) == {0, 1, 2} and np.all(np.diff(idx) >= 0), np.unique(idx, return_counts=True)
    assert list(ds.meta.episodes["agentworld/subtasks"][0]) == list(MULTISTAGE["heat_food"].subtasks)
