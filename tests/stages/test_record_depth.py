"""RGB-only recording (``record_depth = false`` in a demos step; ``EngineConfig.record_depth``): the
engine's frames carry no depth, the spec's cameras none, the shards (written by the engine's process
and by writer processes), their merge and LeRobotDataset loading have RGB videos and no ``depth.*``
column; the RGB and state are those of the same episodes recorded with depth."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

QUEUES = {0: [("push_object", 5, 0.2), ("press_button", 3, 0.2)]}


@pytest.fixture(scope="module")
def room(kitchen_room):
    pytest.importorskip("newton")
    pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")
    return kitchen_room


def _record(room, work: Path, depth: bool, procs: int) -> tuple[dict, Path]:
    """QUEUES on a per_world engine of 1 world (64x48, 3 cameras) into shard w0 (``procs`` writer
    processes); returns ((task, seed) -> frames seen by a listener, the shards folder)."""
    from stages.dataset import EpisodeInfo
    from stages.dataset.pool import open_shards
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    config = EngineConfig(worlds=1, width=64, height=48, layout="per_world", record_depth=depth)
    eng = BatchEngine(room, panda_root=None, work_dir=work / "e", config=config)
    frames: dict = {}
    with open_shards(work / "shards", ["w0"], config.dataset_spec(), procs) as shards:
        def begin(w, inst):
            shards[w].begin_episode(EpisodeInfo(task=inst.instruction, task_kind=inst.task, scene_id="k",
                                                seed=inst.seed))
            seen = frames.setdefault((inst.task, inst.seed), [])
            if inst.task == "push_object":  # its frames through a plain sink (copies), the other's
                # straight to the shard (with writer processes: the pool's batched hand-over)
                def sink(frame):
                    seen.append(frame)
                    shards[w].add_frame(frame)
                return sink
            return shards[w].add_frame

        def end(w, inst, res):
            shards[w].end_episode(success=True)  # time limits: kept, the files are compared

        eng.run(Listed(room, QUEUES), begin=begin, end=end)
    return frames, work / "shards"


def test_rgb_only_recording_writes_merges_and_loads_without_depth(room, tmp_path):
    from stages.dataset import load_dataset, merge_shards

    with_depth, shards_d = _record(room, tmp_path / "depth", True, 0)
    rgb_only, shards_r = _record(room, tmp_path / "rgb", False, 2)
    a, b = with_depth[("push_object", 5)], rgb_only[("push_object", 5)]
    assert len(a) == len(b) == 7 and set(b[0].rgb) == {"wrist", "head", "third_person"}
    for x, y in zip(a, b, strict=True):  # the same episode, its depth dropped
        assert y.depth_mm == {} and set(x.depth_mm) == set(x.rgb)
        np.testing.assert_array_equal(x.state(), y.state())
        for cam in x.rgb:
            np.testing.assert_array_equal(x.rgb[cam], y.rgb[cam])
    ds_d = load_dataset(merge_shards(shards_d, tmp_path / "ds_depth").root)
    ds_r = load_dataset(merge_shards(shards_r, tmp_path / "ds_rgb").root)
    assert ds_r.num_episodes == ds_d.num_episodes == 2 and ds_r.num_frames == ds_d.num_frames == 14
    info = json.loads((Path(ds_r.root) / "meta" / "info.json").read_text())
    assert not [k for k in info["features"] if k.startswith("depth.")]
    assert sorted(ds_r.meta.camera_keys) == sorted(ds_d.meta.camera_keys) == [
        f"observation.images.{c}" for c in ("head", "third_person", "wrist")]
    item_d, item_r = ds_d[10], ds_r[10]
    assert "depth.head" in item_d and not any(k.startswith("depth.") for k in item_r)
    np.testing.assert_array_equal(item_d["observation.state"].numpy(), item_r["observation.state"].numpy())
    for cam in ds_r.meta.camera_keys:  # the same frames, decoded from videos of the same encoder
        assert item_r[cam].shape == (3, 48, 64)
        np.testing.assert_allclose(item_d[cam].numpy(), item_r[cam].numpy(), atol=1e-6)
    size = {k: sum(p.stat().st_size for p in (tmp_path / f"ds_{k}").rglob("*.parquet")) for k in ("depth", "rgb")}
    assert size["rgb"] < size["depth"] / 2, size  # the depth PNGs were most of the data parquet
