"""The place-pillow skill (issue 16, make the bed): the neck-roll cushion lying on the bed's blanket
lifted and laid in the bed's head band, between the headboard and the blanket (task
``place_pillow``), in a generated bedroom (:mod:`stages.demos.house_bedroom`: the bed along X, its
long side facing the robot at -Y).

- :func:`cushion_start`: the episode's cushion pose, lengthwise along the bed on the blanket's near
  band, just foot-ward of the blanket's start (``world.blanket_x``; ``world.foot``: -1 the bed's foot
  is to the west, +1 to the east);
- :func:`place_pillow` (the expert): drive before the cushion (slide along the bed's side when the
  base already stands before it), top-down grasp across its width at
  its middle, lift, drive straight along the bed's side to the head band's base pose
  (``world.pillow_base_x``), turn it across the bed and lower it over ``world.pillow_spot`` (on
  the mattress just foot-ward of the bed's own pillows), release, tuck;
- :func:`place_pillow_success` (the predicate): the cushion's centre inside the head band, on the
  bed (not below the mattress's top), the hand open.

Frame: world, Z up, metres, radians.
"""

from __future__ import annotations

import math

import numpy as np

from stages.demos.driver import APPROACH_TOL, ExpertFailure

MAX_CUSHION_WIDTH = 0.072  # a cushion the Franka hand's 80 mm stroke grasps across [m]
PILLOW_SPOT_IN = 0.50      # the cushion's near side this far [m] in from the headboard: across the bed
                           # just foot-ward of the bed's own pillows (0.05-0.45 m in: the bed generator's)
PILLOW_REACH = 0.45        # the place base pose at most this far [m] along the bed from the spot
PINCH = 0.008              # the fingers are commanded this far [m] inside the cushion's width
DROP = 0.03                # the cushion is let go this far [m] above the mattress


def cushion_start(world, seed: int) -> dict:
    """The cushion's pose (body -> (x, y, z, yaw)) for episode ``seed``: on the blanket's near band,
    along the bed (yaw pi/2: its length along X), 3-8 cm foot-ward of the blanket's start (its own
    random stream: the other objects' draws do not change)."""
    rng = np.random.default_rng([int(seed), 14, 1])
    c = world.placed["cushion"]
    length = float(c.asset.params.get("length", c.asset.hi[1] - c.asset.lo[1]))
    width = float(c.asset.params.get("width", c.asset.hi[0] - c.asset.lo[0]))
    x = world.blanket_x + world.foot * (0.5 * length + float(rng.uniform(0.03, 0.08)))
    y = world.table_rect[1] + 0.5 * width + 0.04 + float(rng.uniform(0.0, 0.02))
    return {c.body(): (x, y, world.table_z + 0.002, math.pi / 2 + float(rng.uniform(-0.1, 0.1)))}


def place_pillow_success(inst, state, peaks=None) -> tuple[bool, str]:
    """The cushion's centre inside the head band (2 cm slack), not below the mattress's top; the hand
    open wider than the cushion."""
    w = inst.world
    c = w.placed["cushion"]
    p = np.asarray(state.objects[c.body()].position, float)
    x0, y0, x1, y1 = w.head_band
    if p[2] < w.mattress_z - 0.02:
        return False, "object_fell"
    if not (x0 - 0.02 <= p[0] <= x1 + 0.02 and y0 - 0.02 <= p[1] <= y1 + 0.02):
        return False, "not_at_head"
    if state.robot.gripper_opening < float(c.asset.params.get("width", 0.07)) + 0.004:
        return False, "object_still_held"
    return True, ""


def place_pillow(inst, d) -> None:
    """The expert (see the module doc)."""
    from stages.demos.counter import _pose, facing_north_goal
    from stages.demos.driver import stow
    from stages.demos.record import base_pose
    from stages.demos.skill_trash import _command_for
    from stages.simulate.control import top_down
    from stages.simulate.state import read_state

    w = inst.world
    c = w.placed["cushion"]
    width = float(c.asset.params.get("width", c.asset.hi[0] - c.asset.lo[0]))
    h = float(c.asset.params.get("height", c.asset.hi[2] - c.asset.lo[2]))
    if width > MAX_CUSHION_WIDTH:
        raise ExpertFailure("object_too_wide", f"cushion {width * 1000:.0f} mm wide")
    cxy = np.asarray(inst.objects[c.body()][:2], float)
    pick = facing_north_goal(w.table_rect[1], float(cxy[0]))
    bx, by, th = base_pose(d.sim)
    if abs(by - pick[1]) < 0.1 and abs(math.remainder(th - pick[2], 2 * math.pi)) < 0.2:
        # already before the bed (the last stage's pose): slide along its side (the planner's
        # inflated grid holds a base this near the bed as blocked: no_path)
        stow(d)
        d.drive_straight(pick)
    else:
        d.drive_to(pick, w.grid(), tuck=stow(d, on_the_way=True))
    st = read_state(d.sim).objects[c.body()]
    cxy, z0 = np.asarray(st.position[:2], float), float(st.position[2])
    q = st.orientation
    yaw = math.atan2(2 * (q[0] * q[3] + q[1] * q[2]), 1 - 2 * (q[2] ** 2 + q[3] ** 2))
    # fingers across its width (its local X): top_down(a) closes along a + 90 deg; either way round
    a = (yaw - math.pi / 2 + math.pi / 2) % math.pi - math.pi / 2
    rot = top_down(a)
    at = np.array([*cxy, z0 + 0.5 * h])
    d.grip(0.0, 0.2)
    d.move(_pose(at + [0, 0, 0.10], rot), 1.5, segments=3, settle=0.1, tol=APPROACH_TOL)
    d.move(_pose(at, rot), 0.6, segments=2, settle=0.2)
    d.grip(_command_for(d.sim.desc.gripper, width - PINCH), 0.8)
    lift = max(w.mattress_z + h + 0.15, z0 + 0.15)
    d.move(_pose([*cxy, lift], rot), 0.8, segments=2, carry=True)
    if read_state(d.sim).objects[c.body()].position[2] < z0 + 0.05:
        raise ExpertFailure("grasp_missed", "the cushion stayed on the bed")
    # along the bed's side to the head band's base pose (checked free by the world: no planning)
    d.drive_straight(facing_north_goal(w.table_rect[1], w.pillow_base_x))
    # turned across the bed (its length along Y: the fingers close along X), lowered onto the mattress
    put = top_down(-math.pi / 2)
    spot = np.array([*w.pillow_spot, w.mattress_z + 0.5 * h + DROP])
    d.move(_pose([*spot[:2], lift], put), 1.5, segments=3, carry=True, tol=APPROACH_TOL)
    d.move(_pose(spot, put), 0.8, segments=2, carry=True, settle=0.1)
    d.grip(0.0, 0.5)
    d.step(0.4)
    d.move(_pose(spot + [0, 0, 0.15], put), 0.8, segments=2, tol=APPROACH_TOL)
    stow(d)
