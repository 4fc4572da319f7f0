"""The drink of serve drinks (issue 16) and where an episode sets it out: :data:`DRINK_COUNT` small
spheres, free bodies of the world's model, that start inside a pitcher (the skills that pour them:
:mod:`stages.demos.skill_pour`).

- :func:`drink_positions` / :func:`drink_world`: the spheres' start centres (N, 3) packed in layers
  inside a pitcher (pitcher frame / world), used when a world is written and at every reset;
- :func:`pitcher_ok`, :func:`park_drink`, :func:`write_drink`: which pitchers the hand grasps, the
  task kitchen's parked pitcher and cup, the spheres' USD prims;
- :func:`pour_setup`: the episode's pitcher (handle towards the robot, -Y) and cup on the table's
  near band, the spheres in the pitcher, other objects out of the way; a :class:`PourPlan`.

Frame: world, Z up, metres, radians. Pitcher asset frame: origin at its base centre, handle on +Y,
spout on -Y (asset_catalog.generators.objects.pitcher).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

DRINK_COUNT = 24          # spheres of the drink
DRINK_RADIUS = 0.007      # [m]
DRINK_DENSITY = 1000.0    # water [kg/m^3]: 1.44 g a sphere
DRINK_FRICTION = 0.2      # low: the spheres roll and slide out like a liquid


@dataclass(frozen=True)
class PourPlan:
    """The episode's fixed facts: pitcher / cup body paths; home: the pitcher's start pose
    (x, y, z, yaw) [m, rad] where it is put back; drink: the spheres' body paths; cup_xy: where the
    cup stands (2,) [m]."""

    pitcher: str
    cup: str
    home: tuple[float, float, float, float]
    drink: tuple[str, ...]
    cup_xy: tuple[float, float]


def pitcher_inner_radius(params: dict) -> float:
    """Inner radius [m] of the pitcher's floor (the generator's profile: bottom radius 0.85 r, less
    the wall)."""
    return 0.85 * float(params["radius"]) - float(params["wall"])


def drink_positions(params: dict, n: int = DRINK_COUNT, radius: float = DRINK_RADIUS) -> np.ndarray:
    """Sphere centres (n, 3) [m] in the pitcher frame: layers of a centre and a ring of six
    (:data:`radius` + 2 mm clear of each other and of the inner wall), from 2 mm above the floor
    (the generator's floor at 8 mm) upward. ValueError when the pitcher is too narrow for a ring or
    the layers rise above its rim."""
    inner = pitcher_inner_radius(params)
    ring = 2 * radius + 0.003
    if ring + radius + 0.002 > inner:
        raise ValueError(f"pitcher inner radius {inner * 1000:.0f} mm holds no ring of {radius * 1000:.0f} mm spheres")
    floor = 0.008 + float(params["wall"])
    pts = []
    layer = 0
    while len(pts) < n:
        z = floor + 0.002 + radius + layer * (2 * radius + 0.002)
        turn = 0.5 * (layer % 2) * math.pi / 6  # alternate layers turned (they nest)
        ring_pts = [(ring * math.cos(turn + k * math.pi / 3), ring * math.sin(turn + k * math.pi / 3), z)
                    for k in range(6)]
        pts += [(0.0, 0.0, z), *ring_pts]
        layer += 1
    out = np.asarray(pts[:n], float)
    if out[:, 2].max() + radius > float(params["height"]) - 0.01:
        raise ValueError(f"{n} spheres of {radius * 1000:.0f} mm rise above the pitcher's rim")
    return out


def drink_world(pitcher_pose, params: dict, n: int = DRINK_COUNT) -> np.ndarray:
    """The spheres' centres (n, 3) [m] in the world for a pitcher at ``pitcher_pose`` (x, y, z, yaw)."""
    x, y, z, yaw = pitcher_pose
    c, s = math.cos(yaw), math.sin(yaw)
    p = drink_positions(params, n)
    return np.column_stack([x + c * p[:, 0] - s * p[:, 1], y + s * p[:, 0] + c * p[:, 1], z + p[:, 2]])

def pour_setup(world, rng: np.random.Generator) -> tuple[dict, PourPlan]:
    """The episode's object poses (body -> (x, y, z, yaw)): the pitcher (yaw pi: handle towards the
    robot) and, 0.30 m east of it, the cup on the table's near band; the spheres in the pitcher;
    the mug, bowl and pushed object on the far band; in a house's living room
    (:mod:`stages.demos.house_living`: the paper on its spot at the table's west end) the books
    lying stacked behind the paper and the pitcher east of them (:func:`_books_aside`); and the
    :class:`PourPlan`. ItemError when the world has no pitcher, cup and drink
    (:func:`stages.demos.kitchen.write_kitchen` with ``drink=True``,
    :func:`stages.demos.house_living.house_living` with both on the table) or its table is too short
    for both."""
    from pipeline.types import ItemError

    pl = world.placed
    drink = tuple(getattr(world, "drink", ()))
    if "pitcher" not in pl or "cup" not in pl or not drink:
        raise ItemError(f"{world.usd}: no pitcher, cup and drink in this world (write_kitchen(drink=True), "
                        f"or a living room whose table lacks them)")
    x0, y0, x1, y1 = world.table_rect
    tx, z = 0.5 * (x0 + x1), world.table_z + 0.002
    px, cx = tx - 0.15, tx + 0.15
    objects = {}
    if hasattr(world, "shelves"):   # a house's living room: the west end holds the paper (and books)
        west, books = _books_aside(world, z)
        objects.update(books)
        r = float(pl["pitcher"].asset.params["radius"])
        px = max(px, west + 1.2 * r + 0.02)
        cx = min(px + 0.30, x1 - float(pl["cup"].asset.params["rim_radius"]) - 0.03)
        if cx - px < 0.22:
            raise ItemError(f"{world.usd}: the table top ({x1 - x0:.2f} m) is too short for the paper, the "
                            f"pitcher and the cup")
    home = (float(px + rng.uniform(-0.02, 0.02)), float(y0 + 0.22 + rng.uniform(-0.01, 0.01)), z, math.pi)
    cup = (float(cx + rng.uniform(-0.02, 0.02)), float(y0 + 0.22 + rng.uniform(-0.01, 0.01)), z, 0.0)
    objects.update({pl["pitcher"].body(): home, pl["cup"].body(): cup})
    for body, p in zip(drink, drink_world(home, pl["pitcher"].asset.params, len(drink)), strict=True):
        objects[body] = (*(float(v) for v in p), 0.0)
    far = {"mug": (-0.25, 0.14), "bowl": (0.02, 0.16), "pusher": (0.28, 0.12)}
    for role, (dx, back) in far.items():
        if role in pl:
            objects[pl[role].body()] = (tx + dx, y1 - back, z, 0.0)
    plan = PourPlan(pitcher=pl["pitcher"].body(), cup=pl["cup"].body(), home=home, drink=drink,
                    cup_xy=(cup[0], cup[1]))
    return objects, plan


def _books_aside(world, z: float) -> tuple[float, dict]:
    """A living room's books (roles "book_*") lying flat, stacked, 1 cm in from the table top's west
    end and behind the paper on its spot (:data:`stages.demos.skill_trash.PAPER_AT`; organize books
    stands them where the pitcher goes), their short side along X where the long one fits the top's
    depth behind the paper (else the long side along X: 0.37 m deep coffee tables); returns the x
    [m] east of which the table is free (the paper's or the books' east edge) and their poses
    (body -> (x, y, z, yaw)) from table height ``z`` [m] up."""
    from stages.demos.skill_trash import MAX_PAPER_RADIUS, PAPER_AT

    x0, y0, _, y1 = world.table_rect
    west, behind = x0 + PAPER_AT[0] + MAX_PAPER_RADIUS, y0 + PAPER_AT[1] + MAX_PAPER_RADIUS + 0.02
    out, bottom = {}, z
    for role in sorted(r for r in world.placed if r.startswith("book_")):
        b = world.placed[role]
        lo, hi = np.asarray(b.asset.lo, float), np.asarray(b.asset.hi, float)
        ext = hi - lo
        short_x = 0.0 if ext[0] <= ext[1] else math.pi / 2       # the yaw that lays the short side along X
        yaw = short_x if behind + max(ext[0], ext[1]) <= y1 - 0.01 else short_x + math.pi / 2
        c, s = math.cos(yaw), math.sin(yaw)
        hx, hy = 0.5 * (abs(c) * ext[0] + abs(s) * ext[1]), 0.5 * (abs(s) * ext[0] + abs(c) * ext[1])
        mid = 0.5 * (lo + hi)
        off = (c * mid[0] - s * mid[1], s * mid[0] + c * mid[1])
        centre = (x0 + 0.01 + hx, behind + hy)
        out[b.body()] = (float(centre[0] - off[0]), float(centre[1] - off[1]), float(bottom - lo[2]), float(yaw))
        bottom += float(ext[2]) + 0.002
        west = max(west, x0 + 0.01 + 2 * hx)
    return float(west), out


def pitcher_ok(a) -> bool:
    """A pitcher whose floor holds a ring of spheres and whose handle the Franka hand grasps: a flat
    strap loop (the generator's ``handle_depth``: pads on a round rod let the pitcher turn about it)
    with clearance for a fingertip."""
    try:
        drink_positions(a.params)
    except (ValueError, KeyError):
        return False
    if "handle_depth" not in a.params:
        return False
    return any(h.get("kind") == "loop" and float(h.get("clearance", 0.0)) >= 0.018 for h in a.info.get("handles", []))


def park_drink(lib, rng: np.random.Generator, table_rect, table_z: float) -> tuple[dict, tuple[str, ...]]:
    """A pitcher (:func:`pitcher_ok`) and a cup on the table's far band, west and east of the
    household objects, and the drink's sphere bodies (``/World/Drink/D<k>``); ({}, ()) when the
    catalog has no such pitcher or no cup."""
    from stages.demos.packages import Placed

    pitchers = [a for a in lib.of("pitcher") if pitcher_ok(a)]
    cups = lib.of("cup")
    if not pitchers or not cups:
        return {}, ()
    pitcher, cup = pitchers[int(rng.integers(len(pitchers)))], cups[int(rng.integers(len(cups)))]
    tx, far = 0.5 * (table_rect[0] + table_rect[2]), table_rect[3]
    placed = {"pitcher": Placed("Pitcher", pitcher, (tx - 0.42, far - 0.14, table_z + 0.002), 0.0),
              "cup": Placed("Cup", cup, (tx + 0.45, far - 0.10, table_z + 0.002), 0.0)}
    return placed, tuple(f"/World/Drink/D{k:02d}" for k in range(DRINK_COUNT))


def write_drink(w, centres: dict) -> None:
    """Author the drink in scene writer ``w`` (stages.simulate.demo_scene._Writer): one rigid body
    Xform per sphere (``centres``: body path -> centre (3,) [m]) with a sphere collider of
    :data:`DRINK_RADIUS`, mass of water, bound to a low-friction physics material."""
    from pxr import Gf, Sdf

    from stages.simulate.demo_scene import _xform_attrs

    T = Sdf.ValueTypeNames
    w.prim("/World/Drink", "Xform")
    mat = "/World/Drink/Water"
    w.prim(mat, "Material", apis=["PhysicsMaterialAPI"], attrs={
        "physics:staticFriction": (T.Float, DRINK_FRICTION), "physics:dynamicFriction": (T.Float, DRINK_FRICTION),
        "physics:restitution": (T.Float, 0.0)})
    mass = DRINK_DENSITY * 4.0 / 3.0 * math.pi * DRINK_RADIUS ** 3
    for body, c in centres.items():
        w.prim(body, "Xform", apis=["PhysicsRigidBodyAPI", "PhysicsMassAPI"],
               attrs={**_xform_attrs(c), "physics:mass": (T.Float, mass)})
        w.prim(f"{body}/Ball", "Sphere", apis=["PhysicsCollisionAPI", "MaterialBindingAPI"],
               attrs={"radius": (T.Double, DRINK_RADIUS),
                      "primvars:displayColor": (T.Color3fArray, [Gf.Vec3f(0.2, 0.45, 0.9)])},
               rels={"material:binding:physics": [mat]})
