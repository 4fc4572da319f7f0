"""Scripted experts of a humanoid (legged base walking by its policy, arms by CLIK) on the engine of
``stages.engine.humanoid``: programs ``expert(h, inst)`` that command a world through its
``WorldHandle`` and yield the control steps to wait.

Walking: A* on the task world's grid (``stages.demos.planner``), followed by the wheeled base's
``PathFollower`` (holonomic pure pursuit) giving (vx, vy, v_theta) in the base frame at the control
rate; the policy tracks them with a lag, so the follower runs slower and with softer gains than the
wheeled base's and its goal tolerance is the policy's (a few centimetres).

close_drawer (the counter's top drawer, left 60-85% open): walk to a standoff before the open
drawer's handle, facing it; manipulation mode (the policy holds the legs), the right hand's sphere
to just in front of the handle; then walk towards the counter with the hand held in the base frame
(the hand pushes the drawer while the body walks: the arm alone does not reach over the drawer's
travel of up to 0.34 m); manipulation mode again, the hand pushes 3 cm past the closed handle, then
pulls back 10 cm. Frame: world, Z up, metres, radians.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Generator
from dataclasses import dataclass
from typing import Any

import numpy as np

from stages.demos.driver import ExpertFailure

log = logging.getLogger(__name__)

LOCOMOTION, MANIPULATION = 0, 1


@dataclass(frozen=True, kw_only=True)
class WalkConfig:
    """The path follower of a walking base: speed limits and accelerations [m/s, rad/s, m/s^2,
    rad/s^2], gains [1/s], goal tolerances [m, rad], robot radius for planning [m], time limit [s]."""

    v_max: float = 0.5
    w_max: float = 0.8
    accel: float = 0.8
    alpha: float = 1.5
    k_pos: float = 2.0
    k_yaw: float = 2.0
    pos_tol: float = 0.04
    yaw_tol: float = 0.06
    radius: float = 0.3
    timeout_s: float = 25.0


@dataclass(frozen=True, kw_only=True)
class DrawerPushConfig:
    """close_drawer: the arm, the hand's place in the base frame while pushing (forward, left [m]),
    the standoff before the open handle [m], the push's overshoot past closed [m], the walking
    speed while pushing [m/s]."""

    arm: str = "right"
    reach: float = 0.32
    lateral: float = -0.16
    standoff: float = 0.10
    overshoot: float = 0.03
    push_speed: float = 0.2
    hand_radius: float = 0.045
    walk: WalkConfig = WalkConfig()


def _wait(n: int = 1) -> Generator[int, None, None]:
    yield n


def walk_to(h: Any, goal: tuple[float, float, float], cfg: WalkConfig, *, path: np.ndarray | None = None,
            grid: Any = None, straight: bool = False, until: Any = None) -> Generator[int, None, None]:
    """Walk (locomotion mode) along ``path`` (``straight``: the line from where the base stands; else
    an A* path on ``grid``) to ``goal`` = (x, y, yaw), or until ``until()`` holds;
    ExpertFailure("no_path" | "not_reached" | "fell")."""
    from stages.demos.planner import NoPathError, PathFollower, plan_path

    x, y, yaw = h.base_pose()
    if straight:
        path = np.array([[x, y], goal[:2]])
    elif path is None:
        try:
            path = plan_path(grid, (x, y), goal[:2], cfg.radius)
        except NoPathError as e:
            raise ExpertFailure("no_path", str(e)) from None
    f = PathFollower(path=np.asarray(path, float), goal_yaw=goal[2], v_max=cfg.v_max, w_max=cfg.w_max,
                     accel=cfg.accel, alpha=cfg.alpha, dt=h.dt, pos_tol=cfg.pos_tol, yaw_tol=cfg.yaw_tol,
                     k_pos=cfg.k_pos, k_yaw=cfg.k_yaw)
    h.set_mode(LOCOMOTION)
    for _ in range(int(cfg.timeout_s / h.dt)):
        cmd, done = f.command(*h.base_pose())
        if done or (until is not None and until()):
            h.set_command(0.0, 0.0, 0.0)
            return
        if h.base_height() < 0.5:
            raise ExpertFailure("fell", f"pelvis at {h.base_height():.2f} m")
        h.set_command(*cmd)
        yield 1
    h.set_command(0.0, 0.0, 0.0)
    x, y, yaw = h.base_pose()
    raise ExpertFailure("not_reached",
                        f"base at ({x:.2f}, {y:.2f}, {yaw:.2f}), goal {tuple(round(v, 2) for v in goal)}")


def hand_to(h: Any, arm: str, target: np.ndarray, *, tol: float = 0.02, timeout_s: float = 3.0,
            frame: str = "world") -> Generator[int, None, float]:
    """Set ``arm``'s target (4, 4) and wait until the hand is within ``tol`` [m] of it (or the
    timeout); returns the last error [m]."""
    h.set_ee_target(arm, target, frame=frame)
    err = math.inf
    for _ in range(int(timeout_s / h.dt)):
        yield 1
        got = h.ee_pose(arm)[:3, 3]
        want = target[:3, 3] if frame == "world" else _base_matrix(h) @ target[:, 3]
        err = float(np.linalg.norm(got - np.asarray(want)[:3]))
        if err < tol:
            break
    return err


def _base_matrix(h: Any) -> np.ndarray:
    """The base (pelvis) pose (4, 4) in the world, as the runtime's base frame."""
    from stages.locomotion.runtime import pose_matrices

    pos, quat, _, _ = h.rt.base_state(h.engine.sim.state)
    return pose_matrices(pos[h.world:h.world + 1].double().cpu().numpy(),
                         quat[h.world:h.world + 1].double().cpu().numpy())[0]


def _yaw_rot(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def close_drawer(h: Any, inst: Any, cfg: DrawerPushConfig = DrawerPushConfig()) -> Generator[int, None, None]:
    """The close_drawer expert (module docstring)."""
    part = inst.part
    q0 = h.joint_value(part.joint_path)
    out = -np.asarray(part.front, float)                  # the push direction (into the furniture)
    out[2] = 0.0
    out /= np.linalg.norm(out)
    yaw = math.atan2(out[1], out[0])
    left = np.array([-out[1], out[0], 0.0])
    handle_open, handle_closed = part.handle_at(q0), part.handle_at(part.closed)
    contact = cfg.hand_radius + part.grip_width / 2 + 0.005  # sphere centre before the bar's axis
    # the base where the hand, at (reach, lateral) in the base frame, is `standoff` before the open handle
    pre_hand = handle_open - out * (contact + cfg.standoff)
    base_pre = pre_hand - out * cfg.reach - left * cfg.lateral
    yield from walk_to(h, (float(base_pre[0]), float(base_pre[1]), yaw), cfg.walk, grid=inst.world.grid())

    # manipulation: the hand to the pre-push point, orientation as it is
    h.set_mode(MANIPULATION)
    yield from _wait(10)
    hand = h.ee_pose(cfg.arm)
    target = hand.copy()
    target[:3, 3] = pre_hand
    err = yield from hand_to(h, cfg.arm, target, tol=0.025, timeout_s=4.0)
    if err > 0.06:
        raise ExpertFailure("hand_not_placed", f"hand {err * 1000:.0f} mm from the pre-push point")
    log.debug("close_drawer: hand at the pre-push point (%.0f mm), drawer %.3f m", err * 1000,
              h.joint_value(part.joint_path))

    # push while walking: the hand held in the base frame, the base to where the hand is past closed
    hand_b = np.linalg.inv(_base_matrix(h)) @ h.ee_pose(cfg.arm)
    h.set_ee_target(cfg.arm, hand_b, frame="base")
    end_hand = handle_closed + out * (cfg.overshoot - contact)
    offset = _yaw_rot(yaw) @ np.array([hand_b[0, 3], hand_b[1, 3], 0.0])
    base_end = end_hand - offset
    push_walk = WalkConfig(**{**cfg.walk.__dict__, "v_max": cfg.push_speed, "timeout_s": 8.0})
    closed = lambda: h.joint_value(part.joint_path) - part.closed < 0.005  # noqa: E731
    try:
        yield from walk_to(h, (float(base_end[0]), float(base_end[1]), yaw), push_walk, straight=True,
                           until=closed)
    except ExpertFailure as e:
        if e.reason != "not_reached":
            raise
    log.debug("close_drawer: push walk ended, base %s, drawer %.3f m", h.base_pose(),
              h.joint_value(part.joint_path))
    # finish with the arm from where the base stands
    h.set_mode(MANIPULATION)
    yield from _wait(10)
    target = h.ee_pose(cfg.arm).copy()
    target[:3, 3] = end_hand
    yield from hand_to(h, cfg.arm, target, tol=0.01, timeout_s=2.0)
    yield from _wait(int(0.5 / h.dt))
    # back off 10 cm
    target[:3, 3] = end_hand - out * 0.10
    yield from hand_to(h, cfg.arm, target, tol=0.02, timeout_s=2.0)


@dataclass(frozen=True, kw_only=True)
class LeafPushConfig:
    """Closing a vertically hinged leaf by sweeping a hand along it: the push point's place on the
    leaf (fraction of the hinge-to-handle distance), the sweep's middle in the base frame (forward
    [m], |lateral| [m] towards the pushing hand's side), the sweep rate [rad/s], the overshoot past
    closed [rad], the approach offset off the leaf [m]."""

    along: float = 0.6
    reach: float = 0.27
    lateral: float = 0.2
    rate: float = 0.5
    overshoot: float = 0.08
    approach: float = 0.08
    hand_radius: float = 0.045
    back: float = 0.0
    """> 0: first walk to a point this far [m] behind the stance (away from the furniture), then
    straight ahead onto it, so that hands at the leaf's height (the H1's) do not sweep into the open
    leaf on a path along the furniture's front"""
    walk: WalkConfig = WalkConfig()


#: LeafPushConfig per embodiment spec (others: the defaults, tuned on the G1). The H1's policy
#: (h1_velocity, iteration 4,767) does not act on the follower's last few cm/s and rad/s: its base
#: stopped 3 cm and 0.06 rad short of the stance in 5 of 30 episodes, so its tolerances are wider;
#: walking in 0.2 m beside the leaf's middle, its pushing hand (at the leaf's height) knocked the
#: open leaf to its stop in 11 of 30, so it stands 0.3 m beside it (0.26 and 0.32: 30/30 each).
LEAF_PUSH = {"h1": LeafPushConfig(back=0.6, reach=0.2, lateral=0.3,
                                  walk=WalkConfig(pos_tol=0.05, yaw_tol=0.09))}


def close_leaf(h: Any, inst: Any, cfg: LeafPushConfig | None = None) -> Generator[int, None, None]:
    """Close a vertically hinged door (the microwave's) with one hand: walk to a stance beside the
    open leaf, facing the furniture; the hand's sphere onto the leaf's outer face (``along`` of the
    way from the hinge to the handle), then swept along the leaf's arc to ``overshoot`` past closed
    at ``rate``, a few degrees ahead of the leaf; the hand backs off 10 cm."""
    cfg = cfg or LEAF_PUSH.get(h.engine.spec.name, LeafPushConfig())
    part = inst.part
    if part.kind != "revolute" or abs(part.axis[2]) < 0.9:
        raise ExpertFailure("no_expert", f"{part.joint_path} is not a vertically hinged leaf")
    q0 = h.joint_value(part.joint_path)
    out = -np.asarray(part.front, float)
    out[2] = 0.0
    out /= np.linalg.norm(out)
    yaw = math.atan2(out[1], out[0])
    left = np.array([-out[1], out[0], 0.0])
    origin, handle = np.asarray(part.origin, float), np.asarray(part.handle, float)
    radial = handle - origin
    radial[2] = 0.0
    p_closed = origin + cfg.along * radial + np.asarray(part.front) * (cfg.hand_radius + 0.005)
    p_closed[2] = handle[2]

    def centre(q: float) -> np.ndarray:
        return part.point_at(p_closed, q)

    # the pushing hand: on the side the leaf's free edge moves to while closing
    closing = centre(q0 - 0.05) - centre(q0)
    arm, side = ("right", -1.0) if float(closing @ left) < 0.0 else ("left", 1.0)
    mid = centre(0.5 * q0)
    base = mid - out * cfg.reach - left * side * cfg.lateral
    if cfg.back > 0.0:
        pre = base - out * cfg.back
        yield from walk_to(h, (float(pre[0]), float(pre[1]), yaw), cfg.walk, grid=inst.world.grid())
        yield from walk_to(h, (float(base[0]), float(base[1]), yaw), cfg.walk, straight=True)
    else:
        yield from walk_to(h, (float(base[0]), float(base[1]), yaw), cfg.walk, grid=inst.world.grid())
    h.set_mode(MANIPULATION)
    yield from _wait(10)
    q = h.joint_value(part.joint_path)
    target = h.ee_pose(arm).copy()
    normal = part.front_at(q)                              # outward normal of the leaf's outer face
    target[:3, 3] = centre(q) + normal * cfg.approach
    yield from hand_to(h, arm, target, tol=0.025, timeout_s=4.0)
    target[:3, 3] = centre(q)
    err = yield from hand_to(h, arm, target, tol=0.02, timeout_s=2.0)
    if err > 0.05:
        raise ExpertFailure("hand_not_placed", f"hand {err * 1000:.0f} mm from the leaf")
    q_cmd = q
    step = cfg.rate * h.dt
    while q_cmd > part.closed - cfg.overshoot:
        q_cmd = max(part.closed - cfg.overshoot, min(q_cmd, h.joint_value(part.joint_path) + 0.15) - step)
        target[:3, 3] = centre(q_cmd)
        h.set_ee_target(arm, target)
        yield 1
    yield from _wait(int(0.8 / h.dt))
    log.debug("close_leaf: leaf at %.3f rad after the sweep", h.joint_value(part.joint_path))
    target[:3, 3] = centre(part.closed) - out * 0.10
    yield from hand_to(h, arm, target, tol=0.02, timeout_s=2.0)


@dataclass(frozen=True, kw_only=True)
class HandPickConfig:
    """Picking an upright object (a mug) with a hand (the Dex3: the object between the palm, the
    thumb behind it and the two fingers curling around its front) and placing it in a container.

    arm; reach / lateral: the object's place in the base frame at the grasp (forward, left [m]);
    grasp_offset: the object's axis in the end-effector frame of the right hand (the left hand
    mirrors y) [m]: the Dex3 palm faces the hand's +y (right hand), the open thumb stands out of
    it 0.07 m behind the end-effector frame, the straight fingers run ahead along x, so a mug of
    3.7 cm radius with its axis 6.6 cm off the palm's centre plane and 3.5 cm ahead of the frame
    clears the thumb by 2.2 cm and the fingers by 1.5 cm as the hand comes down around it (with
    1 cm, a 1 cm hand error put the thumb on the rim: 2 of 10 episodes; with 1.7 cm 1 of 20);
    grasp_height: the
    end-effector frame above the object's base [m];
    above: the pre-grasp height over the grasp [m]; lift [m]; release_height: the object's base
    above the container's base when the hand opens [m]; approach: the straight walk-in from a
    standoff to the stance [m]; side_speed: the walking speed while carrying [m/s]; close_s: the
    hand's command ramps from open to closed over this time [s]; hold_s: then held closed before
    the lift [s]; open_s: the hand's command ramps back to open over this time [s]."""

    arm: str = "right"
    reach: float = 0.32
    lateral: float = -0.08
    grasp_offset: tuple[float, float, float] = (0.035, 0.066, 0.0)
    grasp_height: float = 0.055
    above: float = 0.10
    lift: float = 0.13
    release_height: float = 0.035
    approach: float = 0.35
    side_speed: float = 0.2
    close_s: float = 1.2
    hold_s: float = 0.4
    open_s: float = 0.6
    carry_hand: tuple[float, float, float] = (0.24, -0.16, 0.16)
    """the grasping hand's end-effector frame in the base frame while walking in (forward, left,
    up [m] from the pelvis; the right hand's, the left mirrors): above the table top, clear of its edge"""
    idle_hand: tuple[float, float, float] = (0.12, 0.24, 0.10)
    """the other hand's (the left's; the right mirrors), out of the way above the table's height"""
    walk: WalkConfig = WalkConfig()


def _inward_normal(rect: tuple[float, float, float, float], xy: np.ndarray) -> np.ndarray:
    """The inward unit normal (3,) of the edge of ``rect`` = (x0, y0, x1, y1) nearest to ``xy``."""
    x0, y0, x1, y1 = rect
    d = {(1.0, 0.0): xy[0] - x0, (-1.0, 0.0): x1 - xy[0], (0.0, 1.0): xy[1] - y0, (0.0, -1.0): y1 - xy[1]}
    n = min(d, key=d.get)
    return np.array([n[0], n[1], 0.0])


def _grasp_pose(centre: np.ndarray, forward: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """The end-effector pose (4, 4) that puts the object's axis point ``centre`` (3,) at ``offset``
    (3,) in the hand frame, the hand's x along ``forward`` (horizontal), z up."""
    up = np.array([0.0, 0.0, 1.0])
    rot = np.stack([forward, np.cross(up, forward), up], axis=1)
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = rot, centre - rot @ offset
    return t


def pick_place_hand(h: Any, inst: Any, cfg: HandPickConfig = HandPickConfig()) -> Generator[int, None, None]:
    """pick_place_bowl with a hand: walk to a standoff before the table edge nearest the object,
    then straight in to the stance (the object at ``reach``, ``lateral`` in the base frame);
    manipulation mode: the open hand above the object, down around it, closed, lifted; walk
    sideways with the hand held in the base frame until the object is at the same place over the
    container; lower it into the container (where it stops on the container's floor the hand
    eases 5 mm up: opening a hand that presses the mug into a curved bowl tipped it), open, the
    hand up."""
    if cfg.arm not in h.rt.hands.arms:
        raise ExpertFailure("no_hand", f"the {cfg.arm} arm of {h.rt.spec.name} has no hand to grasp with")
    w = inst.world
    obj, box = w.placed["mug"].body(), w.placed["bowl"].body()
    m = np.asarray(h.object_pose(obj).position, float)
    c = np.asarray(h.object_pose(box).position, float)
    fwd = _inward_normal(w.table_rect, m[:2])
    yaw = math.atan2(fwd[1], fwd[0])
    left = np.array([-fwd[1], fwd[0], 0.0])
    off = np.asarray(cfg.grasp_offset) * (1.0, 1.0 if cfg.arm == "right" else -1.0, 1.0)
    base1 = m - fwd * cfg.reach - left * cfg.lateral
    stand = base1 - fwd * cfg.approach
    yield from walk_to(h, (float(stand[0]), float(stand[1]), yaw), cfg.walk, grid=w.grid())
    # both hands up, held in the base frame (a hand at its default pose is under the table top)
    sign = 1.0 if cfg.arm == "right" else -1.0
    other = "left" if cfg.arm == "right" else "right"
    for arm, (fx, fy, fz) in ((cfg.arm, cfg.carry_hand), (other, cfg.idle_hand)):
        t = np.eye(4)
        t[:3, 3] = (fx, fy * sign, fz)
        h.set_ee_target(arm, t, frame="base")
    h.set_mode(MANIPULATION)
    yield from _wait(int(1.5 / h.dt))
    yield from walk_to(h, (float(base1[0]), float(base1[1]), yaw), cfg.walk, straight=True)

    h.set_mode(MANIPULATION)
    yield from _wait(10)
    up = np.array([0.0, 0.0, 1.0])
    m = np.asarray(h.object_pose(obj).position, float)
    grasp = _grasp_pose(m + up * cfg.grasp_height, fwd, off)
    pre = grasp.copy()
    pre[:3, 3] += up * cfg.above
    yield from hand_to(h, cfg.arm, pre, tol=0.015, timeout_s=4.0)
    err = yield from hand_to(h, cfg.arm, grasp, tol=0.008, timeout_s=3.0)
    if err > 0.03:
        raise ExpertFailure("hand_not_placed", f"hand {err * 1000:.0f} mm from the grasp")
    yield from _wait(10)
    n = max(1, int(cfg.close_s / h.dt))
    for i in range(n):                                  # a ramp: a sudden close knocks the object over
        h.set_hand(cfg.arm, (i + 1) / n)
        yield 1
    yield from _wait(int(cfg.hold_s / h.dt))
    lifted = grasp.copy()
    lifted[:3, 3] += up * cfg.lift
    yield from hand_to(h, cfg.arm, lifted, tol=0.015, timeout_s=3.0)
    z = h.object_pose(obj).position[2]
    if z < m[2] + 0.5 * cfg.lift:
        raise ExpertFailure("object_not_lifted", f"object base {1000 * (z - m[2]):.0f} mm above its start")

    # carry: walk sideways with the hand held in the base frame
    hand_b = np.linalg.inv(_base_matrix(h)) @ h.ee_pose(cfg.arm)
    h.set_ee_target(cfg.arm, hand_b, frame="base")
    x, y, _ = h.base_pose()
    shift = c - m
    shift[2] = 0.0
    base2 = np.array([x, y, 0.0]) + shift
    carry = WalkConfig(**{**cfg.walk.__dict__, "v_max": cfg.side_speed, "timeout_s": 10.0})
    yield from walk_to(h, (float(base2[0]), float(base2[1]), yaw), carry, straight=True)
    h.set_mode(MANIPULATION)
    yield from _wait(10)
    p = np.asarray(h.object_pose(obj).position, float)
    if p[2] < m[2] + 0.5 * cfg.lift:
        raise ExpertFailure("object_dropped", f"object base {1000 * (p[2] - m[2]):.0f} mm above the table")

    # place: over the container, down, open, up
    over = _grasp_pose(np.array([c[0], c[1], m[2] + cfg.grasp_height + cfg.lift]), fwd, off)
    yield from hand_to(h, cfg.arm, over, tol=0.012, timeout_s=3.0)
    down = _grasp_pose(np.array([c[0], c[1], c[2] + cfg.release_height + cfg.grasp_height]), fwd, off)
    yield from hand_to(h, cfg.arm, down, tol=0.012, timeout_s=3.0)
    rest = down.copy()                                  # the object sits: stop pressing it down
    rest[:3, 3] = h.ee_pose(cfg.arm)[:3, 3] + up * 0.005
    yield from hand_to(h, cfg.arm, rest, tol=0.004, timeout_s=0.5)
    n = max(1, int(cfg.open_s / h.dt))
    for i in range(n):
        h.set_hand(cfg.arm, 1.0 - (i + 1) / n)
        yield 1
    yield from _wait(10)
    away = down.copy()
    away[:3, 3] += up * 0.12
    yield from hand_to(h, cfg.arm, away, tol=0.02, timeout_s=2.0)
    yield from _wait(int(0.5 / h.dt))


#: humanoid experts by task name
HUMANOID_EXPERTS = {"close_drawer": close_drawer, "close_microwave": close_leaf,
                    "pick_place_bowl": pick_place_hand}


def humanoid_program(h: Any, inst: Any) -> Generator[int, None, None]:
    """The engine's program: the task's humanoid expert; ExpertFailure("no_expert") for other tasks."""
    expert = HUMANOID_EXPERTS.get(inst.task)
    if expert is None:
        raise ExpertFailure("no_expert",
                            f"no humanoid expert for {inst.task} (have {sorted(HUMANOID_EXPERTS)})")
    yield from expert(h, inst)
