"""ShardPool.add_frames (issue 12): a frame step's frames handed over as columns and stacked images
are the same files as frames handed over one by one; a bad frame in a batch is still rejected with a
one-line error naming its shard and frame; the batch screen passes no frame the per-frame check rejects."""

from __future__ import annotations

import dataclasses
import hashlib
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from stages.dataset import CameraSpec, DatasetSpec, FrameError, list_shards  # noqa: E402
from stages.dataset.columns import NUMERIC, FrameColumns, suspect_rows  # noqa: E402
from stages.dataset.pool import PoolConfig, ShardPool  # noqa: E402
from stages.dataset.schema import frame_problems  # noqa: E402
from stages.dataset.synthetic import synthetic_episode_info, synthetic_frame  # noqa: E402

FULL = DatasetSpec(cameras=tuple(CameraSpec(c, 48, 64) for c in ("wrist", "head", "third_person")))
MIXED = DatasetSpec(cameras=(CameraSpec("wrist", 48, 64), CameraSpec("head", 48, 64, depth=False),
                             CameraSpec("third_person", 48, 64, rgb=False)))
PLAN = {0: [(0, 6, True), (1, 4, False)], 1: [(0, 7, True)], 2: [(0, 3, False), (1, 5, True)]}
"""shard -> [(episode, frames, success)]"""


def _files(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file() and p.name != "agentworld.json"}


def _batch(spec: DatasetSpec, frames: list, rows: list[int]):
    """Columns of ``frames`` and stacked images in which frame j sits at row ``rows[j]``."""
    fields = {}
    for name in NUMERIC:
        vals = [getattr(f, name) for f in frames]
        if vals[0] is not None:
            fields[name] = np.array(vals)
    b = max(rows) + 1
    images = {}
    for c in spec.cameras:
        rgb = np.zeros((b, c.height, c.width, 3), np.uint8) if c.rgb else None
        depth = np.zeros((b, c.height, c.width), np.uint16) if c.depth else None
        for f, r in zip(frames, rows):
            if c.rgb:
                rgb[r] = f.rgb[c.name]
            if c.depth:
                depth[r] = f.depth_mm[c.name]
        images[c.name] = (rgb, depth)
    return FrameColumns(fields), images


def _write(d: Path, spec: DatasetSpec, batched: bool) -> None:
    """Every shard's episodes, the shards' frames interleaved step by step as an engine delivers them."""
    with ShardPool(d, [f"s{s}" for s in PLAN], spec, PoolConfig(workers=2, slots=3)) as pool:
        for e_idx in range(max(len(v) for v in PLAN.values())):
            live = {s: eps[e_idx] for s, eps in PLAN.items() if e_idx < len(eps)}
            for s, (e, n, ok) in live.items():
                pool.begin_episode(s, synthetic_episode_info(s, e))
            for i in range(max(n for _, n, _ in live.values())):
                shards = [s for s, (e, n, ok) in live.items() if i < n]
                frames = [synthetic_frame(spec, s, live[s][0], i) for s in shards]
                if batched:  # rows in another order than the shards: each frame takes its own
                    cols, images = _batch(spec, frames, rows=list(range(len(frames)))[::-1])
                    pool.add_frames(shards, cols, images, list(range(len(frames)))[::-1])
                else:
                    for s, f in zip(shards, frames):
                        pool.add_frame(s, f)
            for s, (e, n, ok) in live.items():
                pool.end_episode(s, success=ok, reason="" if ok else "dropped")


@pytest.mark.parametrize("spec", [FULL, MIXED], ids=["rgb_depth", "mixed_streams"])
def test_batched_hand_over_writes_the_same_files_as_frame_by_frame(tmp_path, spec):
    _write(tmp_path / "one", spec, batched=False)
    _write(tmp_path / "batch", spec, batched=True)
    one, batch = _files(tmp_path / "one"), _files(tmp_path / "batch")
    assert one == batch
    assert sum(k.endswith(".mp4") for k in one) == 3 * sum(c.rgb for c in spec.cameras)


def test_a_bad_frame_in_a_batch_is_rejected_naming_its_shard_and_frame(tmp_path):
    frames = [synthetic_frame(FULL, s, 0, 0) for s in range(3)]
    with pytest.raises(FrameError, match=r"s1 frame 1: 1 problem\(s\): arm_joint_pos: contains NaN"):
        with ShardPool(tmp_path, ["s0", "s1", "s2"], FULL, PoolConfig(workers=1)) as pool:
            for s in range(3):
                pool.begin_episode(s, synthetic_episode_info(s, 0))
            cols, images = _batch(FULL, frames, [0, 1, 2])
            pool.add_frames([0, 1, 2], cols, images, [0, 1, 2])  # frame 0 of every shard: valid
            cols.fields["arm_joint_pos"][1, 3] = np.nan
            pool.add_frames([0, 1, 2], cols, images, [0, 1, 2])
    assert list_shards(tmp_path) == []  # the pool aborted: nothing published
    with pytest.raises(FrameError, match=r"s0 frame 0: .*rgb\['head'\]: expected uint8 \(48, 64, 3\)"):
        with ShardPool(tmp_path, ["s0"], FULL, PoolConfig(workers=1)) as pool:
            pool.begin_episode(0, synthetic_episode_info(0, 0))
            cols, images = _batch(FULL, frames[:1], [0])
            images["head"] = (images["head"][0].astype(np.uint16), images["head"][1])
            pool.add_frames([0], cols, images, [0])


def test_the_screen_passes_no_frame_the_per_frame_check_rejects():
    """Random breakage of valid columns: every row the screen passes has no problem; valid columns
    pass whole (the screen is what saves the per-frame check)."""
    rng = np.random.default_rng(0)
    for spec in (FULL, DatasetSpec(cameras=FULL.cameras, subtasks=True, hand_joints=("j0", "j1")),
                 DatasetSpec(arm_dof=14, cameras=FULL.cameras, arms=("left", "right"))):
        frames = [synthetic_frame(spec, s, 0, i) for s in range(4) for i in range(4)]
        if spec.arms:
            frames = [dataclasses.replace(f, ee_pose=np.tile(f.ee_pose, 2), ee_target=np.tile(f.ee_target, 2),
                                          gripper=np.array([f.gripper, 0.5])) for f in frames]
        cols, images = _batch(spec, frames, list(range(len(frames))))
        assert not suspect_rows(spec, cols, images).any()
        flagged = 0
        for trial in range(60):
            c = FrameColumns({n: v.astype(np.float64) if n not in ("mode", "subtask_index") else v.copy()
                              for n, v in cols.fields.items()})
            for _ in range(3):
                name = rng.choice([n for n, v in c.fields.items() if v.size])
                v = c.fields[name]
                j = rng.integers(len(frames))
                flat = v[j].reshape(-1) if v.ndim > 1 else v[j:j + 1]
                flat[rng.integers(flat.size)] = rng.choice([np.nan, np.inf, -1.0, 2.0, 1.0005, 7.0]) \
                    if v.dtype.kind == "f" else rng.choice([-1, 2, 3])
            sus = suspect_rows(spec, c, images)
            for j in range(len(frames)):
                f = c.frame(j, {k: im[0][j] for k, im in images.items()}, {k: im[1][j] for k, im in images.items()})
                # exact on these values: a passed row has no problem, a suspect one has one
                assert bool(frame_problems(spec, f)) == bool(sus[j]), (trial, j, frame_problems(spec, f))
            flagged += int(sus.sum())
        assert flagged > 30  # the breakage was seen (most of it is invalid)


def test_the_engine_pools_ring_holds_two_frame_steps_of_a_writers_shards(tmp_path):
    """A ring smaller than one frame step's frames per writer made the engine wait mid-step for the
    writers (bench_handoff --gap: 4 slots for 16 shards waited, 32 did not): open_shards sizes it."""
    from stages.dataset.pool import open_shards, ring_slots

    slot = 3 * (240 * 320 * 3 + 240 * 320 * 2)  # 3 cameras at 240x320, RGB + depth [bytes]
    assert ring_slots(256, 4, slot) == 128  # 64 shards per writer: two steps
    assert ring_slots(8, 2, slot) == 32  # at least 32
    assert ring_slots(1024, 1, 4 * slot) == (1 << 30) // (4 * slot)  # 480x640: 1 GiB of shared memory
    with open_shards(tmp_path, [f"w{i:02d}" for i in range(40)], FULL, writer_procs=1) as shards:
        assert shards[0].pool.config.slots == 80


def test_the_engines_hand_over_batches_pool_sinks_and_gives_other_sinks_frames(tmp_path):
    """stages.engine.capture.hand_over: a pool's sinks get their frames through add_frames (the
    pool counts them), any other sink one Frame per call, with copies unless it takes views."""
    from stages.engine.capture import collected, hand_over

    frames = [synthetic_frame(FULL, s, 0, 3) for s in range(3)]
    cols, images = _batch(FULL, frames, [2, 0, 1])
    got: list = []
    with ShardPool(tmp_path, ["s0", "s1"], FULL, PoolConfig(workers=1)) as pool:
        for s in range(2):
            pool.begin_episode(s, synthetic_episode_info(s, 0))
        c = collected([pool.sink(0), got.append, pool.sink(1)], [7, 7, 7], [2, 0, 1], cols.fields)
        hand_over(c, {7: images})
        assert pool._frames == [1, 1]
        for s in range(2):
            pool.end_episode(s, success=True)
    (f,) = got
    assert np.array_equal(f.arm_joint_pos, frames[1].arm_joint_pos) and f.gripper == frames[1].gripper
    assert isinstance(f.mode, int) and f.mode == frames[1].mode
    assert np.array_equal(f.rgb["head"], frames[1].rgb["head"]) and not np.shares_memory(f.rgb["head"], images["head"][0])
