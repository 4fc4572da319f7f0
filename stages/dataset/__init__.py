"""Demonstration datasets: LeRobot v3.0 shards written in parallel, merged, loaded (issue 7).

Recorder side (one shard per worker; a shard is complete or absent)::

    from stages.dataset import DatasetSpec, EpisodeInfo, Frame, open_shard, depth_m_to_mm

    spec = DatasetSpec()  # 7-dof arm, 30 fps, wrist/head/third_person at 320x240, RGB + depth
    with open_shard(work_dir / "datasets/basic/shards", item_id, spec) as shard:
        shard.begin_episode(EpisodeInfo(task="put the mug in the bowl", task_kind="pick_place",
                                        scene_id=scene_id, seed=seed, asset_ids=("mug_02", "bowl_01")))
        for step in episode:
            shard.add_frame(Frame(arm_joint_pos=q, ee_pose=ee, base_pose=base, arm_joint_target=q_cmd,
                                  ee_target=ee_cmd, base_velocity=v_cmd, gripper=g, mode=1,
                                  rgb={"wrist": rgb_w, ...}, depth_mm={"wrist": depth_m_to_mm(d_w), ...}))
        outcome = shard.end_episode(success=ok, reason=why)  # failed: not written, counted by reason
    # leaving the block publishes the shard (rename); an exception deletes its temporary folder

Merge and load::

    from stages.dataset import merge_shards, load_dataset, read_episode_columns
    result = merge_shards(shards_dir, work_dir / "datasets/basic/merged")   # MergeResult with failures
    ds = load_dataset(result.root)                           # a lerobot LeRobotDataset
    depth = decode_depth(ds[0]["depth.wrist"])               # uint16 (H, W) [mm], lossless
    torch.utils.data.DataLoader(ds, batch_size=32, num_workers=4)

Contact sheet: ``agentworld render-dataset DATASET --out sheet.png``.

Modules: schema (typed spec, frames, validation), depth (the lossless depth codec), writer (EpisodeWriter lifecycle, lerobot backend),
direct (the faster backend writing the same format), shards (atomic shards), merge (aggregation,
loading), render (contact sheet), synthetic (deterministic frames for tests and benchmarks).
Importing this package loads neither torch nor lerobot; they load when a writer opens.
"""

from .depth import decode_depth, depth_keys_of, encode_depth
from .merge import MergeError, MergeResult, load_dataset, merge_datasets, merge_shards, read_episode_columns
from .schema import (
    CameraSpec,
    DatasetSpec,
    EpisodeInfo,
    Frame,
    FrameError,
    VideoCodecSpec,
    depth_m_to_mm,
    validate_frame,
)
from .shards import (
    ShardExistsError,
    ShardInfo,
    ShardWriter,
    clean_stale_temps,
    list_shards,
    open_shard,
    shard_info,
)
from .writer import EpisodeOutcome, EpisodeWriter, WriterStats, read_sidecar

__all__ = [
    "CameraSpec",
    "DatasetSpec",
    "EpisodeInfo",
    "EpisodeOutcome",
    "EpisodeWriter",
    "Frame",
    "FrameError",
    "MergeError",
    "MergeResult",
    "ShardExistsError",
    "ShardInfo",
    "ShardWriter",
    "VideoCodecSpec",
    "WriterStats",
    "clean_stale_temps",
    "decode_depth",
    "depth_keys_of",
    "depth_m_to_mm",
    "encode_depth",
    "list_shards",
    "load_dataset",
    "merge_datasets",
    "merge_shards",
    "open_shard",
    "read_episode_columns",
    "read_sidecar",
    "shard_info",
    "validate_frame",
]
