"""The drink of serve_drinks in the simulation (issue 16): a CPU kitchen whose catalog has a pitcher
and a cup (the kitchen catalog job plus those categories; world seed 0): the 24 spheres are free
bodies of the world's model that rest inside the parked pitcher (no contact dropped), an episode's
reset puts them into the pitcher at its sampled pose, and the episode ends with a stage-named result.

Slow (the catalog job, a settle and an episode, minutes of CPU on 2 shared cores): ``-m slow``."""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest

from kitchen_testutil import KITCHEN, PACKAGES

pytestmark = pytest.mark.slow

#: pitcher_03: the narrowest pitcher of the five variants (50 mm radius); a 32 mm cup
DRINKS = ("pitcher_03", "cup_03")


@pytest.fixture(scope="module")
def drink_kitchen(tmp_path_factory):
    pytest.importorskip("newton")
    from pipeline import build_job, run_job
    from stages.demos.kitchen import AssetLibrary, write_kitchen

    out = tmp_path_factory.mktemp("drinks") / "out"
    job = {"job": {"name": "drinks", "seed": 0, "out": str(out), "executor": "inline", "workers": 1},
           "step": [{"name": "catalog", "kind": "default_catalog",
                     "config": {"variants": 5, "categories": [*KITCHEN, "pitcher", "cup"]}},
                    {"name": "assets", "kind": "ingest", "config": {"catalog_step": "catalog", "only": [*PACKAGES, *DRINKS]}}]}
    summary = run_job(build_job(job, source="<test>", base_dir=out.parent), progress=False)
    assert {s.name: s.failed for s in summary.steps} == {"catalog": 0, "assets": 0}
    lib = AssetLibrary.from_folder(out / "assets", out / "catalog" / "default" / "generated.json")
    return write_kitchen(out.parent / "kitchen", lib, scene_id="p", rng=np.random.default_rng(0), drink=True)


def _in_pitcher(state, world, pitcher_pose) -> np.ndarray:
    """Which drink spheres lie inside the pitcher at ``pitcher_pose`` (x, y, z) (upright)."""
    from stages.demos.drink import pitcher_inner_radius

    params = world.placed["pitcher"].asset.params
    pts = np.array([state.objects[b].position for b in world.drink])
    rel = pts - np.asarray(pitcher_pose[:3])
    return ((np.linalg.norm(rel[:, :2], axis=1) < pitcher_inner_radius(params))
            & (rel[:, 2] > 0.008) & (rel[:, 2] < float(params["height"])))


def test_the_drink_rests_in_the_parked_pitcher(drink_kitchen, tmp_path, caplog):
    from stages.demos.drink import DRINK_COUNT
    from stages.engine import BatchEngine, EngineConfig
    from stages.simulate.state import read_state

    assert len(drink_kitchen.drink) == DRINK_COUNT and {"pitcher", "cup"} <= set(drink_kitchen.placed)
    eng = BatchEngine(drink_kitchen, panda_root=None, work_dir=tmp_path / "w",
                      config=EngineConfig(worlds=1, layout="per_world", record_images=False))
    sim = eng.banks[0].sim
    assert set(drink_kitchen.drink) <= set(eng._free)  # free bodies the reset poses
    with caplog.at_level(logging.WARNING):
        sim.step(int(round(1.0 / sim.settings.dt)))  # 1 s
    st = read_state(sim)
    p = drink_kitchen.placed["pitcher"].position
    assert _in_pitcher(st, drink_kitchen, p).all()
    assert not [r for r in caplog.records if "dropped" in r.getMessage()]


def test_a_serve_drinks_episode_starts_with_the_drink_in_the_pitcher(drink_kitchen, tmp_path):
    from stages.demos.multistage import MULTISTAGE
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed
    from stages.simulate.state import read_state

    eng = BatchEngine(drink_kitchen, panda_root=None, work_dir=tmp_path / "w",
                      config=EngineConfig(worlds=1, layout="per_world", record_images=False, subtasks=True))
    src = Listed(drink_kitchen, {0: [("serve_drinks", 1, None)]})
    insts, starts, results = [], [], []

    def next_instance(w):
        inst = src(w)
        if inst is not None:
            insts.append(inst)
        return inst

    def begin(w, inst):
        starts.append(read_state(eng.banks[0].sim))

    eng.run(next_instance, begin=begin, end=lambda w, t, res: results.append(res))
    home = insts[0].place.home
    assert math.dist(home[:2], drink_kitchen.placed["pitcher"].position[:2]) > 0.1  # not where it was parked
    assert _in_pitcher(starts[0], drink_kitchen, home).all()
    stages = [f"s{k}_{s.skill}." for k, s in enumerate(MULTISTAGE["serve_drinks"].stages, 1)]
    assert results[0].success or results[0].reason.startswith(tuple(stages)), results[0].reason
