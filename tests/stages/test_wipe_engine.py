"""wipe_plate on the batched engine (issue 16, clean dishes): in a CPU kitchen whose catalog has
plates and sponges (the kitchen catalog job plus those categories), the expert grasps the sponge,
wipes the plate in rows with contact and puts the sponge back; the coverage of the plate's top by
the sponge's contact path reaches the predicate's threshold.

Slow (the catalog job and one episode, several minutes of CPU on 2 shared cores): ``-m slow``."""

from __future__ import annotations

import pytest

from kitchen_testutil import KITCHEN, PACKAGES

pytestmark = pytest.mark.slow

DISHES = ("plate_02", "sponge_04")  # a plate and a sponge the hand grasps across (61-72 mm)


@pytest.fixture(scope="module")
def dish_kitchen(tmp_path_factory):
    pytest.importorskip("newton")
    import numpy as np

    from pipeline import build_job, run_job
    from stages.demos.kitchen import AssetLibrary, write_kitchen

    out = tmp_path_factory.mktemp("dishes") / "out"
    job = {"job": {"name": "dishes", "seed": 0, "out": str(out), "executor": "inline", "workers": 1},
           "step": [{"name": "catalog", "kind": "default_catalog",
                     "config": {"variants": 5, "categories": [*KITCHEN, "plate", "sponge"]}},
                    {"name": "assets", "kind": "ingest",
                     "config": {"catalog_step": "catalog", "only": [*PACKAGES, *DISHES]}}]}
    summary = run_job(build_job(job, source="<test>", base_dir=out.parent), progress=False)
    assert {s.name: s.failed for s in summary.steps} == {"catalog": 0, "assets": 0}
    lib = AssetLibrary.from_folder(out / "assets", out / "catalog" / "default" / "generated.json")
    return write_kitchen(out.parent / "kitchen", lib, scene_id="d", rng=np.random.default_rng(0))


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
