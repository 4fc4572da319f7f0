"""Small kitchens with windows on most walls (the layouts the scene job used to reject): the fridge
(tall: it must not stand in front of a window) and the counter beside it are placed, on real asset
packages (the default catalog's fridge and counter variants, built in-process) and the real
layouts the layout stage makes from the job's seeds."""

from __future__ import annotations

import numpy as np
import pytest

from stages.scene.geom import convex_overlap
from stages.scene.rules import PlacementRules, load_rules
from stages.scene.solver import Library, Populator, _edges
from stages.scene.verify import verify

# layout seeds of jobs/scenes.toml's kitchen_003 (2.35 x 3.5 m, windows on three walls) and
# kitchen_007 (2.8 x 3.3 m, windows on three walls, the door on the fourth)
KITCHENS = {"kitchen_003": 1424908988552557180, "kitchen_007": 4940562089984916083}


@pytest.fixture(scope="module")
def kitchens(tmp_path_factory):
    from stages.layout.build import generate_layout
    from stages.layout.spec import LayoutSpec
    from stages.scene.standin import build_library

    root = tmp_path_factory.mktemp("kitchen")
    lib = Library.from_index(build_library(root / "lib", categories=["fridge", "kitchen_counter"], variants=5))
    lays = {k: generate_layout(LayoutSpec(rooms={"kitchen": 1}), seed, root / k) for k, seed in KITCHENS.items()}
    return lib, lays


def _fridge_and_counter_rules() -> PlacementRules:
    """The default rules' kitchen furniture entries for the fridge and the counter, nothing else."""
    rules = load_rules()
    kitchen = rules.for_room("kitchen")
    furn = tuple(e for e in kitchen.furniture if e.category in ("fridge", "kitchen_counter"))
    assert [e.count[0] for e in furn] == [1, 1]  # both required
    return rules.model_copy(update={"room": {"kitchen": kitchen.model_copy(update={"furniture": furn, "objects": ()})}})


def _populate(kitchens, name: str, seed: int, attempts: int = 6):
    """Like one scene of the job: up to ``attempts`` populate attempts, each with its own generator."""
    from stages.layout.floorplan import load_floor_plan
    from stages.scene.solver import PlacementFailure

    lib, lays = kitchens
    plan = load_floor_plan(lays[name].plan_json)
    why = []
    for a in range(attempts):
        pop = Populator(plan, lays[name].usd, lib, _fridge_and_counter_rules(), np.random.default_rng([seed, a]))
        try:
            return plan, pop, pop.populate_room(plan.floors[0].rooms[0])
        except PlacementFailure as e:
            why.append(str(e))
    pytest.fail(f"{name} seed {seed}: no arrangement in {attempts} attempts: {why}")


@pytest.mark.parametrize("name", sorted(KITCHENS))
def test_small_kitchen_gets_fridge_and_counter(kitchens, name):
    for seed in range(3):
        plan, pop, rep = _populate(kitchens, name, seed)
        cats = sorted(i.p.record.category for i in pop.insts)
        assert cats == ["fridge", "kitchen_counter"], (seed, rep)
        check = verify(pop)
        assert check.ok, check
        ctx = pop.room_ctx[plan.floors[0].rooms[0].id]
        fridge = next(i for i in pop.insts if i.p.record.category == "fridge")
        for zone, sill in ctx.windows:   # the fridge is taller than every sill: never in front of a window
            assert not convex_overlap(fridge.footprint, zone)
        for zone in ctx.door_zones:
            assert not any(convex_overlap(i.footprint, zone) for i in pop.insts)
        # arrangements given up on the way are reported with the required entry that failed
        assert all("could not place required" in r for r in rep.arrangements_rejected)


def test_free_wall_spans_leave_out_windows_for_tall_assets_only(kitchens):
    """kitchen_003's south wall is mostly window: a fridge-sized asset has no span wide enough there,
    a counter (allowed under a window) has the whole wall but the door's keep-out."""
    from stages.layout.floorplan import load_floor_plan
    from stages.scene.solver import room_context

    lib, lays = kitchens
    plan = load_floor_plan(lays["kitchen_003"].plan_json)
    room = plan.floors[0].rooms[0]
    pop = Populator(plan, lays["kitchen_003"].usd, lib, load_rules(), np.random.default_rng(0))
    ctx = room_context(plan, room, 1.0)
    south = next(e for e in _edges(ctx.interior) if e[1][0] > 0.99)  # runs along +x, the window wall
    tall = pop._free_wall_spans(south, 0.7, 1.7, ctx, True, 0.02)
    low = pop._free_wall_spans(south, 0.7, 1.7, ctx, False, 0.02)
    assert max(b - a for a, b in tall) < 0.6
    # only the door's keep-out (the door is on the west wall, 1 m keep-out) is left out for a low asset
    door_end = max(float(((z - south[0]) @ south[1]).max()) for z in ctx.door_zones)
    assert low == [(pytest.approx(door_end), pytest.approx(south[2]))]
