"""A generated house's bedroom as the alarm clock's task world (issue 16, set the alarm clock:
``stages.demos.house_bedside``): a 3-room flat from the layout stage, its bedroom populated by the
scene stage with the household-task rules (the clock on a nightstand) from the default catalog's
bedroom categories (all 5 variants, as ``tests/benchmarks/bench_house_tasks.py --room bedroom --tasks
set_alarm_clock``), turned into the facts the press and slide experts read (the nightstand's top as the
work surface, a side of it with free floor facing -Y, the clock's back with the switch to the robot, the
base's pose before it); and one real set_alarm_clock episode on the batched engine."""

from __future__ import annotations

import math

import pytest

BEDROOM_PACKAGES = tuple(f"{c}_{k:02d}" for c in ("bed", "nightstand", "wardrobe", "dresser", "chair", "rug", "pillow",
                                                  "cushion", "crumpled_paper", "trash_can", "alarm_clock", "book",
                                                  "hanger") for k in range(5))


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    pytest.importorskip("newton")
    from house_testutil import populate_flat

    from stages.demos.house_bedside import house_bedside

    # flat_000 (job seed 0, as bench_house_tasks.py --room bedroom): its nightstand has free floor before it
    scene, gen = populate_flat(tmp_path_factory.mktemp("bedside") / "out", "bedside", BEDROOM_PACKAGES, "bedroom",
                               count=1, scene="flat_000_p0")
    return house_bedside(scene, tmp_path_factory.mktemp("task"), gen, scene_id=scene.name)


@pytest.mark.slow
def test_house_bedside_facts_put_the_clock_on_the_nightstand_before_the_base(world):
    from stages.demos.counter import facing_north_goal
    from stages.demos.house_bedside import CLOCK_REACH
    from stages.demos.house_room import base_free, obstacles
    from stages.demos.multistage import sample_task
    from stages.demos.skill_press import clock_parts, parts_at

    pl = world.placed
    stand, clock = pl["nightstand"], pl["clock"]
    assert pl["counter"] is stand and stand.asset.category == "nightstand"
    x0, y0, x1, y1 = world.counter_rect
    fp = clock.footprint()
    assert x0 <= fp[0] < fp[2] <= x1 and y0 <= fp[1] < fp[3] <= y1   # on the top
    assert 0.4 < world.counter_z < 0.8 and abs(clock.position[2] - world.counter_z) < 0.01
    at = parts_at(clock_parts(clock), clock.position, (math.cos(clock.yaw / 2), 0.0, 0.0, math.sin(clock.yaw / 2)))
    assert at.out[1] < -0.99 and at.knob_face[1] < at.button_top[1]  # the switch on the robot's side
    # the base's pose before the nightstand: free, in reach of the top's middle
    assert abs(world.base_x - 0.5 * (x0 + x1)) <= CLOCK_REACH + 1e-9
    goal = facing_north_goal(stand.footprint()[1], world.base_x, world.base_gap)
    assert base_free(goal, world.walls, obstacles(world.furniture.values()))
    assert world.anchor is not None and abs(world.anchor[0] - world.base_x) < 1e-9
    # the other rooms' objects and the nightstand's other objects are cut; the clock stays
    assert clock.prim.split("/")[-1] not in world.cut
    inst = sample_task("set_alarm_clock", world, 1)
    assert inst.objects[clock.body()] == (*clock.position, clock.yaw)
    parts = clock_parts(clock)
    assert inst.joints[clock.joint(parts.button_joint)] == 0.0 and inst.joints[clock.joint(parts.switch_joint)] == 0.0
    assert inst.instruction


@pytest.mark.slow
def test_set_alarm_clock_episode_at_a_generated_nightstand(world, tmp_path):
    """One real episode of set_alarm_clock (press the button, slide the switch on) on the batched
    engine: both stages' predicates hold."""
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    eng = BatchEngine(world, panda_root=None, work_dir=tmp_path,
                      config=EngineConfig(worlds=1, layout="per_world", record_images=False, subtasks=True))
    out = []
    eng.run(Listed(world, {0: [("set_alarm_clock", 1, None)]}), begin=lambda *_: None,
            end=lambda _w, t, r: out.append(r))
    assert len(out) == 1 and out[0].success, out[0].reason
    assert out[0].frames > 300
