"""The household-task rules (issue 16) in a generated house: a living room, a bedroom and a kitchen
populated from real asset packages of the default catalog's generators hold what the tasks use (a
bookshelf and books, a pitcher and cups, paper trash and a trash can; a wardrobe with hangers inside,
pillows on the bed, an alarm clock; a dish rack, a sponge and plates on the kitchen counter)."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest

from stages.scene.rules import HOUSEHOLD_TASK_RULES, load_rules
from stages.scene.solver import Library, PlacementFailure, Populator
from stages.scene.verify import verify

RULES = load_rules(HOUSEHOLD_TASK_RULES)

def _required_categories() -> list[str]:
    """Every category a required entry of the three rooms names, if what it requires is required too."""
    entries = [e for rt in ("living_room", "bedroom", "kitchen")
               for e in (*RULES.for_room(rt).furniture, *RULES.for_room(rt).objects) if e.count[0] > 0]
    cats: set[str] = set()
    while True:
        more = {e.category for e in entries if set(e.requires) <= cats} - cats
        if not more:
            return sorted(cats)
        cats |= more


CATEGORIES = _required_categories()    # one variant each
LAYOUT_SEED = 7
ATTEMPTS = 4      # populate attempts per scene, as the scene job's default


@pytest.fixture(scope="module")
def house(tmp_path_factory):
    from stages.layout.build import generate_layout
    from stages.layout.floorplan import load_floor_plan
    from stages.layout.spec import LayoutSpec
    from stages.scene.standin import build_library

    root = tmp_path_factory.mktemp("household")
    # one variant of each category; the kitchen's mug entry takes only mugs the hand grasps across
    # (max_width): mug_04 is the default catalog's one, so every mug variant is built
    base = Library.from_index(build_library(root / "lib", categories=[c for c in CATEGORIES if c != "mug"],
                                            variants=1, seed=0))
    mugs = Library.from_index(build_library(root / "lib", categories=["mug"], variants=5, seed=0))
    lib = Library({**base.records, **mugs.records}, base.root)
    lay = generate_layout(LayoutSpec(rooms={"living_room": 1, "bedroom": 1, "kitchen": 1}), LAYOUT_SEED,
                          root / "layout")
    plan = load_floor_plan(lay.plan_json)
    why = []
    for a in range(ATTEMPTS):
        pop = Populator(plan, lay.usd, lib, RULES, np.random.default_rng([LAYOUT_SEED, a]))
        try:
            reports = [pop.populate_room(r) for f in plan.floors for r in f.rooms]
            return pop, reports
        except PlacementFailure as e:
            why.append(str(e))
    pytest.fail(f"no population in {ATTEMPTS} attempts: {why}")


def test_task_rooms_hold_what_the_rules_require(house):
    pop, reports = house
    assert {r.room_type for r in reports} == {"living_room", "bedroom", "kitchen"}
    for rep in reports:
        rr = RULES.for_room(rep.room_type)
        placed = Counter(i.p.record.category for i in pop.insts if i.p.room == rep.room)
        need = Counter()
        for e in (*rr.furniture, *rr.objects):
            if all(placed[c] for c in e.requires):
                need[e.category] += e.count[0]
        short = {c: (placed[c], n) for c, n in need.items() if placed[c] < n}
        assert not short, f"{rep.room}: placed < required: {short}; skipped {rep.skipped}"
    check = verify(pop)
    assert check.penetrations == () and check.path == ()


def test_task_objects_sit_where_the_tasks_look_for_them(house):
    pop, _ = house
    by_inst = {i.p.inst: i for i in pop.insts}

    def on(category: str, room: str = "") -> set[str]:
        return {by_inst[i.p.support].p.record.category if i.p.support else "floor"
                for i in pop.insts if i.p.record.category == category and room in i.p.room}

    assert on("hanger") <= {"wardrobe", "closet"} and on("hanger")
    assert on("dish_rack") == {"kitchen_counter"} and on("sponge") == {"kitchen_counter"}
    assert on("pitcher", "living_room") == {"coffee_table"} and "coffee_table" in on("book")
    assert on("mug", "kitchen") and {i.p.record.id for i in pop.insts if i.p.record.category == "mug"} == {"mug_04"}
    assert on("crumpled_paper", "living_room") == {"coffee_table"} and on("trash_can") == {"floor"}
    assert on("crumpled_paper", "bedroom") <= {"bed"}  # make the bed: the thing put away into the trash can
    assert on("pillow") >= {"bed"} and on("alarm_clock") == {"nightstand"}
    # a hanger lies inside its wardrobe: within its footprint, below its top
    for h in (i for i in pop.insts if i.p.record.category == "hanger"):
        w = by_inst[h.p.support]
        assert h.p.position[2] < w.p.position[2] + w.geo.hi[2] - 0.05
        c, s = np.cos(w.p.yaw), np.sin(w.p.yaw)
        local = np.array([[c, s], [-s, c]]) @ (np.array(h.p.position[:2]) - np.array(w.p.position[:2]))
        assert np.all(local >= w.geo.lo[:2]) and np.all(local <= w.geo.hi[:2])
