"""The press and slide skills of set_alarm_clock (issue 16): the alarm clock's parts read from its
ingested package, the kitchen that parks it on the counter when a task asks, the task file and the
predicates on typed states (no simulation). The catalog job (the kitchen categories plus the alarm
clock, real steps) runs once per module (~20 s on 2 shared cores).

The episodes on the engine are in ``test_skill_press_engine.py`` (slow)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from kitchen_testutil import clock_library

CLOCKS = ("alarm_clock_00", "alarm_clock_02")


@pytest.fixture(scope="module")
def clock_lib(tmp_path_factory):
    return clock_library(tmp_path_factory.mktemp("clock") / "out", CLOCKS)


def _state(objects: dict, joints: dict):
    from asset_catalog.asset_model import Pose
    from stages.simulate.state import BasePose, RobotState, StepState

    robot = RobotState(joint_names=(), q=np.zeros(0), qd=np.zeros(0), ee_pose=Pose(position=(0.0, 0.0, 2.0)),
                       base=BasePose(x=0.0, y=0.0, theta=0.0), gripper_opening=0.08)
    return StepState(time=0.0, step=0, world=0, robot=robot, objects=objects, scene_joints=joints)


def test_clock_parts_come_from_the_package(clock_lib):
    from stages.demos.packages import Placed
    from stages.demos.skill_press import clock_parts, parts_at

    for a in clock_lib.of("alarm_clock"):
        parts = clock_parts(Placed("Clock", a, (1.0, 2.0, 0.9), math.pi / 2))
        assert parts.button_axis == pytest.approx((0.0, 0.0, -1.0), abs=1e-6)
        assert parts.switch_axis == pytest.approx((0.0, 1.0, 0.0), abs=1e-6)
        assert parts.button_travel == pytest.approx(a.params["button_travel"], rel=1e-4)
        assert parts.switch_travel == pytest.approx(a.params["switch_travel"], rel=1e-4)
        assert parts.back_x == pytest.approx(-a.params["depth"] / 2, abs=1e-6)
        # the button's top face on the clock's axis, above the body (a twin-bell clock's bells rise higher)
        assert parts.button_top[:2] == pytest.approx((0.0, 0.0), abs=1e-6)
        assert a.hi[2] - 0.02 < parts.button_top[2] <= a.hi[2] + 1e-6
        # placed facing +Y (yaw 90 deg): the switch slides towards -X, its back faces -Y
        at = parts_at(parts, (1.0, 2.0, 0.9), (math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4)))
        assert at.slide == pytest.approx((-1.0, 0.0, 0.0), abs=1e-6)
        assert at.out == pytest.approx((0.0, -1.0, 0.0), abs=1e-6)
        assert at.knob_face[1] < 2.0 - a.params["depth"] / 2 - 0.01  # proud of the back face
        assert at.yaw == pytest.approx(math.pi / 2)


def test_the_kitchen_parks_the_clock_only_when_asked(clock_lib, tmp_path):
    from stages.demos.kitchen import CLOCK_BUSY_GAP, CLOCK_END_GAP, watched_joints, write_kitchen

    for seed in range(3):
        plain = write_kitchen(tmp_path / f"p{seed}", clock_lib, scene_id="p", rng=np.random.default_rng(seed))
        w = write_kitchen(tmp_path / f"c{seed}", clock_lib, scene_id="c", rng=np.random.default_rng(seed), clock=True)
        assert "clock" not in plain.placed and "clock" in w.placed
        assert {k: p.position for k, p in plain.placed.items()} == {k: p.position for k, p in w.placed.items()
                                                                   if k != "clock"}
        c = w.placed["clock"]
        x0, y0, x1, y1 = w.counter_rect
        assert x0 + CLOCK_END_GAP <= c.position[0] <= x1 - CLOCK_END_GAP and y0 < c.position[1] < y1
        assert c.position[2] == pytest.approx(w.counter_z + 0.002)
        mw = w.placed["microwave"].footprint()
        near = min(mw[0], w.counter_spot[0]) - CLOCK_BUSY_GAP, max(mw[2], w.counter_spot[0]) + CLOCK_BUSY_GAP
        assert not near[0] < c.position[0] < near[1]
        assert c.yaw == pytest.approx(math.pi / 2)
        assert c.joint("button_joint") in watched_joints(w) and len(watched_joints(plain)) == 1


def test_set_alarm_clock_is_data_and_starts_with_the_clock_off(clock_lib, tmp_path):
    from stages.demos.kitchen import write_kitchen
    from stages.demos.multistage import MULTISTAGE, needs_clock, needs_household, sample_task

    spec = MULTISTAGE["set_alarm_clock"]
    assert [s.skill for s in spec.stages] == ["press_clock_button", "slide_clock_switch"]
    assert all(s.instruction for s in spec.stages) and all(s.final for s in spec.stages)
    assert needs_clock(["set_alarm_clock"]) and needs_clock(["slide_clock_switch"])
    assert not needs_clock(["heat_food", "clean_dishes", "press_button"])
    assert not needs_household(["set_alarm_clock"])
    w = write_kitchen(tmp_path / "k", clock_lib, scene_id="k", rng=np.random.default_rng(0), clock=True)
    inst = sample_task("set_alarm_clock", w, 3)
    c = w.placed["clock"]
    assert inst.joints[c.joint("button_joint")] == 0.0 and inst.joints[c.joint("switch_joint")] == 0.0
    assert inst.objects[c.body()] == (*c.position, c.yaw)
    assert c.asset.asset_id in inst.asset_ids


def test_the_predicates_read_the_joints_and_the_clock_pose(clock_lib, tmp_path):
    from types import SimpleNamespace

    from asset_catalog.asset_model import Pose
    from stages.demos.packages import Placed
    from stages.demos.skill_press import (
        PRESS_FRACTION,
        SLIDE_FRACTION,
        clock_parts,
        press_clock_button_success,
        slide_clock_switch_success,
    )

    c = Placed("Clock", clock_lib.of("alarm_clock")[0], (1.0, 2.0, 0.9), math.pi / 2)
    inst = SimpleNamespace(world=SimpleNamespace(placed={"clock": c}))
    parts = clock_parts(c)
    button, switch = c.joint(parts.button_joint), c.joint(parts.switch_joint)
    up = {c.body(): Pose(position=(1.0, 2.0, 0.9), orientation=(math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4)))}
    tipped = {c.body(): Pose(position=(1.0, 2.0, 0.9), orientation=(math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0))}
    bt, st = parts.button_travel, parts.switch_travel
    rest = _state(up, {button: 0.0, switch: 0.0})
    # the button: its deepest position during the episode counts (it springs back)
    assert press_clock_button_success(inst, rest, peaks={button: 0.75 * bt}) == (True, "")
    assert press_clock_button_success(inst, rest, peaks={button: (PRESS_FRACTION - 0.05) * bt}) == \
        (False, "button_not_pressed")
    assert press_clock_button_success(inst, rest) == (False, "button_not_pressed")
    assert press_clock_button_success(inst, _state(tipped, {button: 0.0, switch: 0.0}), peaks={button: bt}) == \
        (False, "clock_tipped")
    # the switch: where it is at the end counts (moved to its other end and left there)
    assert slide_clock_switch_success(inst, _state(up, {button: 0.0, switch: 0.95 * st})) == (True, "")
    assert slide_clock_switch_success(inst, _state(up, {button: 0.0, switch: (SLIDE_FRACTION - 0.1) * st}),
                                      peaks={switch: st}) == (False, "switch_not_on")
    assert slide_clock_switch_success(inst, _state(tipped, {button: 0.0, switch: st})) == (False, "clock_tipped")
