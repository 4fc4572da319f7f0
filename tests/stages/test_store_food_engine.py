"""store_food on the batched engine (issue 16): the fridge opened, the mug from the counter onto a
fridge shelf, the fridge closed, in the CPU test kitchen (world seed 5); every frame records its
stage (0, 1, 2 in order) and the whole task's predicate (the mug on the shelf, the door closed)
holds at the end.

Slow (one ~50 s episode, several minutes of CPU on 2 shared cores): run with ``-m slow``."""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.slow


def test_store_food_records_its_stages_and_succeeds(kitchen_room, tmp_path):
    pytest.importorskip("newton")
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    cfg = EngineConfig(worlds=1, layout="per_world", record_images=False, subtasks=True)
    eng = BatchEngine(kitchen_room, panda_root=None, work_dir=tmp_path / "w", config=cfg)
    results, stages = [], []

    def begin(w, t):
        return lambda frame: stages.append(int(frame.subtask_index))

    eng.run(Listed(kitchen_room, {0: [("store_food", 1, None)]}), begin=begin,
            end=lambda w, t, res: results.append(res))
    assert results[0].success, results[0].detail
    idx = np.array(stages)
    assert set(idx.tolist()) == {0, 1, 2} and np.all(np.diff(idx) >= 0), np.unique(idx, return_counts=True)
