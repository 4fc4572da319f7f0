"""The shelve-book skill (issue 16, organize books): a book standing on the coffee table put
standing on a board of the living room's bookshelf (tasks ``shelve_book_1``, ``shelve_book_2``: the
world's roles "book_1", "book_2"; the multistage task ``organize_books`` runs one stage per book), in
a generated living room (:mod:`stages.demos.house_living`: the coffee table's free side facing -Y,
the bookshelf's boards as ``shelves``).

The catalog's books (:func:`asset_catalog.generators.objects.book`: length along local X, width
along Y with the spine at -Y, thickness along Z, lying flat) are 110-190 mm wide, more than the Franka
hand's 80 mm stroke, but 10-50 mm thick: the household rules put books :data:`THICKNESS` thick on
the coffee table, and the task stands them upright there, spine up (local -Y to world +Z), their length
along the table's depth, so that a hand over the spine grasps one across its covers.

- :func:`book_setup`: the episode's poses: the books standing on the table's near band east of the
  paper's spot, :data:`BOOK_DX` apart, their near ends :data:`BOOK_IN` behind the top's front edge;
  the paper parked on its spot (``skill_trash.PAPER_AT``). A start pose may carry a roll
  (:func:`stages.demos.sampling.object_coords`);
- :func:`shelf_spot`: where book k goes: the board :data:`BOARD_Z` high (nearest
  :data:`BOARD_PREFER`) with :data:`HAND_ROOM` above the tallest book, the books side by side
  :data:`SPOT_DX` apart across it, their centres :data:`EDGE_IN` behind its front edge, length along
  the shelf's depth (the near end stands out of the shelf by up to 6 cm: the arm over a book set
  deeper meets the board above);
- :func:`shelve_book` (the expert): the base :data:`REACH_TABLE` behind the book's centre, the hand
  pitched :data:`PITCH` down over it (a joint-space reach: a straight path from the tucked hand turns
  the wrist through its limits) grasps it across its covers :data:`GRIP_DOWN` below the spine, above
  its centre of mass (held by one end, the 0.5-1 kg book swung down in the fingers); lift, raise it
  :data:`RAISE` over the table, carry it high by the base (:data:`CARRY`), drive before the bookshelf
  (:func:`stages.demos.base_approach.staging`), hold it :data:`LIFT` over the board's height, drive
  straight in, set it down on its spot, release, draw the open fingers out along its covers, back
  out the way in;
- :func:`shelve_book_success` (the predicate): the book's centre over a board (1 cm in), its
  lowest corner within 2 cm of that board, its spine within 25 deg of up, the hand open wider than
  the book and away from it.

Frame: world, Z up, metres, radians.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np

from stages.demos.driver import APPROACH_TOL, ExpertFailure

log = logging.getLogger(__name__)

THICKNESS = (0.02, 0.046)  # books this thick [m] stand (>= 20 mm) and fit the hand's 80 mm stroke
BOOKS = 2                  # books a living room needs for organize_books
BOOK_X0 = 0.30             # the first book's centre this far [m] in from the table top's west end
BOOK_DX = 0.20             # the books' centres this far apart [m] along the table (0.14: the hand over
                           # the first one turned the second by 25-45 deg)
BOOK_IN = 0.07             # a book's near end this far [m] behind the table top's front edge
BOARD_Z = (0.45, 1.15)     # boards this high [m] take a book from the pitched hand
BOARD_PREFER = 0.75        # of those, the one nearest this height [m]
HAND_ROOM = 0.11           # free height above a standing book a board needs [m] (the pitched hand over it)
SPOT_DX = 0.15             # the books' centres this far apart [m] across the board
GRIP_DOWN = 0.025          # the fingers' centre this far [m] below the spine, over the book's centre (a grasp
                           # at its near end let the 0.5-1 kg book swing down in the fingers)
PITCH = 60.0               # the hand pitched down [deg]: the pads reach 25 mm down the covers below the spine
                           # (at 30 deg the hand met the spine first; a level hand low before the base: ik_unreachable)
PRE = 0.12                 # the grasp approached from this far [m] back along the hand
REACH_TABLE = 0.66         # the grasp's TCP this far [m] ahead of the base's centre (nearer: ik_unreachable)
REACH_SHELF = 0.66         # the place's TCP this far [m] ahead of the base's centre
RAISE = 0.10               # the lifted book raised this far [m] over the table before it is carried off
LIFT = 0.025               # the book lifted / held this far [m] above the table or board
STAGE = 0.25               # the drive before the bookshelf ends at least this far [m] back (base_approach.staging:
                           # further back or aside where that is blocked), straight in after
EDGE_IN = 0.06             # the book set down with its centre this far [m] behind the board's front edge
CARRY = (0.35, 1.0)        # the carried TCP this far ahead of the base's centre, this high [m] while driving
BACK = 0.10                # the base backs at least this far [m] from the table before it turns
HOLD = 0.50                # the carried TCP this far [m] ahead of the base's centre while driving in


def book_roles(world) -> list[str]:
    """The world's book roles in stage order ("book_1", "book_2", ...)."""
    return sorted(r for r in world.placed if r.startswith("book_"))


def book_dims(placed) -> tuple[float, float, float]:
    """(length, standing height, thickness) [m] of a book package (its local X, Y, Z extents)."""
    lo, hi = np.asarray(placed.asset.lo, float), np.asarray(placed.asset.hi, float)
    return float(hi[0] - lo[0]), float(hi[1] - lo[1]), float(hi[2] - lo[2])


def _quat(yaw: float, roll: float) -> tuple[float, float, float, float]:
    """(w, x, y, z) of a roll about the body's X, then a yaw about world Z."""
    cz, sz, cx, sx = math.cos(yaw / 2), math.sin(yaw / 2), math.cos(roll / 2), math.sin(roll / 2)
    return (cz * cx, cz * sx, sz * sx, sz * cx)


def _rot(q) -> np.ndarray:
    w, x, y, z = (float(v) for v in q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


STAND_ROLL = -math.pi / 2  # roll about local X that stands a book spine up (local -Y to +Z)


def standing_pose(placed, centre_xy, bottom_z: float, yaw: float) -> tuple:
    """The start pose (x, y, z, yaw, roll) of a book standing spine up with its bounds' centre at
    ``centre_xy`` (2,) [m] and its fore-edge at ``bottom_z`` [m], its length along ``yaw``."""
    lo, hi = np.asarray(placed.asset.lo, float), np.asarray(placed.asset.hi, float)
    r = _rot(_quat(yaw, STAND_ROLL))
    c = r @ (0.5 * (lo + hi))
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]) @ r.T
    return (float(centre_xy[0] - c[0]), float(centre_xy[1] - c[1]), float(bottom_z - corners[:, 2].min()),
            float(yaw), STAND_ROLL)


def book_setup(world, seed: int) -> dict:
    """The episode's object poses (body -> (x, y, z, yaw[, roll])): the books standing on the
    table's near band, the paper on its spot (its own random stream: the other draws do not change).
    ItemError when the world has fewer than :data:`BOOKS` books."""
    from pipeline.types import ItemError
    from stages.demos.skill_trash import PAPER_AT

    roles = book_roles(world)
    if len(roles) < BOOKS:
        raise ItemError(f"{world.usd}: organize_books needs {BOOKS} books {THICKNESS[0] * 1000:.0f}-"
                        f"{THICKNESS[1] * 1000:.0f} mm thick in the living room, found {len(roles)}")
    rng = np.random.default_rng([int(seed), 15, 3])
    x0, y0, _, _ = world.table_rect
    out = {}
    for k, role in enumerate(roles):
        b = world.placed[role]
        length, _, _ = book_dims(b)
        c = (x0 + BOOK_X0 + k * BOOK_DX + float(rng.uniform(-0.01, 0.01)),
             y0 + BOOK_IN + 0.5 * length + float(rng.uniform(0.0, 0.015)))
        out[b.body()] = standing_pose(b, c, world.table_z + 0.001, math.pi / 2 + float(rng.uniform(-0.06, 0.06)))
    if "paper" in world.placed:
        p = world.placed["paper"]
        out[p.body()] = (x0 + PAPER_AT[0], y0 + PAPER_AT[1], world.table_z + 0.002, float(rng.uniform(-np.pi, np.pi)))
    return out


@dataclass(frozen=True)
class ShelfSpot:
    """Where a book goes. board: the world's shelf tuple (xmin, ymin, xmax, ymax, z, clear height);
    centre (x, y) [m]: the book's bounds' centre there; front (2,): the bookshelf's outward
    front normal; edge (x, y) [m]: the board's front edge point before the spot."""

    board: tuple
    centre: tuple[float, float]
    front: tuple[float, float]
    edge: tuple[float, float]


def shelf_spot(world, k: int) -> ShelfSpot:
    """The :class:`ShelfSpot` of book ``k`` (0-based); ExpertFailure("no_board") when no board is
    reachable with room for the world's books."""
    shelf = world.placed.get("bookshelf")
    if shelf is None or not world.shelves:
        raise ExpertFailure("no_board", "the living room has no bookshelf")
    dims = [book_dims(world.placed[r]) for r in book_roles(world)]
    tall = max(d[1] for d in dims)
    deep = max(d[0] for d in dims)
    n = np.array([math.cos(shelf.yaw), math.sin(shelf.yaw)])  # the asset's +X: its open front
    lat = np.array([-n[1], n[0]])
    ok = []
    for b in world.shelves:
        x0, y0, x1, y1, z, clear = b
        depth = abs(float(np.dot([x1 - x0, y1 - y0], np.abs(n))))
        width = abs(float(np.dot([x1 - x0, y1 - y0], np.abs(lat))))
        if (BOARD_Z[0] <= z <= BOARD_Z[1] and clear >= tall + HAND_ROOM and depth >= 0.5 * deep + EDGE_IN + 0.01
                and width >= (len(dims) - 1) * SPOT_DX + 2 * max(d[2] for d in dims) + 0.04):
            ok.append(b)
    if not ok:
        raise ExpertFailure("no_board", f"no board {BOARD_Z[0]}-{BOARD_Z[1]} m high with "
                                        f"{tall + HAND_ROOM:.2f} m above it and {0.5 * deep + EDGE_IN + 0.01:.2f} m deep")
    b = min(ok, key=lambda s: abs(s[4] - BOARD_PREFER))
    mid = np.array([0.5 * (b[0] + b[2]), 0.5 * (b[1] + b[3])])
    half_depth = 0.5 * abs(float(np.dot([b[2] - b[0], b[3] - b[1]], np.abs(n))))
    edge = mid + half_depth * n + ((k - 0.5 * (len(dims) - 1)) * SPOT_DX) * lat
    centre = edge - EDGE_IN * n
    return ShelfSpot(board=b, centre=(float(centre[0]), float(centre[1])), front=(float(n[0]), float(n[1])),
                     edge=(float(edge[0]), float(edge[1])))


def book_state(state, placed) -> tuple[np.ndarray, np.ndarray]:
    """The book's bounds' centre (3,) [m] and rotation (3, 3) in the world at ``state``."""
    o = state.objects[placed.body()]
    r = _rot(o.orientation)
    c = 0.5 * (np.asarray(placed.asset.lo, float) + np.asarray(placed.asset.hi, float))
    return np.asarray(o.position, float) + r @ c, r


def shelve_book_success(inst, state, peaks=None, k: int = 0) -> tuple[bool, str]:
    """Book ``k``'s centre over a board of the bookshelf (1 cm in from its edges), its lowest
    corner within 2 cm of that board, spine within 25 deg of up, the hand open and away from it."""
    w = inst.world
    roles = book_roles(w)
    if k >= len(roles):
        return False, "no_book"
    b = w.placed[roles[k]]
    c, r = book_state(state, b)
    _, tall, thick = book_dims(b)
    lo, hi = b.asset.lo, b.asset.hi
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])], float)
    low = float(state.objects[b.body()].position[2]) + float((corners @ r.T)[:, 2].min())
    board = next((s for s in w.shelves if s[0] + 0.01 <= c[0] <= s[2] - 0.01 and s[1] + 0.01 <= c[1] <= s[3] - 0.01
                  and abs(low - s[4]) <= 0.02), None)
    if board is None:
        return False, "not_on_shelf"
    if float(-r[2, 1]) < math.cos(math.radians(25.0)):  # local -Y (the spine) against world +Z
        return False, "book_tipped"
    ee = np.asarray(state.robot.ee_pose.position, float)
    if state.robot.gripper_opening < thick + 0.01 or float(np.linalg.norm(ee - c)) < 0.5 * tall:
        return False, "object_still_held"
    return True, ""


def shelve_book_1_success(inst, state, peaks=None) -> tuple[bool, str]:
    return shelve_book_success(inst, state, peaks, 0)


def shelve_book_2_success(inst, state, peaks=None) -> tuple[bool, str]:
    return shelve_book_success(inst, state, peaks, 1)


def _pose_text(state, placed) -> str:
    c, r = book_state(state, placed)
    return f"centre {np.round(c, 3).tolist()} spine-up {-r[2, 1]:.3f} length axis {np.round(r[:, 0], 2).tolist()}"


def _reach(d, target_world: np.ndarray, duration: float) -> None:
    """The hand to ``target_world`` (4x4) by a joint-space move (linear in the arm's joints, as
    ``Driver.home``) to the IK solution nearest the arm's targets among a warm-started one and
    restarts (a straight Cartesian path from the tucked, top-down hand to a pitched one low before
    the table turns the wrist through its limits: ik_unreachable)."""
    from stages.simulate.control import Clik

    q0 = d.ik.with_arm(d.ik.from_sim(d.sim), d.ctl.arm_targets())
    goal = Clik.world_to_root(d.sim.spawn, target_world)
    sols = [d.ik.solve(goal, q0, max_iters=600),
            d.ik.solve(goal, q0, max_iters=600, restarts=24, rng=np.random.default_rng(7))]
    ok = [r for r in sols if r.position_error <= 0.005 and r.rotation_error <= math.radians(2.0)]
    if not ok:
        raise ExpertFailure("ik_unreachable", f"no arm pose reaches {np.round(target_world[:3, 3], 3).tolist()}")
    start = d.ctl.arm_targets()
    q1 = min((d.ik.arm_q(r.q) for r in ok), key=lambda q: float(np.abs(q - start).max()))
    d.cmd.mode = 1
    d.base((0.0, 0.0, 0.0))
    seconds = min(duration, max(d.pace.min_move, float(np.abs(q1 - start).max()) / d.pace.joint_speed))
    n = max(1, int(seconds / d.frame_dt))
    for i in range(1, n + 1):
        d.ctl.set_arm_targets(start + (q1 - start) * i / n)
        d.step(d.frame_dt)
    d.settle(0.2)


def shelve_book(inst, d, k: int) -> None:
    """The expert for book ``k`` (0-based; see the module doc)."""
    from stages.demos.counter import _pose
    from stages.demos.driver import stow
    from stages.demos.record import base_pose
    from stages.demos.base_approach import drive_in
    from stages.demos.skill_fridge import facing_rot
    from stages.simulate.state import read_state

    w = inst.world
    roles = book_roles(w)
    if k >= len(roles):
        raise ExpertFailure("no_book", f"the world has {len(roles)} books")
    b = w.placed[roles[k]]
    length, tall, thick = book_dims(b)
    if not THICKNESS[0] - 1e-6 <= thick <= THICKNESS[1] + 1e-6:
        raise ExpertFailure("object_too_wide", f"book {thick * 1000:.0f} mm thick")
    spot = shelf_spot(w, k)  # (fails early, before anything moves, when no board takes it)
    c, r = book_state(read_state(d.sim), b)
    along = r[:, 0] * (1.0 if r[1, 0] >= 0 else -1.0)  # its length axis, pointing away from the robot
    along = np.array([along[0], along[1], 0.0]) / max(float(np.linalg.norm(along[:2])), 1e-6)
    grasp = np.array([c[0], c[1], w.table_z + tall - GRIP_DOWN])
    # the base REACH_TABLE behind the grasp facing the table (+Y; a standing book creeps round its
    # vertical by up to ~45 deg in a stage: the hand turns with it, the base does not); its drive
    # staged where the other table skills' drives are (0.35 m behind their pose, 0.08 m before the top)
    goal = (float(grasp[0]), float(grasp[1] - REACH_TABLE), math.pi / 2)
    back = max(0.0, goal[1] - (w.table_rect[1] - 0.08 - 0.30 - 0.35))
    d.drive_to(goal, w.grid(), approach=back, tuck=stow(d, on_the_way=True))
    c, r = book_state(read_state(d.sim), b)
    grasp[:2] = c[:2]
    rot = facing_rot(along[:2], PITCH)
    ap = rot[:, 2]
    d.grip(0.0, 0.2)
    _reach(d, _pose(grasp - PRE * ap, rot), 2.5)
    d.move(_pose(grasp, rot), 1.0, segments=2, settle=0.2)
    d.grip(1.0, 0.8)
    d.move(_pose(grasp + [0, 0, LIFT], rot), 0.6, segments=1, carry=True)
    log.debug("book %d lifted: %s; opening %.4f, tcp %s", k, _pose_text(read_state(d.sim), b),
              read_state(d.sim).robot.gripper_opening, np.round(read_state(d.sim).robot.ee_pose.position, 3).tolist())
    if book_state(read_state(d.sim), b)[0][2] < c[2] + 0.5 * LIFT:
        raise ExpertFailure("grasp_missed", "the book stayed on the table")
    # raised clear of the table (drawn back low, a book swinging in the fingers met the table's edge
    # and fell: flat_003, seeds 3 and 5), held high near the base (its disc) while the base drives
    d.move(_pose(grasp + [0, 0, RAISE], rot), 1.0, segments=2, carry=True)
    bx, by, th = base_pose(d.sim)
    d.move(_pose([bx + CARRY[0] * math.cos(th), by + CARRY[0] * math.sin(th), CARRY[1]], rot), 1.2, segments=2,
           carry=True, tol=APPROACH_TOL)
    back = max(back, BACK)  # (to where its drive came straight in from: free for the planner)
    d.drive_straight((bx - back * math.cos(th), by - back * math.sin(th), th))
    # before the bookshelf: facing into it (-front), REACH_SHELF behind the TCP's place point; the
    # book held LIFT above the board's height HOLD ahead, then the base straight in
    n = np.asarray(spot.front)
    heading = math.atan2(-n[1], -n[0])
    place = np.asarray(spot.centre)
    goal_xy = place + REACH_SHELF * n
    goal = (float(goal_xy[0]), float(goal_xy[1]), heading)
    grid = w.grid()
    point, behind = drive_in(d, grid, goal, np.zeros((0, 2)), approach=STAGE, more=1.0, side=0.5)
    z = spot.board[4] + tall - GRIP_DOWN + LIFT + 0.003
    inward = facing_rot(-n, PITCH)
    bx, by, th = base_pose(d.sim)
    d.move(_pose([bx + HOLD * math.cos(th), by + HOLD * math.sin(th), z], inward), 1.5, segments=3, carry=True,
           tol=APPROACH_TOL)
    d.drive_straight(goal)
    log.debug("book %d before the shelf: %s", k, _pose_text(read_state(d.sim), b))
    # set down with its centre EDGE_IN behind the board's front edge (the arm over a book set 0.14 m
    # deep met the board above: not_on_shelf), the TCP keeping its offset from the book measured now
    st = read_state(d.sim)
    bc, _ = book_state(st, b)
    offset = np.asarray(st.robot.ee_pose.position, float) - bc
    n3 = np.array([*n, 0.0])
    first = np.array([*spot.centre, spot.board[4] + 0.5 * tall + 0.004])
    target = first + offset
    d.move(_pose(target + [0, 0, LIFT], inward), 1.5, segments=3, carry=True, tol=APPROACH_TOL)
    d.move(_pose(target, inward), 0.6, segments=1, carry=True, settle=0.2)
    log.debug("book %d set down: %s", k, _pose_text(read_state(d.sim), b))
    d.grip(0.0, 0.6)
    d.step(0.2)
    # the open fingers drawn out along the book (beside its covers) past its near end, then up
    out = target + (0.5 * length + 0.06) * n3
    d.move(_pose(out, inward), 1.0, segments=2, tol=APPROACH_TOL)
    d.move(_pose(out + [0, 0, 0.08], inward), 0.6, segments=1, tol=APPROACH_TOL)
    # back out the way in (onto free floor for the planner: the next drive starts there)
    d.drive_straight((*behind, heading))
    if math.dist(point, behind) > 0.02:
        d.drive_straight((*point, heading))
    d.home(1.0)


def shelve_book_1(inst, d) -> None:
    """The expert for the first book (:func:`shelve_book`)."""
    shelve_book(inst, d, 0)


def shelve_book_2(inst, d) -> None:
    """The expert for the second book (:func:`shelve_book`)."""
    shelve_book(inst, d, 1)
