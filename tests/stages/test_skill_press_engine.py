"""The press and slide skills on the batched engine (issue 16, set_alarm_clock), CPU, one world, no
cameras, in kitchen 0 of the kitchen catalog plus the alarm clocks (the clock parked on the counter).

Known failing (strict xfail): the fingertips pass through the clock's button cap and switch knob
without moving them (the button stays at 0.2 mm while the tip's end goes 12 mm below the cap's top
and stops on the clock's body; the knob likewise): the robot's fingers get no contact with the child
links of the free-floating clock, while they do with its base link and with the fixed-base
microwave's button. Slow (the catalog job and one episode per skill, ~1 minute each): ``-m slow``."""

from __future__ import annotations

import pytest

from kitchen_testutil import KITCHEN, PACKAGES

pytestmark = pytest.mark.slow

CLOCKS = tuple(f"alarm_clock_0{i}" for i in range(5))
NO_CONTACT = "no fingertip contact with the free clock's child links on CPU (see the module doc)"


@pytest.fixture(scope="module")
def clock_kitchen(tmp_path_factory):
    pytest.importorskip("newton")
    import numpy as np

    from pipeline import build_job, run_job
    from stages.demos.kitchen import AssetLibrary, write_kitchen

    out = tmp_path_factory.mktemp("clockk") / "out"
    job = {"job": {"name": "clockk", "seed": 0, "out": str(out), "executor": "inline", "workers": 1},
           "step": [{"name": "catalog", "kind": "default_catalog",
                     "config": {"variants": 5, "categories": [*KITCHEN, "alarm_clock"]}},
                    {"name": "assets", "kind": "ingest",
                     "config": {"catalog_step": "catalog", "only": [*PACKAGES, *CLOCKS]}}]}
    summary = run_job(build_job(job, source="<test>", base_dir=out.parent), progress=False)
    assert {s.name: s.failed for s in summary.steps} == {"catalog": 0, "assets": 0}
    lib = AssetLibrary.from_folder(out / "assets", out / "catalog" / "default" / "generated.json")
    return write_kitchen(out.parent / "kitchen", lib, scene_id="c", rng=np.random.default_rng(0), clock=True)


def _episode(world, task: str, seed: int, work):
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    eng = BatchEngine(world, panda_root=None, work_dir=work,
                      config=EngineConfig(worlds=1, layout="per_world", record_images=False, subtasks=True))
    results = []
    eng.run(Listed(world, {0: [(task, seed, None)]}), begin=lambda *_: None, end=lambda w, t, r: results.append(r))
    return results[0]


@pytest.mark.xfail(strict=True, reason=NO_CONTACT)
def test_press_clock_button_presses_it(clock_kitchen, tmp_path):
    res = _episode(clock_kitchen, "press_clock_button", 1, tmp_path / "w")
    assert res.success, res.reason


@pytest.mark.xfail(strict=True, reason=NO_CONTACT)
def test_slide_clock_switch_turns_it_on(clock_kitchen, tmp_path):
    res = _episode(clock_kitchen, "slide_clock_switch", 1, tmp_path / "w")
    assert res.success, res.reason
