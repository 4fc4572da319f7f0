"""ShardPool (stages.dataset.pool): shards written by worker processes over shared memory are the
same files as shards written inline; errors name the shard; a failure publishes nothing."""

from __future__ import annotations

import hashlib
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from stages.dataset import (  # noqa: E402
    CameraSpec, DatasetSpec, FrameError, decode_depth, list_shards, load_dataset, open_shard)
from stages.dataset.pool import PoolConfig, ShardPool, ShardPoolError  # noqa: E402
from stages.dataset.synthetic import synthetic_episode_info, synthetic_frame  # noqa: E402

SPEC = DatasetSpec(cameras=(CameraSpec("wrist", 48, 64), CameraSpec("head", 48, 64, depth=False),
                            CameraSpec("third_person", 48, 64, rgb=False)))
PLAN = {0: [(0, 9, True), (1, 7, False), (2, 11, True)], 1: [(0, 8, True)], 2: [(0, 5, False), (1, 6, True)]}
"""shard -> [(episode, frames, success)]"""


def _files(root: Path) -> dict[str, str]:
    """relative path -> sha256 of every file of a shard but the sidecar (it holds timings)."""
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file() and p.name != "agentworld.json"}


def _write_inline(d: Path) -> None:
    for s, eps in PLAN.items():
        with open_shard(d, f"s{s}", SPEC) as shard:
            for e, n, ok in eps:
                shard.begin_episode(synthetic_episode_info(s, e))
                for i in range(n):
                    shard.add_frame(synthetic_frame(SPEC, s, e, i))
                shard.end_episode(success=ok, reason="" if ok else "dropped")


def _write_pool(d: Path, config: PoolConfig) -> dict:
    with ShardPool(d, [f"s{s}" for s in PLAN], SPEC, config) as pool:
        # episodes of the shards interleaved frame by frame, as an engine delivers them
        cursors = {s: 0 for s in PLAN}
        for e_idx in range(max(len(v) for v in PLAN.values())):
            live = {s: eps[e_idx] for s, eps in PLAN.items() if e_idx < len(eps)}
            for s, (e, n, ok) in live.items():
                pool.begin_episode(s, synthetic_episode_info(s, e))
            for i in range(max(n for _, n, _ in live.values())):
                for s, (e, n, ok) in live.items():
                    if i < n:
                        pool.sink(s)(synthetic_frame(SPEC, s, e, i))
                        cursors[s] += 1
            for s, (e, n, ok) in live.items():
                pool.end_episode(s, success=ok, reason="" if ok else "dropped")
        return pool


def test_pool_writes_the_same_files_as_inline_shards(tmp_path):
    _write_inline(tmp_path / "inline")
    pool = _write_pool(tmp_path / "pool", PoolConfig(workers=2, slots=2))  # 2 slots: add_frame waits
    inline, pooled = list_shards(tmp_path / "inline"), list_shards(tmp_path / "pool")
    assert [s.shard_id for s in pooled] == ["s0", "s1", "s2"]
    for a, b in zip(inline, pooled):
        assert (a.episodes, a.frames, a.failures) == (b.episodes, b.frames, b.failures)
        fa, fb = _files(a.path), _files(b.path)
        assert fa == fb and any(k.endswith(".mp4") for k in fa) and any(k.endswith(".parquet") for k in fa)
    assert pooled[0].episodes == 2 and pooled[0].failures == {"dropped": 1}
    assert not [p for p in (tmp_path / "pool").iterdir() if p.name.startswith(".")]  # no temporaries
    assert pool.wait_s >= 0.0
    ds = load_dataset(pooled[2].path)  # lerobot reads it; depth exact
    item = ds[0]
    assert item["observation.state"].shape[0] == SPEC.state_dim
    depth_key = SPEC.depth_keys()["wrist"]
    want = synthetic_frame(SPEC, 2, 1, 0).depth_mm["wrist"].astype(np.float32)
    np.testing.assert_array_equal(decode_depth(item[depth_key]).astype(np.float32), want)


def test_a_bad_frame_names_the_shard_and_a_worker_failure_publishes_nothing(tmp_path):
    d = tmp_path / "shards"
    with open_shard(d, "s1", SPEC) as shard:  # s1 is complete already: its worker fails to open it
        shard.begin_episode(synthetic_episode_info(1, 0))
        shard.add_frame(synthetic_frame(SPEC, 1, 0, 0))
        shard.end_episode(success=True)
    before = _files(d / "s1")
    with pytest.raises(FrameError, match=r"s0 frame 0"):
        with ShardPool(d, ["s0", "s1"], SPEC, PoolConfig(workers=2)) as pool:
            pool.begin_episode(0, synthetic_episode_info(0, 0))
            bad = synthetic_frame(SPEC, 0, 0, 0)
            bad.rgb["wrist"] = bad.rgb["wrist"][:10]
            pool.add_frame(0, bad)
    with pytest.raises(ShardPoolError, match=r"writer process 1, shard s1: ShardExistsError"):
        with ShardPool(d, ["s0", "s1"], SPEC, PoolConfig(workers=2)) as pool:
            for i in range(3):
                pool.begin_episode(1, synthetic_episode_info(1, i))
                pool.end_episode(1, success=False, reason="x")
            pool.close()
    assert [s.shard_id for s in list_shards(d)] == ["s1"] and _files(d / "s1") == before
    assert not [p for p in d.iterdir() if p.name.startswith(".")]  # s0's temporary folder removed


def test_inline_encoding_writes_the_same_files(tmp_path):
    """``inline_encoding`` (RGB and depth encoded in add_frame's thread, for a pool's workers) gives
    the same bytes as the encoder and depth threads; a dropped episode leaves nothing behind."""
    def write(d: Path, inline: bool) -> Path:
        with open_shard(d, "s0", SPEC, inline_encoding=inline) as shard:
            for e, n, ok in PLAN[0]:
                shard.begin_episode(synthetic_episode_info(0, e))
                for i in range(n):
                    shard.add_frame(synthetic_frame(SPEC, 0, e, i))
                shard.end_episode(success=ok, reason="" if ok else "dropped")
        return d / "s0"

    threaded, inline = _files(write(tmp_path / "threads", False)), _files(write(tmp_path / "inline", True))
    assert threaded == inline
    assert sum(k.endswith(".mp4") for k in inline) == 4  # 2 written episodes x 2 RGB cameras
    with pytest.raises(ValueError, match="inline_encoding needs the direct backend"):
        open_shard(tmp_path / "x", "s0", SPEC, backend="lerobot", inline_encoding=True)
