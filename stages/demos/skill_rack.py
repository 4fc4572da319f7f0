"""The place-in-rack skill (issue 16, clean dishes, its second stage): the wiped plate from the
counter onto the dish rack beside it (task ``place_in_rack``).

A catalog plate is one convex hull in simulation (a solid disc, its underside sloping from the foot
up to the rim) and 200-280 mm across: the Franka hand (80 mm stroke) cannot grasp it across, nor
pinch its rim from above. The expert takes it as a person does off a table:

- :func:`place_in_rack` (the expert): drive before the plate and the rack; the open hand pointing
  down behind the plate's far rim, its fingertips :data:`DRAG_TIP` above the counter, slides the
  plate towards the robot until its near rim overhangs the counter's front edge by :data:`OVERHANG`;
  at a top lower than :data:`LOW_TOP` (the task kitchen's table) the base backs :data:`GRASP_BACK`;
  the hand, pointing along +Y with the fingers closing vertically (:func:`rim_rot`), takes the
  overhanging rim between them (one finger under it, one on top), lifts the plate flat, carries it
  over the rack and lets it go :data:`DROP` above the tines: the plate lies flat across the rack's
  two rows of tines (a simplification: a rack's slots hold a plate on edge, which needs the plate
  turned in the hand; see README);
- :func:`place_in_rack_success` (the predicate): the plate's centre within the rack's footprint, at
  most :data:`REST_ABOVE` above its tines (resting on them or in the tray), tilted less than 30 deg,
  the rack upright, the hand open and away.

The rack stands with its tine rows along world Y (yaw 0: the catalog rack's depth along X), its
front :data:`RACK_FRONT` behind the work surface's front edge, beside the plate (a house kitchen's
counter: :mod:`stages.demos.house_dishes`; the task kitchen's table: the wipe's set-up,
:func:`stages.demos.skill_wipe.wipe_setup`, takes the rack that ``write_kitchen(household=True)``
parks under the table).

Frame: world, Z up, metres, radians.
"""

from __future__ import annotations

import math

import numpy as np

from stages.demos.driver import APPROACH_TOL, ExpertFailure

OVERHANG = 0.045    # the plate's near rim this far [m] over the counter's front edge before the grasp
DRAG_TIP = 0.008    # the dragging fingertips this far [m] above the counter
TIP_PAST = 0.009    # the Franka fingertips this far [m] past the TCP (stages.demos.skill_pour)
GRASP_IN = 0.012    # the grasp's TCP this far [m] before the counter's front edge (fingertips 3 mm short)
DROP = 0.02         # the plate's underside this far [m] above the tines when it is let go
REST_ABOVE = 0.04   # success: the plate's underside at most this far [m] above the tines' tops
BASE_GAP = 0.04     # the base's chassis this far [m] before the counter (the far rim is at the arm's reach)
GRASP_BACK = 0.25   # at a top lower than LOW_TOP the base backs this far [m] after the drag: the rim
LOW_TOP = 0.85      # grasp's level hand at a 0.75 m table was too near the arm's base for the IK (task
                    # kitchens 0-1: ik_unreachable with 0 and 0.15 m, or pitched 15 deg down); a
                    # 0.88-0.92 m counter needs no backing
DRAG_PITCH = 25.0   # the dragging hand's fingertips tilted this far [deg] away from the robot (reach)
RACK_GAP = 0.04     # the row of the dishes (stages.demos.house_dishes, skill_wipe.wipe_setup): between the
                    # rack's side and the plate's rim [m]
SPONGE_GAP = 0.12   # ... between the plate's rim and the sponge's centre [m]
PLATE_BACK = 0.03   # ... the plate's near rim behind the front edge [m]
RACK_FRONT = 0.02   # the rack's front this far [m] behind the counter's front edge
PLATE_IN = 0.01     # the plate's near rim this far [m] inside the rack's front
TRAY_FLOOR = 0.004  # the catalog rack's tray floor (stages.asset_catalog.generators.objects.dish_rack) [m]


def rack_box(params: dict) -> tuple[float, float, float]:
    """The catalog dish rack's half depth (along its X), half width (along its Y) and the height of
    its tines' tops above its base [m]."""
    return (0.5 * float(params["depth"]), 0.5 * float(params["width"]),
            TRAY_FLOOR + float(params["tine_height"]))


def rim_rot(pitch_deg: float = 0.0) -> np.ndarray:
    """Hand pointing along world +Y (tool Z), pitched down ``pitch_deg``, fingers closing along the
    (tilted) vertical: one finger under a plate's rim, one on top."""
    p = math.radians(pitch_deg)
    z = np.array([0.0, math.cos(p), -math.sin(p)])
    y = np.array([0.0, math.sin(p), math.cos(p)])
    return np.stack([np.cross(y, z), y, z], axis=1)


def _pose(p, rot) -> np.ndarray:
    from stages.simulate.control import pose

    return pose(np.asarray(p, float), rot)


def _yaw(q) -> float:
    w, x, y, z = (float(v) for v in q)
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _tilt_cos(q) -> float:
    w, x, y, z = (float(v) for v in q)
    return 1 - 2 * (x * x + y * y)


def place_in_rack_success(inst, state, peaks=None) -> tuple[bool, str]:
    """The plate's centre within the rack's footprint, its underside at most :data:`REST_ABOVE` above
    the tines (on them or lower, in the tray), tilted less than 30 deg; the rack upright; the hand
    open and away from the plate."""
    from stages.demos.predicates import _released, _upright

    pl = inst.world.placed
    rack, plate = pl["dish_rack"], pl["plate"]
    rq, pq = state.objects[rack.body()], state.objects[plate.body()]
    if not _upright(rq.orientation):
        return False, "rack_tipped"
    hx, hy, tines = rack_box(rack.asset.params)
    h = float(plate.asset.params["height"])
    c = np.asarray(pq.position, float) + 0.5 * h * np.array(_axis(pq.orientation))  # the plate's centre
    yaw = _yaw(rq.orientation)
    d = c[:2] - np.asarray(rq.position[:2], float)
    u = math.cos(yaw) * d[0] + math.sin(yaw) * d[1]
    v = -math.sin(yaw) * d[0] + math.cos(yaw) * d[1]
    if abs(u) > hx or abs(v) > hy:
        return False, "object_not_in_container"
    if float(pq.position[2]) > float(rq.position[2]) + tines + REST_ABOVE:
        return False, "not_resting"
    if _tilt_cos(pq.orientation) < math.cos(math.radians(30.0)):
        return False, "plate_tipped"
    if not _released(state, plate.body()):
        return False, "object_still_held"
    return True, ""


def _axis(q) -> tuple[float, float, float]:
    """The body's +Z in the world (q: w, x, y, z)."""
    w, x, y, z = (float(v) for v in q)
    return (2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y))


def place_in_rack(inst, d) -> None:
    """The expert (see the module doc)."""

    from stages.demos.counter import facing_north_goal
    from stages.demos.driver import stow
    from stages.demos.record import base_pose
    from stages.simulate.control import top_down
    from stages.simulate.state import read_state

    w = inst.world
    pl = w.placed
    plate, rack = pl["plate"], pl["dish_rack"]
    p = plate.asset.params
    r, h, rf = float(p["radius"]), float(p["height"]), float(p["radius"]) * float(p["well_ratio"])
    front = float(w.table_rect[1])
    top = float(w.table_z)
    st = read_state(d.sim)
    pxy = np.asarray(st.objects[plate.body()].position[:2], float)
    rq = st.objects[rack.body()]
    rxy = np.asarray(rq.position[:2], float)
    hx, hy, tines = rack_box(rack.asset.params)
    goal = facing_north_goal(front, float(0.5 * (pxy[0] + rxy[0])), gap=BASE_GAP)
    bx, by, th = base_pose(d.sim)
    if abs(by - goal[1]) < 0.15 and abs(math.remainder(th - goal[2], 2 * math.pi)) < 0.2:
        stow(d)  # still before the counter (the wipe): sideways along it, no planning (its floor is blocked)
        d.drive_straight(goal)
    else:
        d.drive_to(goal, w.grid(), tuck=stow(d, on_the_way=True))

    # 1. slide the plate towards the robot until its near rim overhangs the counter's front edge
    a = math.radians(DRAG_PITCH)
    tilt = np.array([[1.0, 0.0, 0.0], [0.0, math.cos(a), -math.sin(a)], [0.0, math.sin(a), math.cos(a)]])
    drag = tilt @ top_down(0.5 * math.pi)  # fingers side by side along world X, open: two points behind the rim
    d.grip(0.0, 0.2)
    tcp_z = top + DRAG_TIP + TIP_PAST * math.cos(a)
    behind = pxy[1] + r + 0.025
    d.move(_pose([pxy[0], behind, top + 0.05], drag), 1.5, segments=3, settle=0.1, tol=APPROACH_TOL)
    d.move(_pose([pxy[0], behind, tcp_z], drag), 0.8, segments=2, settle=0.1)
    goal_y = front - OVERHANG + r  # the plate's centre
    end = goal_y + r - 0.005  # (the fingers' faces ~1 cm before the TCP; they yield ~1 cm)
    d.move(_pose([pxy[0], end, tcp_z], drag), max(0.8, (behind - end) / 0.08), segments=4, settle=0.2)
    d.move(_pose([pxy[0], end + 0.01, top + 0.10], drag), 0.6, segments=2, tol=APPROACH_TOL)
    low = top < LOW_TOP
    if low:
        bx, by, th = base_pose(d.sim)
        d.drive_straight((bx, by - GRASP_BACK, th))
    st = read_state(d.sim)
    pq = st.objects[plate.body()]
    pxy = np.asarray(pq.position[:2], float)
    over = front - (pxy[1] - r)
    if over < 0.015:
        raise ExpertFailure("not_dragged", f"the plate's rim overhangs {over * 1000:.0f} mm")

    # 2. the overhanging rim between the fingers: one under it, one on top
    rot = rim_rot(0.0)
    tip_y = front - GRASP_IN + TIP_PAST  # the fingertips' reach
    rho = max(float(pxy[1]) - (front - GRASP_IN), rf)  # the plate's radius under the TCP
    under = h * float(np.clip((rho - rf) / max(r - rf, 1e-3), 0.0, 1.0))  # its underside there
    gz = float(pq.position[2]) + 0.5 * (h + under)
    at = np.array([pxy[0], tip_y - TIP_PAST, gz])
    # turned to the rim grasp clear of the plate (a straight move down from over it swept it off the top)
    d.move(_pose([at[0], front - 0.12, top + 0.14], rot), 1.5, segments=3, tol=APPROACH_TOL)
    d.move(_pose(at - [0, 0.07 if low else 0.10, 0], rot), 1.0, segments=2, settle=0.1, tol=APPROACH_TOL)
    d.move(_pose(at, rot), 0.8, segments=2, settle=0.2)
    d.grip(1.0, 0.8)
    d.move(_pose(at + [0, 0, 0.04], rot), 0.8, segments=2, carry=True)
    st = read_state(d.sim)
    pq = st.objects[plate.body()]
    if float(pq.position[2]) < top + 0.02:
        raise ExpertFailure("grasp_missed", f"plate at {np.round(pq.position, 3)}")
    off = np.asarray(pq.position[:2], float) - at[:2]  # plate origin from the TCP, as held

    # 3. over the rack, down to DROP above the tines, let go
    rz = float(rq.position[2])
    goal = np.array([rxy[0], rxy[1] - hy + PLATE_IN + r])  # the plate's centre on the rack
    tcp = goal - off
    lift = float(pq.position[2]) - (at[2] + 0.04)  # plate origin below the TCP (< 0)
    carry_z = rz + tines + 0.08 - lift
    here = at + [0, 0, 0.04]
    d.move(_pose([here[0], here[1], carry_z], rot), 1.0, segments=2, carry=True, tol=APPROACH_TOL)
    d.move(_pose([tcp[0], tcp[1], carry_z], rot), 2.0, segments=3, carry=True, tol=APPROACH_TOL)
    d.move(_pose([tcp[0], tcp[1], rz + tines + DROP - lift], rot), 1.0, segments=2, carry=True, settle=0.2)
    d.grip(0.0, 0.6)
    d.step(0.3)
    d.move(_pose([tcp[0], tcp[1] - 0.10, rz + tines + DROP - lift + 0.02], rot), 0.8, segments=2,
           tol=APPROACH_TOL)
    d.move(_pose([tcp[0], tcp[1] - 0.15, rz + tines + 0.15], rot), 0.8, segments=2, tol=APPROACH_TOL)
    stow(d)

