"""Deterministic synthetic frames and shards, for the writer's tests and benchmark (not for training).

Every value is a pure function of (shard, episode, frame index), so a reader can recompute what was
written. Command (used by the tests to write shards in parallel processes and to kill a writer)::

    python -m stages.dataset.synthetic SHARDS_DIR SHARD_ID --shard-index 0 --episodes 2 --frames 12 \
        --fail-every 3 [--spec-json '{...}'] [--pause-after 5] [--backend direct|lerobot]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from .schema import CameraSpec, DatasetSpec, EpisodeInfo, Frame


def synthetic_rgb(cam: CameraSpec, shard: int, episode: int, i: int, cam_index: int = 0) -> np.ndarray:
    """uint8 (H, W, 3): smooth moving waves plus a moving white square (different in every frame)."""
    yy, xx = np.mgrid[0 : cam.height, 0 : cam.width]
    img = np.empty((cam.height, cam.width, 3), np.uint8)
    img[..., 0] = 128 + 100 * np.sin(2 * np.pi * (xx / cam.width + i / 40))
    img[..., 1] = 128 + 100 * np.cos(2 * np.pi * (yy / cam.height + cam_index / 3))
    img[..., 2] = (60 * shard + 25 * episode + 40) % 200
    s = max(cam.height // 6, 2)
    y0, x0 = (2 * i) % max(cam.height - s, 1), (3 * i + 7 * episode) % max(cam.width - s, 1)
    img[y0 : y0 + s, x0 : x0 + s] = (255, 255, 255)
    return img


def synthetic_depth_mm(cam: CameraSpec, shard: int, episode: int, i: int, cam_index: int = 0) -> np.ndarray:
    """uint16 (H, W) [mm] covering 0..65535 (exactness check needs the extremes and odd values)."""
    yy, xx = np.mgrid[0 : cam.height, 0 : cam.width].astype(np.int64)
    d = (xx * 997 + yy * 131 + i * 17 + episode * 1009 + shard * 7919 + cam_index * 3) % 65536
    d[0, 0], d[-1, -1] = 0, 65535
    return d.astype(np.uint16)


def synthetic_frame(spec: DatasetSpec, shard: int, episode: int, i: int) -> Frame:
    """The frame ``i`` of ``episode`` of ``shard`` (state/action values encode their indices)."""
    n, h = spec.arm_dof, len(spec.hand_joints)
    base = shard * 100.0 + episode + i / 1000.0
    angle = 0.1 * i
    quat = np.array([np.cos(angle / 2), 0.0, 0.0, np.sin(angle / 2)])
    return Frame(
        arm_joint_pos=base + np.arange(n) * 0.01,
        ee_pose=np.concatenate([[0.3, -0.1, 0.8 + 0.001 * i], quat]),
        base_pose=np.array([0.01 * i, -0.02 * i, angle]),
        arm_joint_target=base + 0.5 + np.arange(n) * 0.01,
        ee_target=np.concatenate([[0.31, -0.1, 0.8 + 0.001 * i], quat]),
        base_velocity=np.array([0.3, -0.6, 0.1 * (i % 3)]),
        gripper=float(i % 2),
        mode=1 if i >= 3 else 0,
        rgb={c.name: synthetic_rgb(c, shard, episode, i, k) for k, c in enumerate(spec.cameras) if c.rgb},
        depth_mm={
            c.name: synthetic_depth_mm(c, shard, episode, i, k) for k, c in enumerate(spec.cameras) if c.depth
        },
        hand_joint_pos=0.01 * i + np.arange(h) * 0.1,
        hand_joint_target=0.01 * i + 0.05 + np.arange(h) * 0.1,
        environment_state=(0.5 + 0.01 * i + 0.1 * np.arange(len(spec.environment_state))
                           if spec.environment_state else None),
    )


def synthetic_episode_info(shard: int, episode: int) -> EpisodeInfo:
    return EpisodeInfo(
        task=f"put object {episode % 2} into the bowl",
        task_kind="pick_place",
        scene_id=f"scene-{shard:03d}",
        seed=1000 * shard + episode,
        asset_ids=(f"obj_{episode}", "bowl_01"),
    )


def is_failed(episode: int, fail_every: int) -> bool:
    """Whether synthetic episode ``episode`` is recorded as failed (every ``fail_every``-th, 0 = never)."""
    return fail_every > 0 and episode % fail_every == fail_every - 1


def write_synthetic_shard(
    shards_dir: Path,
    shard_id: str,
    spec: DatasetSpec,
    *,
    shard_index: int,
    episodes: int,
    frames: int,
    fail_every: int = 0,
    pause_after: int | None = None,
    backend: str = "direct",
) -> None:
    """Write a shard of ``episodes`` episodes of ``frames`` frames (failed ones discarded with a reason).

    pause_after: after this many frames of the last episode, print ``PAUSED`` and sleep forever
    (the kill test kills the process there)."""
    from .shards import open_shard

    with open_shard(shards_dir, shard_id, spec, backend=backend) as shard:
        for e in range(episodes):
            shard.begin_episode(synthetic_episode_info(shard_index, e))
            for i in range(frames):
                if pause_after is not None and e == episodes - 1 and i == pause_after:
                    print("PAUSED", flush=True)
                    while True:
                        time.sleep(60)
                shard.add_frame(synthetic_frame(spec, shard_index, e, i))
            shard.end_episode(success=not is_failed(e, fail_every), reason="grasp slipped")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("shards_dir", type=Path)
    p.add_argument("shard_id")
    p.add_argument("--shard-index", type=int, default=0)
    p.add_argument("--episodes", type=int, default=2)
    p.add_argument("--frames", type=int, default=12)
    p.add_argument("--fail-every", type=int, default=0)
    p.add_argument("--spec-json", default=None, help="DatasetSpec.to_json() as a string")
    p.add_argument("--pause-after", type=int, default=None)
    p.add_argument("--backend", choices=("direct", "lerobot"), default="direct")
    a = p.parse_args(argv)
    spec = DatasetSpec.from_json(json.loads(a.spec_json)) if a.spec_json else DatasetSpec()
    write_synthetic_shard(a.shards_dir, a.shard_id, spec, shard_index=a.shard_index, episodes=a.episodes,
                          frames=a.frames, fail_every=a.fail_every, pause_after=a.pause_after,
                          backend=a.backend)  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
