"""Shards written in parallel processes, merged with lerobot's aggregation, loaded with LeRobotDataset.

Frames are synthetic and deterministic (stages.dataset.synthetic): the test recomputes what each
process wrote and compares it with what LeRobotDataset / a torch DataLoader return.
"""

from __future__ import annotations

import atexit
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

os.environ.setdefault("HF_HUB_OFFLINE", "1")
if "HF_DATASETS_CACHE" not in os.environ:  # LeRobotDataset caches arrow copies of the parquet files there
    os.environ["HF_DATASETS_CACHE"] = tempfile.mkdtemp(prefix="hf-datasets-cache-")
    atexit.register(shutil.rmtree, os.environ["HF_DATASETS_CACHE"], True)

from stages.dataset.depth import decode_depth  # noqa: E402
from stages.dataset.merge import MergeError, load_dataset, merge_shards, read_episode_columns  # noqa: E402
from stages.dataset.schema import CameraSpec, DatasetSpec, FrameError  # noqa: E402
from stages.dataset.shards import ShardExistsError, clean_stale_temps, list_shards, open_shard  # noqa: E402
from stages.dataset.synthetic import (  # noqa: E402
    is_failed,
    synthetic_episode_info,
    synthetic_frame,
    write_synthetic_shard,
)

pytest.importorskip("lerobot.datasets")
REPO = Path(__file__).resolve().parents[2]
SPEC = DatasetSpec(
    cameras=(CameraSpec("wrist", 48, 64), CameraSpec("head", 48, 64), CameraSpec("third_person", 48, 64,
                                                                                     depth=False)),
)  # fmt: skip
N_SHARDS, EPISODES, FRAMES, FAIL_EVERY = 3, 3, 12, 3  # episode 2 of each shard fails


def _writer_cmd(shards_dir: Path, shard_id: str, index: int, spec: DatasetSpec, **kw) -> list[str]:
    cmd = [sys.executable, "-m", "stages.dataset.synthetic", str(shards_dir), shard_id, "--shard-index",
           str(index), "--spec-json", json.dumps(spec.to_json())]  # fmt: skip
    for k, v in kw.items():
        cmd += [f"--{k.replace('_', '-')}", str(v)]
    return cmd


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", "")}


@pytest.fixture(scope="module")
def merged(tmp_path_factory) -> tuple[Path, object]:
    """3 shards written by 3 concurrent processes (worker-1 with lerobot's own writer, the others with
    the direct backend: the merge and every check below also prove the two write the same format)."""
    base = tmp_path_factory.mktemp("ds")
    procs = []
    for k in range(N_SHARDS):
        cmd = _writer_cmd(base / "shards", f"worker-{k}", k, SPEC, episodes=EPISODES, frames=FRAMES,
                          fail_every=FAIL_EVERY, backend="lerobot" if k == 1 else "direct")  # fmt: skip
        procs.append(subprocess.Popen(cmd, cwd=REPO, env=_env(), stderr=subprocess.PIPE, text=True))
    for p in procs:
        _, err = p.communicate(timeout=240)
        assert p.returncode == 0, err[-3000:]
    result = merge_shards(base / "shards", base / "merged")
    return base, result


def _psnr(decoded: np.ndarray, original: np.ndarray) -> float:
    """Peak signal-to-noise ratio [dB] of a decoded frame (float, 0..255) against the uint8 original."""
    mse = float(np.mean((decoded.astype(np.float64) - original.astype(np.float64)) ** 2))
    return 10.0 * np.log10(255.0**2 / max(mse, 1e-12))


def _written() -> list[tuple[int, int]]:
    """(shard, episode) of every written episode, in merged order."""
    return [(s, e) for s in range(N_SHARDS) for e in range(EPISODES) if not is_failed(e, FAIL_EVERY)]


def test_shards_are_complete_and_count_failures(merged):
    base, result = merged
    shards = list_shards(base / "shards")
    assert [s.shard_id for s in shards] == ["worker-0", "worker-1", "worker-2"]
    assert all(s.episodes == 2 and s.frames == 2 * FRAMES for s in shards)
    assert all(s.failures == {"grasp slipped": 1} for s in shards)
    assert not list((base / "shards").glob(".tmp-*"))
    assert result.episodes == 6 and result.frames == 6 * FRAMES
    assert result.failures == {"grasp slipped": 3}
    assert [json.loads((s.path / "meta" / "agentworld.json").read_text())["backend"] for s in shards] == [
        "direct", "lerobot", "direct"]  # fmt: skip
    side = json.loads((base / "merged" / "meta" / "agentworld.json").read_text())
    assert side["episodes_failed"] == 3 and tuple(s["id"] for s in side["shards"]) == result.shards


def test_merged_frames_match_what_was_written(merged):
    import torch

    base, _ = merged
    ds = load_dataset(base / "merged")
    assert len(ds) == 6 * FRAMES and ds.num_episodes == 6 and ds.fps == 30
    written = _written()
    loader = torch.utils.data.DataLoader(ds, batch_size=FRAMES, shuffle=False, num_workers=2)
    rgb_psnr = []
    seen = 0
    for batch in loader:
        for j in range(len(batch["index"])):
            ep, i = int(batch["episode_index"][j]), int(batch["frame_index"][j])
            shard, episode = written[ep]
            want = synthetic_frame(SPEC, shard, episode, i)
            assert float(batch["timestamp"][j]) == pytest.approx(i / 30, abs=1e-6)
            np.testing.assert_array_equal(batch["observation.state"][j].numpy(), want.state())
            np.testing.assert_array_equal(batch["action"][j].numpy(), want.action())
            assert batch["task"][j] == synthetic_episode_info(shard, episode).task
            for cam in ("wrist", "head"):  # depth: exact uint16 (H, W) millimetres, decoded from its PNG text
                depth = decode_depth(batch[f"depth.{cam}"][j])
                assert depth.shape == (48, 64) and depth.dtype == np.uint16
                np.testing.assert_array_equal(depth, want.depth_mm[cam])
            for cam in ("wrist", "head", "third_person"):  # rgb: lossy codec, float32 (3, H, W) in [0, 1]
                got = batch[f"observation.images.{cam}"][j].permute(1, 2, 0).numpy() * 255.0
                rgb_psnr.append(_psnr(got, want.rgb[cam]))
            seen += 1
    assert seen == 6 * FRAMES
    # h264 ultrafast, crf 23 on 48x64 frames: lossy but close (a neighbouring frame scores ~20 dB)
    assert min(rgb_psnr) > 28.0 and np.mean(rgb_psnr) > 31.0, (min(rgb_psnr), np.mean(rgb_psnr))


def test_merged_stats_match_written_values(merged):
    base, _ = merged
    ds = load_dataset(base / "merged")
    frames = [synthetic_frame(SPEC, s, e, i) for s, e in _written() for i in range(FRAMES)]
    for key, values in (("observation.state", np.stack([f.state() for f in frames])),
                        ("action", np.stack([f.action() for f in frames]))):  # fmt: skip
        st = ds.meta.stats[key]
        np.testing.assert_allclose(st["min"], values.min(0), rtol=1e-6)
        np.testing.assert_allclose(st["max"], values.max(0), rtol=1e-6)
        np.testing.assert_allclose(st["mean"], values.mean(0, dtype=np.float64), rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(st["std"], values.std(0, dtype=np.float64), rtol=1e-4, atol=1e-3)
        assert int(np.asarray(st["count"]).item()) == len(frames)
    depth = ds.meta.stats["depth.wrist"]
    assert float(np.squeeze(depth["min"])) == 0.0 and float(np.squeeze(depth["max"])) == 65535.0
    rgb = np.stack([f.rgb["head"] for f in frames]).astype(np.float64) / 255.0
    np.testing.assert_allclose(np.squeeze(ds.meta.stats["observation.images.head"]["mean"]),
                               rgb.mean((0, 1, 2)), atol=0.01)  # fmt: skip


def test_episode_metadata_columns_survive_merge(merged):
    base, _ = merged
    rows = read_episode_columns(base / "merged")
    assert [(r["scene_id"], r["seed"]) for r in rows] == [
        (f"scene-{s:03d}", 1000 * s + e) for s, e in _written()]  # fmt: skip
    assert all(r["success"] and r["task_kind"] == "pick_place" and r["length"] == FRAMES for r in rows)
    assert rows[1]["asset_ids"] == ["obj_1", "bowl_01"]
    ds = load_dataset(base / "merged", episode_filter=lambda ep: ep["agentworld/scene_id"] == "scene-001")
    assert ds.num_episodes == 2 and len(ds) == 2 * FRAMES


def test_killed_writer_leaves_no_shard_and_next_start_cleans_it(tmp_path):
    shards = tmp_path / "shards"
    spec = DatasetSpec(cameras=(CameraSpec("wrist", 32, 48),))
    proc = subprocess.Popen(_writer_cmd(shards, "w7", 7, spec, episodes=2, frames=10, pause_after=5),
                            cwd=REPO, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline()  # first episode written, second one in progress
        assert line.strip() == "PAUSED", proc.stderr.read()[-3000:]
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    assert not (shards / "w7").exists()
    temps = list(shards.glob(".tmp-w7-*"))
    assert len(temps) == 1 and (temps[0] / "data").is_dir()  # the first episode's files were there
    assert list_shards(shards) == []
    write_synthetic_shard(shards, "w7", spec, shard_index=7, episodes=1, frames=4)
    assert not list(shards.glob(".tmp-*"))
    assert [(s.shard_id, s.episodes) for s in list_shards(shards)] == [("w7", 1)]
    assert len(load_dataset(shards / "w7")) == 4


@pytest.mark.parametrize("backend", ["direct", "lerobot"])
def test_rollover_to_several_files_loads_every_frame(tmp_path, backend):
    spec = DatasetSpec(cameras=(CameraSpec("wrist", 48, 64),), data_files_size_mb=0.01,
                       video_files_size_mb=0.001)  # fmt: skip
    for k in range(2):
        write_synthetic_shard(tmp_path / "shards", f"s{k}", spec, shard_index=k, episodes=3, frames=8,
                              backend=backend)  # fmt: skip
    shard0 = tmp_path / "shards" / "s0"
    assert len(list((shard0 / "data").glob("*/*.parquet"))) >= 2
    assert len(list((shard0 / "videos").glob("*/*/*.mp4"))) >= 2
    merge_shards(tmp_path / "shards", tmp_path / "merged")
    assert len(list((tmp_path / "merged" / "data").glob("*/*.parquet"))) >= 3
    ds = load_dataset(tmp_path / "merged")
    assert len(ds) == 6 * 8
    for idx in range(0, len(ds), 5):
        item = ds[idx]
        ep, i = int(item["episode_index"]), int(item["frame_index"])
        want = synthetic_frame(spec, ep // 3, ep % 3, i)
        np.testing.assert_array_equal(item["observation.state"].numpy(), want.state())
        depth = decode_depth(item["depth.wrist"])
        np.testing.assert_array_equal(depth, want.depth_mm["wrist"])
        got = item["observation.images.wrist"].permute(1, 2, 0).numpy() * 255.0
        assert _psnr(got, want.rgb["wrist"]) > 28.0


def test_writer_lifecycle_is_guarded(tmp_path):
    spec = DatasetSpec(cameras=(CameraSpec("wrist", 16, 16),))
    shard = open_shard(tmp_path, "a", spec)
    with pytest.raises(RuntimeError, match="add_frame.*needs writer state in_episode.*new"):
        shard.add_frame(synthetic_frame(spec, 0, 0, 0))
    with shard:
        with pytest.raises(RuntimeError, match="end_episode.*needs writer state in_episode, it is open"):
            shard.end_episode(True)
        shard.begin_episode(synthetic_episode_info(0, 0))
        with pytest.raises(FrameError, match="problem"):
            shard.add_frame(synthetic_frame(DatasetSpec(cameras=(CameraSpec("wrist", 8, 8),)), 0, 0, 0))
        with pytest.raises(RuntimeError, match="close.*inside an episode"):
            shard.close()
        assert shard.end_episode(True).reason == "no frames"  # nothing added: counted, not written
    assert list_shards(tmp_path)[0].failures == {"no frames": 1}
    with pytest.raises(ShardExistsError):
        open_shard(tmp_path, "a", spec).open()
    with pytest.raises(MergeError, match="no successful episode"):
        merge_shards(tmp_path, tmp_path / "out")


def test_exception_in_recording_loop_deletes_the_temporary_shard(tmp_path):
    spec = DatasetSpec(cameras=(CameraSpec("wrist", 16, 16),))
    with pytest.raises(KeyError):
        with open_shard(tmp_path, "b", spec) as shard:
            shard.begin_episode(synthetic_episode_info(0, 0))
            shard.add_frame(synthetic_frame(spec, 0, 0, 0))
            raise KeyError("simulation crashed")
    assert list(tmp_path.iterdir()) == []
    assert clean_stale_temps(tmp_path) == []


def test_merge_refuses_shards_with_different_specs(tmp_path):
    for k, h in enumerate((16, 24)):
        write_synthetic_shard(tmp_path, f"s{k}", DatasetSpec(cameras=(CameraSpec("wrist", h, 16),)),
                              shard_index=k, episodes=1, frames=2)  # fmt: skip
    with pytest.raises(MergeError, match=r"\['s1'\] have a different spec than s0"):
        merge_shards(tmp_path, tmp_path / "merged")
    assert not (tmp_path / "merged").exists() and not list(tmp_path.glob(".tmp-*"))


def test_merge_removes_the_temporary_of_a_killed_merge_but_not_a_live_one(tmp_path):
    """A merge killed before its rename leaves ``.tmp-<out>-<pid>-<hex>``; the next merge into the same
    folder deletes it (its process is gone) and leaves a live process's temporary alone."""
    write_synthetic_shard(tmp_path / "shards", "s0", DatasetSpec(cameras=(CameraSpec("wrist", 16, 16),)),
                          shard_index=0, episodes=1, frames=2)  # fmt: skip
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait(timeout=30)
    dead = tmp_path / f".tmp-merged-{gone.pid}-0123abcd"
    live = tmp_path / f".tmp-merged-{os.getppid()}-4567cdef"
    for d in (dead, live):
        (d / "data").mkdir(parents=True)
    merge_shards(tmp_path / "shards", tmp_path / "merged")
    assert not dead.exists() and live.is_dir() and (tmp_path / "merged").is_dir()


def test_render_contact_sheet_command(merged, tmp_path):
    from PIL import Image

    from stages.dataset.render import THUMB_W, cli

    base, _ = merged
    out = tmp_path / "sheet.png"
    assert cli([str(base / "merged"), "--out", str(out), "--episodes", "0,5", "--frames", "4"]) == 0
    sheet = np.asarray(Image.open(out).convert("RGB"))
    streams = 5  # 3 rgb + 2 depth rows per episode
    thumb_h = round(48 * THUMB_W / 64)
    assert sheet.shape[0] == 2 * (streams * (thumb_h + 2) + 18) and sheet.shape[1] > 4 * THUMB_W
    # the first thumbnail of episode 0's wrist row is that frame, decoded and scaled
    first = sheet[18 : 18 + thumb_h, 150 : 150 + THUMB_W].astype(np.float64)
    want = np.asarray(Image.fromarray(synthetic_frame(SPEC, 0, 0, 0).rgb["wrist"]).resize((THUMB_W, thumb_h)))
    assert np.abs(first - want).mean() < 12.0
    assert cli([str(base / "merged"), "--out", str(out), "--episodes", "9"]) == 2


def test_merge_datasets_of_runner_items(tmp_path, capsys):
    """The runner-item pattern: each item writes <item>/dataset with EpisodeWriter (the runner renames the
    item folder atomically); merge_datasets merges them in the given order, quietly (lerobot's
    progress bars do not reach the console)."""
    from stages.dataset import EpisodeWriter, merge_datasets

    spec = DatasetSpec(cameras=(CameraSpec("wrist", 16, 24),))
    roots = []
    for k in (1, 0):
        root = tmp_path / f"item-{k}" / "dataset"
        with EpisodeWriter(root, spec) as w:
            for e in range(k + 1):
                w.begin_episode(synthetic_episode_info(k, e))
                for i in range(3):
                    w.add_frame(synthetic_frame(spec, k, e, i))
                w.end_episode(success=True)
        roots.append(root)
    capsys.readouterr()
    result = merge_datasets(roots, tmp_path / "merged")
    assert "Copy data and videos" not in capsys.readouterr().err
    assert result.shards == ("shard-0000", "shard-0001") and result.episodes == 3
    scenes = [r["scene_id"] for r in read_episode_columns(result.root)]
    assert scenes == ["scene-001", "scene-001", "scene-000"]
    ds = load_dataset(result.root)
    np.testing.assert_array_equal(ds[6]["observation.state"].numpy(), synthetic_frame(spec, 0, 0, 0).state())
