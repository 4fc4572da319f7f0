"""The press and slide skills on the batched engine (issue 16, set_alarm_clock), CPU, one world, no
cameras, in kitchen 0 of the kitchen catalog plus the alarm clocks (the clock parked on the counter).

Failed before session 14 (0/10 each): the fingertips passed through the button cap and the switch
knob: with Newton's 0.1 m contact gap MuJoCo's convex collision found a fingertip millimetres inside
these thin hulls separated (stages.simulate.world.CONTACT_GAP, tests/stages/test_simulate_thin_contacts.py).
Slow (the catalog job and one episode per skill, ~1 minute each): ``-m slow``."""

from __future__ import annotations

import pytest

from kitchen_testutil import clock_library

pytestmark = pytest.mark.slow

CLOCKS = tuple(f"alarm_clock_0{i}" for i in range(5))


@pytest.fixture(scope="module")
def clock_kitchen(tmp_path_factory):
    pytest.importorskip("newton")
    import numpy as np

    from stages.demos.kitchen import write_kitchen

    out = tmp_path_factory.mktemp("clockk") / "out"
    lib = clock_library(out, CLOCKS)
    return write_kitchen(out.parent / "kitchen", lib, scene_id="c", rng=np.random.default_rng(0), clock=True)


def _episode(world, task: str, seed: int, work):
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    eng = BatchEngine(world, panda_root=None, work_dir=work,
                      config=EngineConfig(worlds=1, layout="per_world", record_images=False, subtasks=True))
    results = []
    eng.run(Listed(world, {0: [(task, seed, None)]}), begin=lambda *_: None, end=lambda w, t, r: results.append(r))
    return results[0]


def test_press_clock_button_presses_it(clock_kitchen, tmp_path):
    res = _episode(clock_kitchen, "press_clock_button", 1, tmp_path / "w")
    assert res.success, res.reason


def test_slide_clock_switch_turns_it_on(clock_kitchen, tmp_path):
    res = _episode(clock_kitchen, "slide_clock_switch", 1, tmp_path / "w")
    assert res.success, res.reason


def test_set_alarm_clock_presses_then_slides(clock_kitchen, tmp_path):
    """The multistage task (stages/demos/multistage/set_alarm_clock.toml): both stages in one episode."""
    res = _episode(clock_kitchen, "set_alarm_clock", 1, tmp_path / "w")
    assert res.success, res.reason
