"""The household rules keep floor round the wardrobe's open leaf (issue 16, organize the wardrobe): the
rule field ``leaf`` (:func:`stages.scene.assets.leaf_zones`) keeps a square of free floor round the free
edge of a door's leaf opened to its stop, where the robot's base drives round the leaf to the hang pose
and stands to push it shut. Before it, 3 of the 40-flat bench's 12 wardrobe bedrooms had no base pose
round that edge (flat_023: the leaf ended 0.39 m from a wall).

A synthetic room (a one-bedroom layout), a real wardrobe package of the default catalog's generator and
the placement solver's own checks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stages.scene.rules import HOUSEHOLD_TASK_RULES, RulesError, load_rules

RULES = load_rules(HOUSEHOLD_TASK_RULES)
NEAR_WALL = 0.39  # [m] flat_023's gap between the open leaf and the wall


@pytest.fixture(scope="module")
def bedroom(tmp_path_factory):
    """(Populator of a one-bedroom layout with the household rules, the room's RoomContext, the
    wardrobe's record and geometry)."""
    from stages.layout.build import generate_layout
    from stages.layout.floorplan import load_floor_plan
    from stages.layout.spec import LayoutSpec
    from stages.scene.room import room_context
    from stages.scene.solver import Library, Populator
    from stages.scene.standin import build_library

    root = tmp_path_factory.mktemp("wardrobe_leaf")
    lib = Library.from_index(build_library(root / "lib", categories=["wardrobe"], variants=1, seed=0))
    lay = generate_layout(LayoutSpec(rooms={"bedroom": 1}), 7, root / "layout")
    plan = load_floor_plan(lay.plan_json)
    room = next(r for f in plan.floors for r in f.rooms if str(r.type) == "bedroom")
    pop = Populator(plan, lay.usd, lib, RULES, np.random.default_rng(0))
    ctx = room_context(plan, room, RULES.setting("bedroom", "door_clearance"))
    rec = lib.records["wardrobe"][0]
    return pop, ctx, rec, pop._geo(rec)


def test_leaf_zone_is_a_square_round_the_open_leafs_free_edge(bedroom):
    """One zone per door of the two-door wardrobe, centred on the hinge's line (the leaf open to its stop
    lies along it) at the swing's far end, cut at the front face; ``door`` picks one; radius 0: none."""
    from stages.scene.assets import leaf_doors, leaf_zones

    *_, geo = bedroom
    rule = next(e for e in RULES.for_room("bedroom").furniture if e.category == "wardrobe")
    assert rule.leaf >= 0.8 + 0.1 and rule.leaf_door == "one"   # the base's 0.8 m disc on 5 cm cells
    assert leaf_doors(geo) == 2
    zones = leaf_zones(geo, 1.0)
    assert len(zones) == 2 and leaf_zones(geo, 0.0) == []
    for z, door in zip(zones, (0, 1)):
        np.testing.assert_allclose(z, leaf_zones(geo, 1.0, door)[0])
        assert z[:, 0].min() == pytest.approx(geo.hi[0]) and np.ptp(z[:, 1]) == pytest.approx(2.0)
        far = max(float(s[:, 0].max()) for s in geo.swings)
        assert z[:, 0].max() == pytest.approx(far + 1.0)
    # door_0 is hinged at -Y (asset_catalog.generators._parts.hinged_door "left"): its square is centred
    # beyond the -Y side, door_1's beyond +Y
    assert zones[0][:, 1].mean() < geo.lo[1] + 0.1 and zones[1][:, 1].mean() > geo.hi[1] - 0.1


def _against_wall(ctx, geo, n, gap: float):
    """(xy, yaw) of the wardrobe with its back on the wall whose inward normal is ``n`` (2,) (a room's
    side) and its door_0 hinge side (asset -Y, where that leaf lies open) ``gap`` [m] from the side wall
    there."""
    n = np.asarray(n, float)
    d = np.array([n[1], -n[0]])   # asset -Y in the world (asset +X along n)
    a = float((ctx.interior @ n).min()) + RULES.setting("bedroom", "wall_gap") - float(geo.lo[0])
    b = float((ctx.interior @ d).max()) - gap + float(geo.lo[1])
    return a * n + b * d, math.atan2(n[1], n[0])


def test_a_wardrobe_whose_open_leaf_would_end_near_a_wall_is_not_placed_there(bedroom):
    """The wardrobe on a long wall with door_0's hinge side (where its leaf lies open) 0.39 m from the side wall:
    the rule without ``leaf`` accepts the pose, with it the door's leaf zone reaches through the wall and
    the solver rejects it; door_1's zone (the other side, room to spare) lets the same pose stand (the task
    world then opens that door: ``house_bedroom._door_with_room``); 1.1 m from the wall door_0's passes."""
    pop, ctx, rec, geo = bedroom
    rule = next(e for e in RULES.for_room("bedroom").furniture if e.category == "wardrobe")
    rule = rule.model_copy(update={"tall_ok_at_window": True})   # the test's walls may have windows
    z = ctx.elevation - float(geo.lo[2])

    def conflict(n, gap: float, leaf) -> str | None:
        xy, yaw = _against_wall(ctx, geo, n, gap)
        inst = pop._instance(rec, geo, ctx, xy, z, yaw, None, rule.clearance, rule.stand, (0.0, 0.0), leaf)
        return pop._floor_conflict(inst, rule, ctx, geo)

    # a wall long enough for the wardrobe, the leaf's square beyond its other side and the gap, where the
    # rule without ``leaf`` takes the pose (not before the room's door)
    need = 2 * rule.leaf + float(geo.hi[1] - geo.lo[1]) + NEAR_WALL
    walls = [n for n in ((0, 1), (0, -1), (1, 0), (-1, 0)) if float(np.ptp(ctx.interior @ np.array([n[1], -n[0]]))) > need
             and conflict(n, NEAR_WALL, (0.0, None)) is None]
    assert walls, "no wall of the room serves the test"
    for n in walls:
        assert conflict(n, NEAR_WALL, (rule.leaf, 0)) == "door/drawer swing or clearance outside the room"
        assert conflict(n, NEAR_WALL, (rule.leaf, None)) == "door/drawer swing or clearance outside the room"
        assert conflict(n, NEAR_WALL, (rule.leaf, 1)) is None, n
        assert conflict(n, rule.leaf + 0.1, (rule.leaf, 0)) is None, n


def test_a_bad_leaf_names_the_file(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('extends = "%s"\n[room.bedroom]\n[[room.bedroom.furniture]]\ncategory = "wardrobe"\n'
                   'leaf = -0.5\n' % HOUSEHOLD_TASK_RULES.as_posix())
    with pytest.raises(RulesError, match=r"bad\.toml.*leaf -0\.5 must be a radius in \[0, 3\] m"):
        load_rules(bad)
    bad.write_text(bad.read_text().replace("leaf = -0.5", 'leaf_door = "two"'))
    with pytest.raises(RulesError, match=r"bad\.toml.*leaf_door: Input should be 'each' or 'one'"):
        load_rules(bad)
