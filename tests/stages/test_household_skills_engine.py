"""The household skills on the batched engine (issue 16), in a CPU kitchen whose catalog has a plate,
a sponge, crumpled paper and a trash can (the kitchen catalog job plus those categories; world seed
0, the world of ``bench_kitchen_tasks.py --kitchens 0``): wipe_plate (the sponge grasped, the plate
wiped in rows with contact, the sponge put back; the coverage of the plate's top by the sponge's
contact path reaches the predicate's threshold), clean_table (the paper into the can) and, from a catalog
with a dish rack, clean_dishes (the wipe, then the plate laid on the rack: stages.demos.skill_rack).

Slow (the catalog job and an episode each, several minutes of CPU on 2 shared cores): ``-m slow``."""

from __future__ import annotations

import pytest

from kitchen_testutil import KITCHEN, PACKAGES

pytestmark = pytest.mark.slow

#: a plate and a sponge the hand grasps across (61-72 mm), paper of 26 mm radius, a round can
DISHES = ("plate_02", "sponge_04", "crumpled_paper_00", "trash_can_01")


@pytest.fixture(scope="module")
def dish_kitchen(tmp_path_factory):
    pytest.importorskip("newton")
    import numpy as np

    from pipeline import build_job, run_job
    from stages.demos.kitchen import AssetLibrary, write_kitchen

    out = tmp_path_factory.mktemp("dishes") / "out"
    job = {"job": {"name": "dishes", "seed": 0, "out": str(out), "executor": "inline", "workers": 1},
           "step": [{"name": "catalog", "kind": "default_catalog",
                     "config": {"variants": 5, "categories": [*KITCHEN, "plate", "sponge", "crumpled_paper", "trash_can"]}},
                    {"name": "assets", "kind": "ingest",
                     "config": {"catalog_step": "catalog", "only": [*PACKAGES, *DISHES]}}]}
    summary = run_job(build_job(job, source="<test>", base_dir=out.parent), progress=False)
    assert {s.name: s.failed for s in summary.steps} == {"catalog": 0, "assets": 0}
    lib = AssetLibrary.from_folder(out / "assets", out / "catalog" / "default" / "generated.json")
    return write_kitchen(out.parent / "kitchen", lib, scene_id="d", rng=np.random.default_rng(0),
                         household=True)


def test_wipe_plate_covers_the_plate_and_succeeds(dish_kitchen, tmp_path):
    from stages.demos.skill_wipe import COVERAGE
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    assert {"plate", "sponge"} <= set(dish_kitchen.placed)
    eng = BatchEngine(dish_kitchen, panda_root=None, work_dir=tmp_path / "w",
                      config=EngineConfig(worlds=1, layout="per_world", record_images=False))
    results, traces = [], []
    src = Listed(dish_kitchen, {0: [("wipe_plate", 1, None)]})

    def next_instance(w):
        inst = src(w)
        if inst is not None:
            traces.append(inst.place)
        return inst

    eng.run(next_instance, begin=lambda *_: None, end=lambda w, t, res: results.append(res))
    assert results[0].success, results[0].detail
    assert traces[0].coverage >= COVERAGE and traces[0].samples > 10


def test_clean_table_throws_the_paper_into_the_can(dish_kitchen, tmp_path):
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    assert {"paper", "trash_can"} <= set(dish_kitchen.placed)
    eng = BatchEngine(dish_kitchen, panda_root=None, work_dir=tmp_path / "w",
                      config=EngineConfig(worlds=1, layout="per_world", record_images=False, subtasks=True))
    results = []
    eng.run(Listed(dish_kitchen, {0: [("clean_table", 1, None)]}), begin=lambda *_: None,
            end=lambda w, t, res: results.append(res))
    assert results[0].success, results[0].detail


@pytest.fixture(scope="module")
def rack_kitchen(tmp_path_factory):
    """The kitchen of world seed 0 from a catalog that also has a dish rack: write_kitchen parks it
    under the table, clean dishes' wipe sets it on the table beside the plate."""
    pytest.importorskip("newton")
    import numpy as np

    from pipeline import build_job, run_job
    from stages.demos.kitchen import AssetLibrary, write_kitchen

    out = tmp_path_factory.mktemp("rack") / "out"
    job = {"job": {"name": "rack", "seed": 0, "out": str(out), "executor": "inline", "workers": 1},
           "step": [{"name": "catalog", "kind": "default_catalog",
                     "config": {"variants": 5, "categories": [*KITCHEN, "plate", "sponge", "dish_rack"]}},
                    {"name": "assets", "kind": "ingest",
                     "config": {"catalog_step": "catalog", "only": [*PACKAGES, "plate_02", "sponge_04", "dish_rack_00"]}}]}
    summary = run_job(build_job(job, source="<test>", base_dir=out.parent), progress=False)
    assert {s.name: s.failed for s in summary.steps} == {"catalog": 0, "assets": 0}
    lib = AssetLibrary.from_folder(out / "assets", out / "catalog" / "default" / "generated.json")
    return write_kitchen(out.parent / "kitchen", lib, scene_id="r", rng=np.random.default_rng(0), household=True)


def test_clean_dishes_wipes_the_plate_and_lays_it_on_the_rack(rack_kitchen, tmp_path):
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    rack = rack_kitchen.placed["dish_rack"]
    assert rack.position[2] == 0.0   # parked on the floor under the table
    eng = BatchEngine(rack_kitchen, panda_root=None, work_dir=tmp_path / "w",
                      config=EngineConfig(worlds=1, layout="per_world", record_images=False, subtasks=True))
    results = []
    eng.run(Listed(rack_kitchen, {0: [("clean_dishes", 1, None)]}), begin=lambda *_: None,
            end=lambda w, t, res: results.append(res))
    assert results[0].success, (results[0].reason, results[0].detail)
