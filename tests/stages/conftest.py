"""Fixtures shared by the stage tests."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def teleop_world(tmp_path_factory):
    """The teleop kitchen (world seed 5), built once per test session (about 20 s on 2 cores)."""
    pytest.importorskip("newton")
    pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")
    from stages.teleop.world import teleop_kitchen

    return teleop_kitchen(tmp_path_factory.mktemp("teleop_world"), world_seed=5)


@pytest.fixture(scope="session")
def policy_dataset(tmp_path_factory):
    """A tiny dataset of ours for the policy tests, recorded by the batched engine's recorder: one
    scripted push_object episode (seed 1) in the default-catalog kitchen of world seed 5 (scene id
    ``kitchen_ws5``), wrist and head cameras at 64x48, merged like the demos job's shards
    (~265 frames; about 2 minutes on 2 shared cores). Returns the dataset folder."""
    pytest.importorskip("newton")
    pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")
    pytest.importorskip("lerobot")
    from stages.dataset import EpisodeInfo, merge_shards, open_shard
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed
    from stages.policy.evaluate import build_kitchen

    d = tmp_path_factory.mktemp("policy_dataset")
    world = build_kitchen(d / "work", 5)
    cfg = EngineConfig(worlds=1, width=64, height=48, cameras=("wrist", "head"))
    engine = BatchEngine(world, panda_root=None, work_dir=d / "engine", config=cfg, seed=5)
    results = []
    with open_shard(d / "shards", "s0", cfg.dataset_spec()) as shard:
        def begin(w, ticket):
            shard.begin_episode(EpisodeInfo(task=ticket.instruction, task_kind=ticket.task, scene_id=world.scene_id,
                                            seed=ticket.seed, asset_ids=ticket.asset_ids))
            return shard.add_frame

        def end(w, ticket, res):
            results.append(res)
            shard.end_episode(success=res.success, reason=res.reason)

        engine.run(Listed(world, {0: [("push_object", 1, None)]}), begin=begin, end=end)
    assert [r.success for r in results] == [True], results
    return merge_shards(d / "shards", d / "dataset").root
