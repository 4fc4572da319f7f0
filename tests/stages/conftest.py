"""Fixtures shared by the stage tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from kitchen_testutil import kitchen_job, link_kitchen_catalog, shard_begin


@pytest.fixture(scope="session")
def kitchen_catalog(tmp_path_factory) -> Path:
    """The work dir of :func:`kitchen_testutil.kitchen_job`, run once per test session by the real job
    steps (~20 s on 2 cores). Shared: tests read it; jobs that add steps run in a copy
    (:func:`kitchen_testutil.copy_kitchen_catalog`); ``teleop_kitchen`` runs in a work dir linked to it
    (:func:`kitchen_testutil.link_kitchen_catalog`: every item cached, nothing but the runner's logs,
    reports and index rewritten)."""
    from pipeline import build_job, run_job

    out = tmp_path_factory.mktemp("kitchen_catalog") / "out"
    summary = run_job(build_job(kitchen_job(out), source="<test>", base_dir=out.parent), progress=False)
    assert {s.name: s.failed for s in summary.steps} == {"catalog": 0, "assets": 0}
    return out


@pytest.fixture(scope="session")
def kitchen_library(kitchen_catalog):
    """The :class:`~stages.demos.kitchen.AssetLibrary` of :func:`kitchen_catalog`."""
    from stages.demos.kitchen import AssetLibrary

    return AssetLibrary.from_folder(kitchen_catalog / "assets",
                                    kitchen_catalog / "catalog" / "default" / "generated.json")


@pytest.fixture(scope="session")
def kitchen_room(kitchen_library, tmp_path_factory):
    """The kitchen of world seed 5 (scene id ``k``) written from :func:`kitchen_library`. Shared:
    tests only read it (engines write into their own work dirs)."""
    import numpy as np

    from stages.demos.kitchen import write_kitchen

    return write_kitchen(tmp_path_factory.mktemp("kitchen_room") / "kitchen", kitchen_library, scene_id="k",
                         rng=np.random.default_rng(5))


@pytest.fixture(scope="session")
def teleop_world(kitchen_catalog, tmp_path_factory):
    """The teleop kitchen (world seed 5), built once per test session by ``teleop_kitchen`` in a work dir
    linked to the session's kitchen catalog (the same job: its items come from the cache)."""
    pytest.importorskip("newton")
    pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")
    from stages.teleop.world import teleop_kitchen

    work = link_kitchen_catalog(kitchen_catalog, tmp_path_factory.mktemp("teleop_world"))
    return teleop_kitchen(work, world_seed=5)


@pytest.fixture(scope="session")
def policy_dataset(kitchen_catalog, tmp_path_factory):
    """A tiny dataset of ours for the policy tests, recorded by the batched engine's recorder: one
    scripted push_object episode (seed 1) in the default-catalog kitchen of world seed 5 (scene id
    ``kitchen_ws5``), wrist and head cameras at 64x48, merged like the demos job's shards
    (~265 frames; about 2 minutes on 2 shared cores). Returns the dataset folder."""
    pytest.importorskip("newton")
    pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")
    pytest.importorskip("lerobot")
    from stages.dataset import merge_shards, open_shard
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed
    from stages.policy.evaluate import build_kitchen

    d = tmp_path_factory.mktemp("policy_dataset")
    world = build_kitchen(link_kitchen_catalog(kitchen_catalog, d / "work"), 5)
    cfg = EngineConfig(worlds=1, width=64, height=48, cameras=("wrist", "head"))
    engine = BatchEngine(world, panda_root=None, work_dir=d / "engine", config=cfg, seed=5)
    results = []
    with open_shard(d / "shards", "s0", cfg.dataset_spec()) as shard:
        def end(w, ticket, res):
            results.append(res)
            shard.end_episode(success=res.success, reason=res.reason)

        engine.run(Listed(world, {0: [("push_object", 1, None)]}), begin=shard_begin(shard, world), end=end)
    assert [r.success for r in results] == [True], results
    return merge_shards(d / "shards", d / "dataset").root
