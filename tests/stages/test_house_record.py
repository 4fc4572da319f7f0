"""Recording a house task (issue 16, ``stages.demos.house_record``): one real set_alarm_clock episode
at a generated bedroom's nightstand on the engine with 3 cameras, its shard merged into the task's
dataset, loaded with ``LeRobotDataset`` (the frames' ``subtask_index`` walks the task's stages, the
episode carries their instructions) and its contact sheet written."""

from __future__ import annotations

import pytest

from test_demos_house_bedside import BEDROOM_PACKAGES


@pytest.mark.slow
def test_a_recorded_house_episode_loads_with_lerobot_and_has_a_contact_sheet(tmp_path):
    pytest.importorskip("newton")
    from house_testutil import populate_flat
    from lerobot.datasets.lerobot_dataset import LeRobotDataset
    from PIL import Image

    from stages.dataset.schema import SUBTASK_KEY
    from stages.demos.house_bedside import house_bedside
    from stages.demos.house_record import HouseRecordConfig, merge_and_sheet, run_world

    scene, gen = populate_flat(tmp_path / "out", "bedside", BEDROOM_PACKAGES, "bedroom", count=1, scene="flat_000_p0")
    world = house_bedside(scene, tmp_path / "task", gen, scene_id=scene.name)
    ends = []
    rec = tmp_path / "rec"
    cfg = HouseRecordConfig(width=64, height=48)
    run_world(world, scene.name, [("set_alarm_clock", 1, None)], tmp_path / "engine",
              lambda inst, r: ends.append(r), out=rec, record=cfg)
    assert len(ends) == 1 and ends[0].success, ends[0].reason
    got = merge_and_sheet(rec, ["set_alarm_clock"])["set_alarm_clock"]
    assert got["episodes"] == 1 and got["frames"] == ends[0].frames > 300

    ds = LeRobotDataset("agentworld/house_set_alarm_clock", root=got["dataset"])
    assert len(ds) == ends[0].frames
    stages = [int(ds[i][SUBTASK_KEY]) for i in range(0, len(ds), 10)]
    assert stages[0] == 0 and stages[-1] == 1 and stages == sorted(stages)  # press, then slide
    item = ds[0]
    for cam in cfg.cameras:
        assert tuple(item[f"observation.images.{cam}"].shape) == (3, 48, 64)
    assert len(list(ds.meta.episodes["agentworld/subtasks"][0])) == 2
    assert ds[0]["task"]

    sheet = Image.open(got["sheet"])
    assert sheet.size[0] >= 6 * 64 and sheet.size[1] >= 48
