"""Multistage episodes in the dataset: a per-frame ``subtask_index`` beside the task text and the
stages' language in the episode column ``agentworld/subtasks``, written by both backends and
loaded with ``LeRobotDataset`` (issue 16)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from stages.dataset import DatasetSpec, EpisodeInfo, EpisodeWriter
from stages.dataset.schema import SUBTASK_KEY, FrameError, frame_problems
from stages.dataset.synthetic import synthetic_frame

STAGES = ("put the mug in the microwave", "close the microwave door", "press the start button")


@pytest.mark.parametrize("backend", ["direct", "lerobot"])
def test_subtask_index_and_texts_round_trip_through_lerobot(tmp_path, backend):
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    spec = DatasetSpec(cameras=(), subtasks=True)
    assert spec.features()[SUBTASK_KEY] == {"dtype": "int64", "shape": (1,), "names": None}
    assert DatasetSpec.from_json(spec.to_json()) == spec
    root = tmp_path / "ds"
    stages_of = [(0, 0, 1, 1, 1, 2), (0, 1, 2, 2)]
    with EpisodeWriter(root, spec, backend=backend) as w:
        for e, stages in enumerate(stages_of):
            w.begin_episode(EpisodeInfo(task="heat the food in the microwave", task_kind="multistage",
                                        scene_id="kitchen_000", seed=e, subtasks=STAGES))
            for i, k in enumerate(stages):
                w.add_frame(replace(synthetic_frame(spec, 0, e, i), subtask_index=k))
            w.end_episode(success=True)
    ds = LeRobotDataset("agentworld/test", root=root)
    got = [int(ds[i][SUBTASK_KEY]) for i in range(len(ds))]
    assert got == [k for stages in stages_of for k in stages]
    assert ds[0]["task"] == "heat the food in the microwave"
    eps = ds.meta.episodes
    assert [list(x) for x in eps["agentworld/subtasks"]] == [list(STAGES)] * 2


def test_a_negative_subtask_index_is_a_frame_problem():
    spec = DatasetSpec(cameras=(), subtasks=True)
    bad = replace(synthetic_frame(spec, 0, 0, 0), subtask_index=-1)
    assert any("subtask_index" in p for p in frame_problems(spec, bad))
    assert not frame_problems(DatasetSpec(cameras=()), bad)  # no subtasks in the spec: not recorded
    assert EpisodeInfo(task="t", task_kind="k", scene_id="s", seed=0, subtasks=("a", " ")).problems()
    with pytest.raises(FrameError):
        from stages.dataset.schema import validate_frame

        validate_frame(spec, bad)


@pytest.mark.parametrize("backend", ["direct", "lerobot"])
def test_each_episode_lists_the_stages_its_frames_reach(tmp_path, backend):
    from stages.dataset import load_dataset, read_episode_columns

    spec = DatasetSpec(cameras=(), subtasks=True)
    root = tmp_path / "ds"
    stages_of = [(0, 0, 1, 1, 2), (0, 0, 1), (1, 1, 2)]  # all three; stopped in stage 2; entered at stage 2
    with EpisodeWriter(root, spec, backend=backend) as w:
        for e, stages in enumerate(stages_of):
            w.begin_episode(EpisodeInfo(task="heat the food", task_kind="heat_food", scene_id="flat_000",
                                        seed=e, subtasks=STAGES))
            for i, k in enumerate(stages):
                w.add_frame(replace(synthetic_frame(spec, 0, e, i), subtask_index=k))
            w.end_episode(success=True)
    rows = read_episode_columns(root)
    assert [list(r["subtasks_reached"]) for r in rows] == [[0, 1, 2], [0, 1], [1, 2]]
    eps = load_dataset(root).meta.episodes
    assert [list(x) for x in eps["agentworld/subtasks_reached"]] == [[0, 1, 2], [0, 1], [1, 2]]
    # a spec without subtasks has no such column
    plain = tmp_path / "plain"
    with EpisodeWriter(plain, DatasetSpec(cameras=()), backend=backend) as w:
        w.begin_episode(EpisodeInfo(task="t", task_kind="k", scene_id="s", seed=0))
        w.add_frame(synthetic_frame(DatasetSpec(cameras=()), 0, 0, 0))
        w.end_episode(success=True)
    assert "subtasks_reached" not in read_episode_columns(plain)[0]
