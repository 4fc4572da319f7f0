"""Datasets in an embodiment's layout (``DatasetSpec.state_layout`` / ``action_layout``): the G1's two
arms, two end-effector poses, base pose, base velocity command and mode, robot type ``unitree_g1``;
frames validated, written as a shard, merged and loaded with LeRobotDataset."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile

import numpy as np
import pytest

os.environ.setdefault("HF_HUB_OFFLINE", "1")
if "HF_DATASETS_CACHE" not in os.environ:
    os.environ["HF_DATASETS_CACHE"] = tempfile.mkdtemp(prefix="hf-datasets-cache-")
    atexit.register(shutil.rmtree, os.environ["HF_DATASETS_CACHE"], True)

from stages.dataset.schema import (  # noqa: E402
    CameraSpec,
    DatasetSpec,
    EpisodeInfo,
    Frame,
    FrameError,
    validate_frame,
)


def _g1_spec(**kw) -> DatasetSpec:
    from stages.embodiment import load_spec
    from stages.embodiment.layout import action_names, state_names

    g1 = load_spec("g1_29dof")
    return DatasetSpec(arm_dof=g1.arm_dof, fps=25, robot_type=g1.robot_type,
                       state_layout=tuple(state_names(g1)), action_layout=tuple(action_names(g1)), **kw)


def _frame(spec: DatasetSpec, k: int, mode: int = 1) -> Frame:
    rng = np.random.default_rng(k)
    state = rng.normal(size=spec.state_dim)
    action = rng.normal(size=spec.action_dim)
    action[-1] = mode
    rgb = {c.name: rng.integers(0, 255, (c.height, c.width, 3), dtype=np.uint8) for c in spec.cameras}
    depth = {c.name: rng.integers(0, 4000, (c.height, c.width), dtype=np.uint16) for c in spec.cameras}
    return Frame.of_vectors(state, action, mode, rgb, depth)


def test_g1_layout_names_dims_and_json_round_trip():
    spec = _g1_spec(cameras=(CameraSpec("head", 24, 32),))
    # 2 arms x 7 joints, 2 end-effector poses, base pose | targets, ee targets, base command, mode
    # (no gripper: the rubber hands)
    assert (spec.state_dim, spec.action_dim) == (14 + 14 + 3, 14 + 14 + 3 + 1)
    names = spec.state_names()
    assert names[:2] == ["left_q0", "left_q1"] and names[-3:] == ["base_x", "base_y", "base_theta"]
    assert spec.action_names()[-4:] == ["base_vx", "base_vy", "base_vtheta", "mode"]
    feats = spec.features()
    assert feats["observation.state"]["shape"] == (31,) and feats["action"]["names"] == spec.action_names()
    assert DatasetSpec.from_json(spec.to_json()) == spec


def test_layout_frames_are_validated_in_one_message():
    spec = _g1_spec(cameras=(CameraSpec("head", 24, 32),))
    validate_frame(spec, _frame(spec, 0))
    bad = Frame.of_vectors(np.zeros(5), np.full(spec.action_dim, np.nan), 1, {}, {})
    with pytest.raises(FrameError) as e:
        validate_frame(spec, bad)
    msg = str(e.value)
    assert "state_vector: shape (5,)" in msg and "action_vector: contains NaN" in msg and "head" in msg
    wrong_mode = _frame(spec, 1, mode=0)
    with pytest.raises(FrameError, match="mode differs"):
        validate_frame(spec, Frame.of_vectors(wrong_mode.state(), wrong_mode.action(), 1, wrong_mode.rgb,
                                              wrong_mode.depth_mm))
    with pytest.raises(ValueError, match="together"):
        DatasetSpec(state_layout=("a",))


def test_layout_dataset_loads_with_lerobot(tmp_path):
    pytest.importorskip("lerobot.datasets")
    from stages.dataset import load_dataset, merge_shards, open_shard

    spec = _g1_spec(cameras=(CameraSpec("head", 24, 32),))
    written = []
    with open_shard(tmp_path / "shards", "g1", spec) as shard:
        shard.begin_episode(EpisodeInfo(task="close the drawer", task_kind="close_drawer", scene_id="k",
                                        seed=1))
        for k in range(6):
            f = _frame(spec, k)
            written.append(f)
            shard.add_frame(f)
        shard.end_episode(success=True)
    res = merge_shards(tmp_path / "shards", tmp_path / "merged")
    ds = load_dataset(res.root)
    assert ds.meta.robot_type == "unitree_g1" and ds.meta.fps == 25 and len(ds) == 6
    assert ds.meta.features["observation.state"]["names"] == spec.state_names()
    for k in (0, 5):
        np.testing.assert_allclose(ds[k]["observation.state"].numpy(), written[k].state(), rtol=1e-6)
        np.testing.assert_allclose(ds[k]["action"].numpy(), written[k].action(), rtol=1e-6)
