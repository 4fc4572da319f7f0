"""The throw-away skill (issue 16, clean the table): a piece of crumpled paper from the table into
the trash can standing on the floor beside it (task ``throw_away``).

- :func:`trash_setup`: the episode's paper on the table's near band by its west end (the trash can
  stays where the kitchen parks it: on the floor off the table's west end, a planning obstacle);
- :func:`throw_away` (the expert): drive before the table's west end, top-down grasp of the paper
  across its middle, lift, swing the hand over the can's opening, release it
  :data:`DROP_ABOVE` over the rim, tuck;
- :func:`throw_away_success` (the predicate): the paper's centre inside the can's opening (1 cm in
  from its wall), below its rim, the can upright, the hand open.

Frame: world, Z up, metres, radians.
"""

from __future__ import annotations

import math

import numpy as np

from stages.demos.driver import APPROACH_TOL, ExpertFailure

DROP_ABOVE = 0.10        # the paper is let go this far [m] above the can's rim
MAX_PAPER_RADIUS = 0.0315  # crumpled paper (bumps up to +18 %) the Franka hand's 80 mm stroke grasps [m]
BIN_GAP = 0.10           # the can stands this far [m] off the table's west end
PINCH = 0.008            # the fingers are commanded this far [m] inside the paper's width
PAPER_AT = (0.12, 0.10)  # the paper's spot: this far [m] in from the table top's west end, front
CREEP_LEAD = 0.8         # the grasp leads the paper's creep by this long [s] (the descent and settle)


def can_opening(placed) -> tuple[np.ndarray, float, float]:
    """The can's opening: centre (2,) [m], inner half extent [m] (radius or the smaller half side,
    less the wall) and the rim's height [m], from the catalog record's parameters."""
    p = placed.asset.params
    wall = float(p.get("wall", 0.005))
    half = float(p["rim_radius"]) if "rim_radius" in p else 0.5 * min(float(p["depth"]), float(p["width"]))
    return (np.asarray(placed.position[:2], float), half - wall,
            float(placed.position[2]) + float(p["height"]))


def trash_setup(world, rng: np.random.Generator) -> dict:
    """The episode's object poses (body -> (x, y, z, yaw)): the paper on the table's near band by its
    west end (the can parked). ItemError when the world has no paper and can
    (:func:`stages.demos.kitchen.write_kitchen` parks them when the catalog has them)."""
    from pipeline.types import ItemError

    pl = world.placed
    if "paper" not in pl or "trash_can" not in pl:
        raise ItemError(f"{world.usd}: no crumpled paper and trash can in this kitchen")
    x0, y0, _, _ = world.table_rect
    return {pl["paper"].body(): (x0 + PAPER_AT[0] + float(rng.uniform(-0.02, 0.02)),
                                 y0 + PAPER_AT[1] + float(rng.uniform(0, 0.02)),
                                 world.table_z + 0.002, float(rng.uniform(-np.pi, np.pi))),
            pl["trash_can"].body(): (*pl["trash_can"].position, 0.0)}


def throw_away_success(inst, state, peaks=None) -> tuple[bool, str]:
    """The paper inside the can's opening, below its rim; the can upright; the hand open."""
    from stages.demos.predicates import _upright

    pl = inst.world.placed
    centre, half, rim = can_opening(pl["trash_can"])
    can = state.objects[pl["trash_can"].body()]
    if not _upright(can.orientation):
        return False, "container_tipped"
    shift = np.asarray(can.position[:2]) - np.asarray(pl["trash_can"].position[:2])
    p = np.asarray(state.objects[pl["paper"].body()].position)
    if np.abs(p[:2] - centre - shift).max() > half - 0.01 or p[2] > rim - 0.01:
        return False, "object_not_in_container"
    if state.robot.gripper_opening < 0.06:
        return False, "object_still_held"
    return True, ""


def _command_for(gripper, width: float) -> float:
    """The gripper command (0 open .. 1 closed) whose finger targets stand ``width`` [m] apart (a
    parallel gripper: each finger at width / 2; command 1 is ``squeeze`` past closed)."""
    span = gripper.open_q - gripper.closed_q + gripper.squeeze
    return float(np.clip((gripper.open_q - 0.5 * width) / span, 0.0, 1.0))


def throw_away(inst, d) -> None:
    """The expert (see the module doc)."""
    from stages.demos.counter import _pose, facing_north_goal
    from stages.demos.driver import stow
    from stages.simulate.control import top_down
    from stages.simulate.state import read_state

    w = inst.world
    paper = w.placed["paper"]
    r = float(paper.asset.params["radius"])
    if r > MAX_PAPER_RADIUS:
        raise ExpertFailure("object_too_wide", f"paper of radius {r * 1000:.0f} mm")
    pxy = np.asarray(inst.objects[paper.body()][:2], float)
    tuck = stow(d, on_the_way=True)
    d.drive_to(facing_north_goal(w.table_rect[1], float(pxy[0])), w.grid(), tuck=tuck)
    st = read_state(d.sim).objects[paper.body()]  # (light: it may have crept)
    pxy, z0 = np.asarray(st.position[:2], float), float(st.position[2])
    rot = top_down(math.pi / 2)
    h = r * 1.5  # the flat-bottomed ball's height [m]
    # across its widest (the ball's centre, flat_bottom x radius above its flat side): pinched above
    # it, the light ball slipped down out of the fingers as they lifted (kitchen 0, seed 1)
    at = np.array([*pxy, z0 + max(float(paper.asset.params.get("flat_bottom", 0.55)) * r, 0.012)])
    d.grip(0.0, 0.2)
    d.move(_pose(at + [0, 0, 0.10], rot), 1.5, segments=3, settle=0.1, tol=APPROACH_TOL)
    # re-aimed where it will be when the fingers close: on a bed's blanket the light ball creeps
    # ~8 mm/s and the fingers closed beside it (a generated bedroom, make_bed: grasp_missed)
    p0, t0 = np.asarray(read_state(d.sim).objects[paper.body()].position[:2], float), d.sim.time
    d.move(_pose([*p0, at[2] + 0.10], rot), 0.6, segments=2, settle=0.1, tol=APPROACH_TOL)
    p1, t1 = np.asarray(read_state(d.sim).objects[paper.body()].position[:2], float), d.sim.time
    creep = (p1 - p0) / max(t1 - t0, 1e-3)
    at[:2] = p1 + np.clip(creep * CREEP_LEAD, -0.02, 0.02)
    d.move(_pose(at, rot), 0.6, segments=2, settle=0.2)
    # a gentle pinch: fingers commanded to 8 mm under the ball's width (the fully closed squeeze shot
    # the 4 g ball out of the hand onto the floor: kitchen 0, seed 1)
    d.grip(_command_for(d.sim.desc.gripper, 2.0 * r - PINCH), 0.8)
    d.move(_pose(at + [0, 0, 0.12], rot), 0.8, segments=2, carry=True)
    if read_state(d.sim).objects[paper.body()].position[2] < z0 + 0.05:
        raise ExpertFailure("grasp_missed", "the paper stayed on the table")
    centre, _, rim = can_opening(w.placed["trash_can"])
    over = np.array([*centre, rim + DROP_ABOVE + 0.5 * h])
    d.move(_pose([*centre, max(over[2], at[2] + 0.12)], rot), 1.5, segments=3, carry=True, tol=APPROACH_TOL)
    d.move(_pose(over, rot), 0.8, segments=2, carry=True, settle=0.1)
    d.grip(0.0, 0.5)
    d.step(0.5)  # let it fall
    d.move(_pose(over + [0, 0, 0.15], rot), 0.8, segments=2, tol=APPROACH_TOL)
    stow(d)
