"""The hang-on-rail skill (issue 16, organize the wardrobe): a clothes hanger lying on the bed hung by
its hook over the wardrobe's lower rail (task ``hang_on_rail``; the multistage task
``organize_wardrobe`` opens the wardrobe's door first and closes it after), in a generated bedroom
(:mod:`stages.demos.house_bedroom`: the bed along X, its long side facing the robot at -Y; the
wardrobe anywhere in the room, facing any way).

Simplifications (the Franka hand cannot do the real thing): the hanger lies flat on the bed's near
edge with its neck and hook sticking out over the edge (:func:`hanger_start`), so that the fingers,
closing vertically across its plane, pinch its neck from the side (the hand level, pointing along the
edge), just under the boss at the neck's top end (the catalog's hangers have one: ``neck_stop``;
held upright, the neck slides down the few mm until the boss rests on the fingers; without it the neck
slid through the pinch until the hook hung on the fingertips); the hand keeps that grasp to the rail:
it turns the hanger upright (hook up, its plane across the way), carries it so, turns it slowly about
the neck before the wardrobe (in joint space, on the branch with the wrist rolled ~90 deg: CLIK's own
path ended by joint 7's limit, from where the rail was out of reach), drives straight in and hooks it
over the wardrobe's lower rail (``low_rail``: 0.95-1.1 m, a double-hang rail; the upper one at
1.4-1.7 m is out of the arm's reach), the hook mid open half. Light things crept on the blanket (the
hanger 7.4 mm/s towards the bed's middle): MuJoCo's one contact point per convex pair; the wardrobe
tasks' bedroom worlds step with multi-CCD contacts (``HouseBedroom.multiccd``), where it stays put;
where it lies back on the bed the expert still first pulls it out by its hook (:func:`_pull_out`). The arm is first homed in joint space and a door that swung under
60% open is opened again (open_wardrobe's tuck swept it half shut in flat_023).

- :func:`rail_facts`: the lower rail's axis (two end points, world) and radius from the wardrobe's
  generator parameters;
- :func:`hanger_start`: the episode's hanger pose on the bed;
- :func:`hang_on_rail` (the expert): drive before the bed, pinch the neck, lift, turn the hanger
  upright beside the base, drive before the open half of the wardrobe, bring the hook in over the
  rail through its opening (the hook's tip inward), lower it onto the rail, release, back out;
- :func:`hang_on_rail_success` (the predicate): the hook's centre within a few cm of the rail's axis,
  below it by about the hook's inner radius (the rail inside the hook's top), between the rail's
  ends, the hanger hanging from it (its neck within 30 deg of vertical, the expert lets it settle),
  released.

Frame: world, Z up, metres, radians. Hanger frame (the generator's): the shoulder bar along local Y at
x = 0, the neck from x = -shoulder_height ``neck`` [m] further along -X, the hook's centre beyond it;
the hook's tip towards local +Y.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from stages.demos.driver import APPROACH_TOL, ExpertFailure
from stages.demos.wardrobe_arm import CARRY, joint_move, posture, ramp, roll_limited

log = logging.getLogger(__name__)

PAD_HALF = 0.010        # the Panda finger pad's half width along the pinched neck [m]
STOP_GAP = 0.003        # the pads pinch the neck this far [m] under its boss (``neck_stop``): held upright, the
                        # neck slides down this far, then the boss rests on the fingers (without the boss the neck
                        # slid through the pinch until the hook hung on the fingertips); the wrist, level with
                        # the neck, clears the blanket's edge only ~45 mm out
OVERHANG = 0.025        # the apex lies this far [m] beyond the blanket's near edge
RAIL_T = 0.018          # the wardrobe's carcass board [m] (asset_catalog.generators.furniture)
HOOK_TOL = 0.03         # success: the hook's centre this near [m] its resting place on the rail
HANG_TILT = math.radians(30.0)  # success: the hanger's neck within this of vertical (it hangs from the hook)
PICK_SIDE = 0.20        # the base stands this far [m] along +X from the neck (the hand comes from +X)
PICK_GAP = 0.22         # ... and its chassis front this far [m] before the blanket's near edge
LOW_BED = 0.48          # on a blanket lower than this [m] ...
LOW_GAP = 0.10          # ... the base stands this much further back [m] (the arm folded down to a 0.42 m bed had
                        # no lifting posture: CLIK jumped branch, flat_018/037)
HANG_GAP = 0.06         # the chassis front this far [m] before the wardrobe's front
LEAF_NEAR = 0.12        # a hand this near [m] the open leaf's free edge is first moved on ...
LEAF_PAST = 0.15        # ... out past it this far [m]
REOPEN_BELOW = 0.6      # the door is opened again where it stands less than this [fraction] of its travel open
HANG_AT = 0.5           # the hook goes this far [fraction] from the rail's hinge-side end to its middle (the
                        # hand, 0.2 m wide across the rail, centred in the open half; the base stands further
                        # from the hinge, clear of the open leaf, and the arm reaches sideways)
SIDE_REACH = 0.08       # ... but at most this far [m] beside the base's centre line (the arm reaches ~0.67 m ahead)
HAND_CLEAR = 0.13       # ... and at least this far [m] from the rail's middle (the closed door's edge)
LEAF_CLEAR = 0.31       # the chassis centre this far [m] beside the open leaf's band
PINCH_PAST = 0.012      # the hand is aimed this far [m] past the neck (it stops ~12 mm short of a low target)
PULL_IF = 0.012         # a hanger whose apex lies less than this [m] beyond the blanket's edge is pulled out ...
PULL_TO = 0.015         # ... until it lies this far [m] out (its centre of mass ~2 cm on the blanket with the
                        # neck's boss; at 0.035 m the hanger tipped over the edge, at 0.025 m after a 0.3 m pull)
PULL_LAG = 0.015        # the pushing hand stops this far [m] short of its target
HOOK_TIP = -0.002       # the pulling hand's tool point aimed this far [m] above the hook rod's middle (it stops
                        # 8-11 mm above a low target, the fingertips ~9 mm below it: they reach under a 2 mm wire's top)
HOOK_FINGER = 0.010     # the closed fingertips' half thickness along the pull [m] (they drag the hook's inside)
PUSH_TIP = 0.009        # the closed hand's tool point this far [m] above the rod's middle (its fingertips just clear the blanket)
PICK_YAW = 0.0          # the pinching hand may point this far off square to the neck, towards the bed [rad]
                        # (35 deg: the lower fingertip met the blanket's edge)
TURN_SLOW = 6.0         # the held hanger is turned about its neck in this long [s]
ROLL = -1.0             # the hand's tool X points away from the hook (+1: towards it; symmetric fingers)
SHORT_OK = 0.03         # the base may stop this far [m] short of the hang pose (the hook's moves aim in the world)
APPROACHES = (0.35, 0.2)  # the straight way in to the hang pose [m], the first the planner finds room for (a 1.2 m
                          # band between the wardrobe and the bed had none at 0.35: flat_026)
STAGE_STEP = 0.08       # the base drives on this far [m] towards the hang pose where the staged hand is out of reach ...
STAGE_MIN = 0.25        # ... while it stays this far [m] from it
RELEASE_DROP = 0.008    # the closed hand is pressed this far [m] below the hook's rest on the rail before it opens
RELEASE_CLEAR = 0.012   # ... and the open hand lowered this much more [m] before it backs out
ENTRY = 0.02            # the hook starts this far [m] outside the rail before it goes in
WITHDRAW_HOLD, WITHDRAW_STEP, WITHDRAW_STEP_S = 0.3, 0.005, 0.15  # the open hand held [s] under the hung hook,
WITHDRAW_SLOW, WITHDRAW_OUT = 0.06, 0.15   # then out in steps [m] of [s] each to SLOW [m], then to OUT [m] in one move
BACK_OUT = 0.2          # the base backs out this far [m] from the hang pose (along the open leaf: _back_out)


@dataclass(frozen=True)
class Rail:
    """The wardrobe's lower rail: p0, p1 (3,) its axis's end points [m] (world); radius [m];
    front (2,) unit: the wardrobe's outward front normal (world)."""

    p0: tuple[float, float, float]
    p1: tuple[float, float, float]
    radius: float
    front: tuple[float, float]


def rail_facts(wardrobe) -> Rail:
    """The lower rail of the placed ``wardrobe`` (a :class:`~stages.demos.packages.Placed`); ItemError
    when its asset has none (a wardrobe generated before the rail)."""
    from asset_catalog.generators.furniture import LOW_RAIL_RADIUS
    from pipeline.types import ItemError

    p = wardrobe.asset.params
    if "low_rail" not in p or "width" not in p:
        raise ItemError(f"{wardrobe.asset.usd}: {wardrobe.asset.asset_id} has no lower rail (param low_rail)")
    z, half = float(p["low_rail"]), 0.5 * float(p["width"]) - RAIL_T
    a, b = wardrobe.to_world((0.0, -half, z)), wardrobe.to_world((0.0, half, z))
    f = wardrobe.dir_to_world((1.0, 0.0, 0.0))
    return Rail(tuple(float(v) for v in a), tuple(float(v) for v in b), LOW_RAIL_RADIUS,
                (float(f[0]), float(f[1])))


def _hook(hanger) -> tuple[float, float, float]:
    """(grasp x, hook centre x, rod radius) in the hanger frame [m]: the grasp just under the neck's
    boss (``neck_stop`` long, at the neck's top end); the hook's inner radius is the ``hook_radius``
    parameter."""
    p = hanger.asset.params
    hh, hr, rod, neck, stop = (float(p[k]) for k in ("shoulder_height", "hook_radius", "rod", "neck", "neck_stop"))
    return -hh - (neck - stop - PAD_HALF - STOP_GAP), -hh - neck - (hr + rod), rod


def hanger_start(world, seed: int) -> dict:
    """The hanger's pose (body -> (x, y, z, yaw)) for episode ``seed``: flat on the blanket at the bed's
    near edge, 0.3 m in from the blanket's foot end (world ``hanger_x``), its neck and hook over the
    edge towards -Y (yaw pi/2: local +X along world +Y) (its own random stream)."""
    rng = np.random.default_rng([int(seed), 16, 1])
    h = world.placed["hanger"]
    hh = float(h.asset.params["shoulder_height"])
    x = world.hanger_x + float(rng.uniform(-0.03, 0.03))
    y = world.blanket_edge - OVERHANG + hh
    return {h.body(): (x, y, world.table_z + 0.003, math.pi / 2 + float(rng.uniform(-0.05, 0.05)))}


def aside(world) -> dict:
    """The paper's and the cushion's poses (body -> (x, y, z, yaw)) in the wardrobe tasks: on the blanket's
    far band, the paper by the foot end, the cushion by the blanket's start (along X), off the near edge
    where the hanger may lie anywhere along the blanket (house_bedroom keeps its arm clear of the open leaf)."""
    top, pl, out = world.table_rect, world.placed, {}
    foot_x = top[2] - 0.1 if world.foot > 0 else top[0] + 0.1
    if "paper" in pl:
        out[pl["paper"].body()] = (foot_x, top[3] - 0.08, world.table_z + 0.01, 0.0)
    if "cushion" in pl:
        c = pl["cushion"]
        length = float(c.asset.params.get("length", c.asset.hi[1] - c.asset.lo[1]))
        width = float(c.asset.params.get("width", c.asset.hi[0] - c.asset.lo[0]))
        x = world.blanket_x + world.foot * (0.5 * length + 0.05)
        out[c.body()] = (x, top[3] - 0.5 * width - 0.06, world.table_z + 0.002, math.pi / 2)
    return out


def _hanger_pose(state, hanger) -> tuple[np.ndarray, np.ndarray]:
    st = state.objects[hanger.body()]
    return np.asarray(st.position, float), st.matrix()[:3, :3]


def hang_on_rail_success(inst, state, peaks=None) -> tuple[bool, str]:
    """The hook's centre within :data:`HOOK_TOL` of where it rests on the rail (the rail's axis
    ``hook_radius - rail radius`` above it, across and along the rail within its ends), the hanger
    hanging (its neck within :data:`HANG_TILT` of vertical), the hand open or away from it."""
    w = inst.world
    h = w.placed["hanger"]
    rail: Rail = w.rail
    pos, rot = _hanger_pose(state, h)
    _, cx, rod = _hook(h)
    c = pos + rot @ np.array([cx, 0.0, rod])
    a, b = np.asarray(rail.p0), np.asarray(rail.p1)
    u = (b - a) / np.linalg.norm(b - a)
    s = float(np.dot(c - a, u))
    if pos[2] < a[2] - 0.5:
        return False, "hanger_fell"
    if not (0.0 <= s <= float(np.linalg.norm(b - a))):
        return False, "not_on_rail"
    rest = a + s * u - np.array([0.0, 0.0, float(h.asset.params["hook_radius"]) - rail.radius])
    if float(np.linalg.norm(c - rest)) > HOOK_TOL:
        return False, "not_on_rail"
    if float(np.dot(-rot[:, 0], [0.0, 0.0, 1.0])) < math.cos(HANG_TILT):
        return False, "not_hanging"
    hand = np.asarray(state.robot.ee_pose.position, float)
    if state.robot.gripper_opening < 0.03 and float(np.linalg.norm(hand - c)) < 0.1:
        return False, "object_still_held"
    return True, ""


def _apex_out(state, world, hanger) -> float:
    """How far [m] the hanger's apex lies beyond the blanket's near edge (towards -Y)."""
    pos, rot = _hanger_pose(state, hanger)
    apex = pos + rot @ np.array([-float(hanger.asset.params["shoulder_height"]), 0.0, 0.0])
    return float(world.blanket_edge - apex[1])


def _pull_out(d, world, hanger, rod: float, cx: float) -> None:
    """Where the hanger has crept onto the bed (its apex less than :data:`PULL_IF` beyond the blanket's
    edge), pull it back out by its hook: the closed hand, pointing down, lowered into the hook (which
    lies flat, open upwards) and moved towards -Y, its fingertips dragging the hook's far side, until
    the apex is :data:`PULL_TO` out. (Pushed by its shoulder bar from the bed's side, a hanger that had
    crept 25 cm in lay out of reach.)"""
    from stages.demos.counter import _pose
    from stages.simulate.control import top_down
    from stages.simulate.state import read_state

    st = read_state(d.sim)
    out = _apex_out(st, world, hanger)
    if out >= PULL_IF:
        return
    z = world.table_z + rod + HOOK_TIP

    def hook_at() -> np.ndarray:  # the hook's centre now, at the pulling height
        pos, rot = _hanger_pose(read_state(d.sim), hanger)
        c = pos + rot @ np.array([cx, 0.0, rod])
        return np.array([c[0], c[1], z])

    down = top_down(0.0)
    d.grip(1.0, 0.8)
    d.move(_pose(hook_at() + [0, 0, 0.08], down), 1.5, segments=3, settle=0.1, tol=APPROACH_TOL)
    d.move(_pose(hook_at() + [0, 0, 0.08], down), 0.3, segments=1, tol=APPROACH_TOL)
    at = hook_at()
    d.move(_pose(at, down), 0.6, segments=2, settle=0.1)
    out = _apex_out(read_state(d.sim), world, hanger)
    push = PULL_TO - out + max(0.0, float(hanger.asset.params["hook_radius"]) - HOOK_FINGER) + PULL_LAG
    d.move(_pose(at - [0.0, push, 0.0], down), max(1.2, 6.0 * push), segments=3, settle=0.1)
    # back off the hook's far side before lifting (a wire caught between the fingertips came up with them)
    back = np.asarray(read_state(d.sim).robot.ee_pose.position, float) + [0.0, HOOK_FINGER, 0.0]
    d.move(_pose(back, down), 0.4, segments=1)
    d.move(_pose(back + [0.0, 0.0, 0.08], down), 0.6, segments=2, tol=APPROACH_TOL)


def _hook_in_hand(state, hanger, cx: float, rod: float) -> np.ndarray:
    """The hook's centre (3,) [m] in the hand's tool frame, from the simulated poses."""
    pos, rot = _hanger_pose(state, hanger)
    c = pos + rot @ np.array([cx, 0.0, rod])
    ee = state.robot.ee_pose.matrix()
    return ee[:3, :3].T @ (c - ee[:3, 3])


def _in_hanger(state, hanger) -> np.ndarray:
    """The hand's rotation (3, 3) in the hanger's frame, from the simulated poses."""
    _, rot = _hanger_pose(state, hanger)
    return rot.T @ state.robot.ee_pose.matrix()[:3, :3]


def _upright(into) -> np.ndarray:
    """The hanger's rotation hanging upright (local -X up) with its plane along the horizontal
    ``into`` (local +Y, the hook's tip side)."""
    y = np.array([into[0], into[1], 0.0], float)
    y /= np.linalg.norm(y)
    x = np.array([0.0, 0.0, -1.0])
    return np.stack([x, y, np.cross(x, y)], axis=1)


def _rot(x_h, z_h) -> np.ndarray:
    """Hand rotation with tool X ``x_h`` and tool Z (approach) ``z_h``; the fingers close along Z x X."""
    x_h, z_h = np.asarray(x_h, float), np.asarray(z_h, float)
    return np.stack([x_h, np.cross(z_h, x_h), z_h], axis=1)


def _back_out(part, q: float, f: np.ndarray) -> np.ndarray:
    """The way (2,) unit out from the hang pose: along the leaf open at ``q`` [rad] (hinge to free edge),
    or the wardrobe's front normal ``f`` where the leaf points less than 45 deg outward (at its stop the two
    are one): straight out along ``f`` with the leaf short of its stop, the chassis' corner pushed it open
    to its stop (flat_023: 78 -> 90 deg, a wall 0.4 m before it, no room left to push it shut)."""
    from stages.demos.part_grasps import lateral

    along = (part.rotation_at(q) @ np.asarray(lateral(part), float))[:2]
    along = along / max(1e-9, float(np.linalg.norm(along)))
    if float(np.dot(along, f[:2])) < 0:
        along = -along
    return along if float(np.dot(along, f[:2])) > math.cos(math.pi / 4) else np.asarray(f[:2], float)


def _clear_leaf(d, part, q: float) -> None:
    """Where open_wardrobe left the hand by the open leaf's free edge (within :data:`LEAF_NEAR` of it),
    move it on along the leaf, out past that edge by :data:`LEAF_PAST` (hand open, orientation kept):
    tucked from by the edge, the arm swept the door half shut (flat_023: 78 -> 13 deg)."""
    from stages.demos.counter import _pose
    from stages.demos.part_grasps import lateral
    from stages.simulate.state import read_state

    o, a = np.asarray(part.origin, float), np.asarray(part.axis, float)
    v = np.asarray(part.handle, float) - o
    reach = float(np.linalg.norm(v - np.dot(v, a) * a)) + 0.08
    along = part.rotation_at(q) @ np.asarray(lateral(part), float)
    along = np.array([along[0], along[1], 0.0]) / max(1e-9, float(np.linalg.norm(along[:2])))
    ee = read_state(d.sim).robot.ee_pose.matrix()
    hand = ee[:3, 3]
    s = float(np.dot(hand[:2] - o[:2], along[:2]))
    off = float(np.linalg.norm(hand[:2] - o[:2] - s * along[:2]))
    if off > LEAF_NEAR or not (reach - LEAF_NEAR < s < reach + LEAF_PAST):
        return
    d.grip(0.0, 0.3)
    try:
        d.move(_pose(hand + (reach + LEAF_PAST - s) * along, ee[:3, :3]), 1.0, segments=2, tol=APPROACH_TOL)
    except ExpertFailure:
        log.info("%s: the hand could not move on past the leaf's edge", part.joint_path)


def _withdraw(d, low: np.ndarray, f: np.ndarray, rot: np.ndarray) -> None:
    """The open hand, its tool point at ``low`` (3,) [m] under the hung hanger's hook (the fingers either side
    of its plane), out along the wardrobe's front normal ``f`` (3,) with its rotation ``rot`` (3, 3) kept: held
    :data:`WITHDRAW_HOLD` [s], then in steps of :data:`WITHDRAW_STEP` [m], each reached before the next, to
    :data:`WITHDRAW_SLOW`, then on to :data:`WITHDRAW_OUT` in one move. Backed out in one 0.15 m move from
    there, the fingers knocked the hook off the rail within the first 5 cm (flat_037 s2; the hanger lay in
    the wardrobe's bottom; slowed to 1 s for 5 cm it fell the same); stepped, it stays on the rail."""
    from stages.demos.counter import _pose

    d.move(_pose(low, rot), WITHDRAW_HOLD, segments=1)
    n = int(round(WITHDRAW_SLOW / WITHDRAW_STEP))
    for k in range(1, n + 1):
        d.move(_pose(low + k * WITHDRAW_STEP * f, rot), WITHDRAW_STEP_S, segments=1, tol=APPROACH_TOL)
    d.move(_pose(low + WITHDRAW_OUT * f, rot), 0.6, segments=1, tol=APPROACH_TOL)


def hang_base(world, rail: Rail, part, q: float) -> tuple[tuple[float, float, float], np.ndarray]:
    """The base pose (x, y, yaw) facing into the wardrobe before its open half (the chassis beside the
    door ``part`` open at ``q``, clear of its leaf) and the rail point (3,) where the hook goes [m]."""
    f = np.asarray(rail.front, float)
    a, b = np.asarray(rail.p0), np.asarray(rail.p1)
    hinge = np.asarray(part.origin, float)
    # the rail end on the hinge side; the open half runs from there to the middle
    near, far = (a, b) if np.linalg.norm(a[:2] - hinge[:2]) < np.linalg.norm(b[:2] - hinge[:2]) else (b, a)
    u = (far - near) / np.linalg.norm(far - near)
    half = 0.5 * float(np.linalg.norm(far - near))
    leaf_band = float(np.dot(hinge[:2] - near[:2], u[:2])) + half * max(0.0, math.cos(q)) + 0.02
    lateral = max(0.75 * half, leaf_band + LEAF_CLEAR)
    spot = near + min(max(HANG_AT * half, lateral - SIDE_REACH), half - HAND_CLEAR) * u
    log.debug("hang_base: near %s far %s hinge %s q %.2f half %.3f leaf_band %.3f lateral %.3f spot %s", np.round(near, 3),
              np.round(far, 3), np.round(hinge, 3), q, half, leaf_band, lateral, np.round(spot, 3))
    wr = world.placed["wardrobe"]
    front = float(np.dot(np.asarray(wr.to_world((wr.asset.hi[0], 0.0, 0.0)))[:2] - near[:2], f[:2]))
    base = near[:2] + lateral * u[:2] + (front + HANG_GAP + 0.30) * f[:2]
    return (float(base[0]), float(base[1]), float(math.atan2(-f[1], -f[0]))), spot


def hang_on_rail(inst, d) -> None:
    """The expert (see the module doc)."""
    from stages.demos.articulated import _escape
    from stages.demos.counter import _pose, facing_north_goal
    from stages.demos.driver import stow
    from stages.demos.record import base_pose
    from stages.demos.base_approach import drive_in, grid_with_leaf, held_points, leaf_points
    from stages.simulate.state import read_state

    w = inst.world
    h = w.placed["hanger"]
    rail: Rail = w.rail
    part = inst.part
    q = float(d.sim.joint_q_of_path(part.joint_path))
    _clear_leaf(d, part, q)
    # the arm as open_wardrobe left it may stand on a branch by its joints' limits (flat_023: joint 3 at
    # -166 deg, the pick's first move unreachable; tucked by CLIK from there it swept the door half shut):
    # home in joint space first
    d.home(3.0)
    q = float(d.sim.joint_q_of_path(part.joint_path))
    log.debug("hang: hanger at %s at the start", np.round(_hanger_pose(read_state(d.sim), h)[0], 3))
    if q - part.closed < REOPEN_BELOW * part.travel:
        # the door swung half shut (the arm's sweep): open it again from where it stands (the same expert),
        # or the leaf stands in the hanger's way
        from stages.demos.articulated import _swing

        log.info("%s: door at %.2f rad after open_wardrobe: opened again", part.joint_path, q)
        _swing(part, d, w.grid(), q, part.closed + 0.9 * part.travel)
        q = float(d.sim.joint_q_of_path(part.joint_path))
    gx, cx, rod = _hook(h)
    hr = float(h.asset.params["hook_radius"])
    R = hr + rod
    grid = grid_with_leaf(w, part, q)
    _escape(d, grid, reach=1.0)
    # --- pick: the neck pinched from +X, the hand horizontal pointing -X, fingers closing vertically
    pos, rot = _hanger_pose(read_state(d.sim), h)
    neck = pos + rot @ np.array([gx, 0.0, rod])
    gaps = (PICK_GAP + LOW_GAP, PICK_GAP + LOW_GAP / 2, PICK_GAP) if w.table_z < LOW_BED else (PICK_GAP,)
    for k, gap in enumerate(gaps):  # planned before the base moves: a blocked pose costs no motion
        try:
            d.drive_to(facing_north_goal(w.blanket_edge, float(neck[0]) + PICK_SIDE, gap=gap), grid,
                       tuck=stow(d, on_the_way=True))
            break
        except ExpertFailure as e:
            if e.reason != "no_path" or k == len(gaps) - 1:
                raise
    _pull_out(d, w, h, rod, cx)
    pos, rot = _hanger_pose(read_state(d.sim), h)
    neck = pos + rot @ np.array([gx, 0.0, rod])
    along = rot @ np.array([0.0, 1.0, 0.0])          # local +Y (the hook's tip side): the approach
    hook_dir = -(rot @ np.array([1.0, 0.0, 0.0]))    # towards the hook
    # turned PICK_YAW in the hanger's plane towards its shoulders (the wrist off the blanket's edge); the
    # fingers close across the plane, so the hanger can only swing in its own plane in the pinch
    inward = -hook_dir
    c, sn = math.cos(PICK_YAW), math.sin(PICK_YAW)
    grasp = _rot(ROLL * (c * hook_dir + sn * along), c * along + sn * inward)
    # the hand in the hanger's frame (the hanger then turned as wanted: hand = hanger @ in_hanger)
    in_hanger = rot.T @ grasp
    d.grip(0.0, 0.2)
    app = grasp[:, 2]  # the approach
    d.move(_pose(neck - 0.10 * app + [0, 0, 0.01], grasp), 1.5, segments=3, settle=0.1, tol=APPROACH_TOL)
    pos, rot = _hanger_pose(read_state(d.sim), h)
    neck = pos + rot @ np.array([gx, 0.0, rod])
    d.move(_pose(neck - 0.10 * app + [0, 0, 0.01], grasp), 0.3, segments=1, tol=APPROACH_TOL)
    d.move(_pose(neck + PINCH_PAST * app, grasp), 0.8, segments=2, settle=0.5, tol=0.003)
    d.grip(1.0, 0.8)
    low = w.table_z < LOW_BED
    joint_move(d, _pose(neck + [0.0, -0.05, 0.15], grasp), 0.8, low)
    # clear of the bed before it is turned upright (its shoulders would sweep the blanket)
    joint_move(d, _pose(neck + [0.0, -0.15, 0.35], grasp), 1.0, low)
    if read_state(d.sim).objects[h.body()].position[2] < pos[2] + 0.02:
        raise ExpertFailure("grasp_missed", "the hanger stayed on the bed")
    # --- upright beside the base: hook up, the hand pointing ahead of the base
    bx, by, th = base_pose(d.sim)
    ahead = np.array([math.cos(th), math.sin(th), 0.0])
    # first turned about the approach (the pinch holds that way), the neck upright; then slowly about
    # the neck (the pinch holds the neck's roll only by friction: a quick turn spun the hanger 90 deg)
    app = grasp[:, 2]
    side = np.array([app[0], app[1], 0.0]) / max(1e-9, float(np.linalg.norm(app[:2])))
    tip = _upright(side) @ in_hanger
    joint_move(d, _pose([bx + 0.35 * ahead[0] + 0.2 * side[0], by + 0.35 * ahead[1] + 0.2 * side[1], 1.05], tip), 2.0, low)
    # the carry pose: the hand ahead of the base, the hanger's plane across the way (within the base's
    # width: carried with its plane along the way, it swept the open door half shut on the way to it);
    # reached in joint space with the wrist rolled (WRIST_SEEDS)
    for reach, hz in CARRY:
        held = _pose([bx + reach * ahead[0], by + reach * ahead[1], hz], tip)
        if (qa := posture(d, held)) is not None:
            ramp(d, qa, 1.5)
            break
    log.debug("carry: %s", None if qa is None else np.round(np.degrees(qa)))
    d.drive_straight((bx - 0.25 * ahead[0], by - 0.25 * ahead[1], th))
    # --- before the wardrobe's open half, as the leaf stands now (the drive to the bed may have pushed it: flat_023
    # 1.35 -> 1.17 rad, planned for 1.35 the chassis met the leaf's edge on the way in)
    q = float(d.sim.joint_q_of_path(part.joint_path))
    grid = grid_with_leaf(w, part, q)
    goal, spot = hang_base(w, rail, part, q)
    _escape(d, grid, reach=1.0)  # backed off the bed, the base may still stand where the planner counts it blocked
    for k, approach in enumerate(APPROACHES):  # planned before the base moves
        try:
            drive_in(d, grid, goal, leaf_points(part, q), approach=approach, held=held_points(d, h))
            break
        except ExpertFailure as e:
            if e.reason != "no_path" or k == len(APPROACHES) - 1:
                raise
    f = np.array([*rail.front, 0.0])
    up = np.array([0.0, 0.0, 1.0])
    # the hanger as it is held now (it slid onto its boss and may have swung in the pinch): measured
    put = _upright(-f) @ roll_limited(_in_hanger(read_state(d.sim), h))  # the hand at most ROLL_LIMIT off square
    off = _hook_in_hand(read_state(d.sim), h, cx, rod)

    def hand_for(centre):  # the hand's tool point for the hook's centre at ``centre``, the hand at ``put``
        return np.asarray(centre, float) - put @ off

    c_in = spot + 0.25 * R * up
    # the hand set here where the base's last straight stretch carries it to the hook's entry (centred in
    # the open half, the hook 3 cm high), so that it goes in straight
    entry = hand_for(c_in + (R + rail.radius + ENTRY) * f + 0.03 * up)
    bx, by, _ = base_pose(d.sim)
    log.debug("hang: door at %.2f (was %.2f)", float(d.sim.joint_q_of_path(part.joint_path)), q)
    log.debug("hang: base %s goal %s spot %s hook in hand %s hand for entry %s", np.round(base_pose(d.sim), 3),
              np.round(goal, 3), np.round(spot, 3), np.round(off, 3), np.round(entry, 3))
    staged = _pose(entry - [goal[0] - bx, goal[1] - by, 0.0], put)
    # turned slowly about the neck, its plane now along the way in (the pinch holds the neck's roll only by
    # friction: a quick turn spun the hanger 90 deg); in joint space, on the wrist-rolled branch (CLIK's own
    # path ended on another, by joint 7's limit, from which the rail was out of reach); where the hand is out
    # of reach there (the staging point 0.55 m back: flat_023), the base first drives on towards the goal
    mid = 0.5 * (np.asarray(rail.p0[:2]) + np.asarray(rail.p1[:2]))  # the closed door's edge; the open half towards spot
    beside = (mid, (spot[:2] - mid) / np.linalg.norm(spot[:2] - mid))
    qa = posture(d, staged, narrow=True, beside=beside)
    while qa is None and math.dist((bx, by), goal[:2]) > STAGE_MIN + STAGE_STEP:
        u = (np.asarray(goal[:2]) - [bx, by]) / math.dist((bx, by), goal[:2])
        d.drive_straight((bx + STAGE_STEP * u[0], by + STAGE_STEP * u[1], goal[2]))
        bx, by, _ = base_pose(d.sim)
        staged = _pose(entry - [goal[0] - bx, goal[1] - by, 0.0], put)
        qa = posture(d, staged, narrow=True, beside=beside)
    if qa is not None:
        ramp(d, qa, TURN_SLOW)
    d.move(staged, 1.0, segments=2, carry=True, tol=APPROACH_TOL)
    try:
        d.drive_straight(goal)
    except ExpertFailure as e:  # the hand's moves below aim in the world: a base a little short does no harm
        if e.reason != "drive_timeout" or math.dist(base_pose(d.sim)[:2], goal[:2]) > SHORT_OK:
            raise
        log.info("hang: the base stopped %.3f m short of its goal", math.dist(base_pose(d.sim)[:2], goal[:2]))
    log.debug("hang: door at %.2f after the drive in", float(d.sim.joint_q_of_path(part.joint_path)))
    d.move(_pose(entry, put), 1.0, segments=2, carry=True, tol=APPROACH_TOL)
    d.move(_pose(hand_for(c_in + (R + rail.radius + ENTRY) * f), put), 0.6, segments=2, carry=True, settle=0.3)
    off = _hook_in_hand(read_state(d.sim), h, cx, rod)
    d.move(_pose(hand_for(c_in + (R + rail.radius + ENTRY) * f), put), 0.4, segments=1, carry=True, settle=0.2)
    d.move(_pose(hand_for(c_in), put), 1.2, segments=3, carry=True)
    # the neck may have slid in the pinch on the way in (1.5 cm in flat_019: the hook went down behind the rail):
    # measured again over the rail and set right before it goes down
    off = _hook_in_hand(read_state(d.sim), h, cx, rod)
    d.move(_pose(hand_for(c_in), put), 0.5, segments=1, carry=True, settle=0.2)
    off = _hook_in_hand(read_state(d.sim), h, cx, rod)
    rest = spot - (hr - rail.radius - 0.003) * up
    d.move(_pose(hand_for(rest), put), 0.8, segments=2, carry=True, settle=0.2)
    # the hand pressed on down past where the hook rests on the rail (the fingers slide down the neck, off the
    # boss), so that the opening fingers do not drag the boss along the rail (4 cm in flat_008) ...
    d.move(_pose(hand_for(rest) - RELEASE_DROP * up, put), 0.6, segments=1, carry=True, settle=0.2)
    d.grip(0.0, 0.6)
    # ... and lowered clear of it before they back out (backing out under it, they swung the hanger off the rail)
    low = hand_for(rest) - (RELEASE_DROP + RELEASE_CLEAR) * up
    d.move(_pose(low, put), 0.5, segments=1)
    _withdraw(d, low, f, put)
    d.step(0.5)
    log.debug("hang: door at %.2f, hanger at %s after the release", float(d.sim.joint_q_of_path(part.joint_path)),
              np.round(_hanger_pose(read_state(d.sim), h)[0], 3))
    bx, by, th = base_pose(d.sim)
    back = _back_out(part, float(d.sim.joint_q_of_path(part.joint_path)), f)
    d.drive_straight((bx + BACK_OUT * back[0], by + BACK_OUT * back[1], th))
    log.debug("hang: door at %.2f, hanger at %s backed out", float(d.sim.joint_q_of_path(part.joint_path)),
              np.round(_hanger_pose(read_state(d.sim), h)[0], 3))
    d.home(2.0)
    log.debug("hang: door at %.2f, hanger at %s homed", float(d.sim.joint_q_of_path(part.joint_path)),
              np.round(_hanger_pose(read_state(d.sim), h)[0], 3))  # a canonical posture: close_wardrobe plans its base poses by IK from it
