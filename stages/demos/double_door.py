"""The dual-arm platform's double-door task (issue 14: "open a double-door cabinet or fridge with
both arms"): the scene, the geometry of the doors' swing, the expert and the success predicate.

The catalog's two-door furniture (generators in :mod:`asset_catalog.generators`): ``wardrobe``
(always two doors, hinged on the outer sides, vertical bar handles 5 cm either side of the middle,
1.05 m high), ``closet`` (2-4 doors; two-door closets hinge like the wardrobe) and the
``side_by_side`` fridge. ``cabinet`` (0.72-0.9 m) has drawers only. The scene uses a wardrobe
(``wardrobe_01``: 0.92 m wide) standing on the floor, its front towards the robot.

- :func:`write_double_door_scene`: floor and the asset, turned to face the robot (its front towards
  -X), placed so that its handles' midpoint is at ``handles_xy``; the returned
  :class:`DoubleDoorScene` says which door each arm takes (the left arm, at +Y, the door whose
  handle is at +Y), each door's joint, hinge line and handle.
- :func:`handle_on_swing`: where a door's handle is when the door has turned by an angle (the
  expert's waypoints).
- :func:`judge_doors`: success from both joint angles: each door open at least ``DOOR_OPEN_DEG``.
- :func:`open_doors`: the expert: both arms pull their doors to ``PULL_DEG`` by the handles; then
  door after door the base moves towards it and the OTHER arm, in through the gap between the
  doors, pushes it on from behind to ``PUSH_DEG`` (:func:`door_plan`, :func:`push_plan`;
  :func:`leaf_clearance` checks a plan's arm against the door's front).

Frames: world, Z up, metres; angles in degrees where named ``*_deg``, else radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

DOOR_OPEN_DEG = 70.0  # [deg] a door counts as open from this angle on
PACKAGE = "wardrobe_01"
ARMS = ("left", "right")


@dataclass(frozen=True, kw_only=True)
class Door:
    """One door as an arm sees it: joint (prim path of its revolute joint), body (the door link's
    prim path), handle (3,) [m] the bar handle's centre with the door shut, hinge (3,) [m] a point
    on the hinge line (vertical), opening: +1 / -1, the sense (about +Z) in which the door swings
    open."""

    joint: str
    body: str
    handle: np.ndarray
    hinge: np.ndarray
    opening: int


@dataclass(frozen=True, kw_only=True)
class DoubleDoorScene:
    """usd: the scene file; doors: arm name ("left", "right") -> :class:`Door`."""

    usd: Path
    doors: dict[str, Door]

    def angles(self, sim) -> dict[str, float]:
        """Each arm's door angle [rad] now (0 shut, positive open)."""
        q = sim.state_0.joint_q.numpy()
        out = {}
        for arm, d in self.doors.items():
            j = next(j for j, p in sim.scene.joint_path.items() if p == d.joint)
            out[arm] = float(q[int(sim.model.joint_q_start.numpy()[j])])
        return out

    def reset(self, rig, rng: np.random.Generator) -> dict:
        """An episode's start for the table rig ``rig`` (:class:`stages.demos.table_rig.TableRig`):
        the base +-2 cm and +-0.03 rad off its spawn pose, the robot at its default posture with the
        grippers open, both doors shut; 0.1 s to settle. Returns the sample (the base pose)."""
        base = (rng.uniform(-0.02, 0.02), rng.uniform(-0.02, 0.02), rng.uniform(-0.03, 0.03))
        rig.sim.reset(base=base)
        rig.ctl.reset()
        rig.sim.step(50)
        return {"base": np.round(base, 4).tolist()}


def handle_on_swing(door: Door, angle: float) -> np.ndarray:
    """The handle's centre (3,) [m] with ``door`` turned ``angle`` [rad] open about its hinge line."""
    a = door.opening * float(angle)
    r = np.asarray(door.handle, float) - np.asarray(door.hinge, float)
    c, s = math.cos(a), math.sin(a)
    return np.asarray(door.hinge, float) + np.array([c * r[0] - s * r[1], s * r[0] + c * r[1], r[2]])


def judge_doors(angles_rad: dict[str, float], *, min_deg: float = DOOR_OPEN_DEG) -> tuple[bool, str, dict]:
    """Success of a double-door episode from both door angles (arm -> rad): every door open at least
    ``min_deg``. Returns (success, reason, detail): reason "" or "<arm>_door_shut" for the first
    arm's door short of it ("doors_shut" when both are); detail: the angles in degrees."""
    deg = {a: round(math.degrees(v), 2) for a, v in angles_rad.items()}
    if set(deg) != set(ARMS):
        raise ValueError(f"judge_doors: angles of arms {sorted(deg)}, expected {list(ARMS)}")
    short = [a for a in ARMS if deg[a] < min_deg]
    reason = "" if not short else "doors_shut" if len(short) == 2 else f"{short[0]}_door_shut"
    return not short, reason, {"door_deg": deg}


def joint_frames(usd: Path) -> dict[str, tuple[np.ndarray, float]]:
    """Revolute joints of a package's USD ``usd``: joint name -> (a point on its axis (3,) [m] in
    the asset frame, the z component of its axis there). (The package's ``base`` link sits at the
    asset origin; the generators' door hinges are vertical.)"""
    from pxr import Gf, Usd, UsdPhysics

    out, stage = {}, Usd.Stage.Open(str(usd))
    for prim in stage.Traverse():
        if prim.IsA(UsdPhysics.RevoluteJoint):
            j = UsdPhysics.RevoluteJoint(prim)
            axis = Gf.Vec3d(*[float(k == j.GetAxisAttr().Get()) for k in "XYZ"])
            r = j.GetLocalRot0Attr().Get()
            az = Gf.Rotation(Gf.Quatd(r)).TransformDir(axis)[2] if r is not None else axis[2]
            out[prim.GetName()] = (np.asarray(j.GetLocalPos0Attr().Get(), float), float(az))
    return out


def doors_of(info: dict, joints: dict[str, tuple[np.ndarray, float]], pos, yaw: float) -> dict[str, Door]:
    """The two doors of a catalog record ``info`` (its ``handles``) with their ``joints``
    (:func:`joint_frames`; a door link ``L``'s joint is ``L_joint``) placed at ``pos`` (3,) [m]
    turned ``yaw`` [rad], assigned to the arms: the door whose handle is at the larger world Y to
    the left arm. Raises ValueError unless exactly two doors have vertical bar handles."""
    from stages.demos.hand_scene import OBJECT_PRIM

    handles = [h for h in info.get("handles", ()) if tuple(h.get("bar_axis", ())) == (0.0, 0.0, 1.0)]
    if len(handles) != 2 or any(f"{h['link']}_joint" not in joints for h in handles):
        raise ValueError(f"{info.get('asset_id', 'asset')}: expected two hinged doors with vertical bar "
                         f"handles, found handles on {[h['link'] for h in handles]}")
    c, s = math.cos(yaw), math.sin(yaw)

    def world(p) -> np.ndarray:
        p = np.asarray(p, float)
        return np.array([pos[0] + c * p[0] - s * p[1], pos[1] + s * p[0] + c * p[1], pos[2] + p[2]])

    doors = []
    for h in handles:
        origin, axis_z = joints[f"{h['link']}_joint"]
        doors.append(Door(joint=f"{OBJECT_PRIM}/joints/{h['link']}_joint", body=f"{OBJECT_PRIM}/{h['link']}",
                          handle=world(h["center"]), hinge=world(origin), opening=1 if axis_z > 0 else -1))
    doors.sort(key=lambda d: -d.handle[1])
    return dict(zip(ARMS, doors, strict=True))


def write_double_door_scene(path: Path, asset, *, handles_xy=(0.62, 0.0)) -> DoubleDoorScene:
    """Author the scene at ``path``: floor and ``asset`` (a two-door package, e.g. a wardrobe) on it,
    turned to face the robot (its front towards -X), placed so that the midpoint of its two door
    handles is at ``handles_xy`` [m]."""
    from stages.demos.hand_scene import table_world, write_object_world

    yaw = math.pi
    joints = joint_frames(asset.usd)
    probe = doors_of(asset.info, joints, (0.0, 0.0, 0.0), yaw)
    mid = (probe["left"].handle + probe["right"].handle) / 2
    pos = (handles_xy[0] - mid[0], handles_xy[1] - mid[1], 0.0)
    path = Path(path)
    w = table_world(table_xy=(-3.0, -3.0), table_size=(0.1, 0.1), table_height=0.05)   # no table in reach
    write_object_world(path, w, asset, pos, yaw)
    return DoubleDoorScene(usd=path, doors=doors_of(asset.info, joints, pos, yaw))


# --------------------------------------------------------------------------------------------
# the expert: pull both doors open by their handles, let go; then each door is pushed on from
# behind by the OTHER arm, reaching in through the gap between the doors
# --------------------------------------------------------------------------------------------
#
# Why the other arm: a door open 50 deg has its free edge towards the middle and its back towards
# the middle and the carcass. The arm on the door's own side is in front of the door's plane
# (its mount at y = +-0.22 m; the plane passes behind it only past ~77 deg), so its forearm must
# wrap round the free edge and, pushing 5-15 cm in from the edge, lay across the door's front: it
# pressed the doors shut again (session 14: pulled 49.7 deg, end 38-49 deg). The other arm's mount
# lies behind the door's plane, beyond its free edge: reaching in through the gap between the
# doors, its whole arm stays on the back side (:func:`arm_clearance`).

PULL_DEG = 50.0   # [deg] each arm pulls its door this far by the handle (further, the wrist cannot follow the handle)
PUSH_DEG = 86.0   # [deg] then the other arm pushes it on from behind to this angle (the hinge stops it at 90)
PUSH_AT = 0.40    # [m] from the hinge (5.5 cm in from the free edge), where the closed fingers push the door's back
PUSH_BELOW = 0.30  # [m] the push this far below the handle (at 0.20 the other arm missed the last waypoints by 2-5 cm)
BASE_SHIFT = 0.12  # [m] the base moves sideways towards the door being pushed (without, the other arm reaches 70 deg, not 86)
TUCK = (0.18, 0.22, 0.70)  # [m] an arm out of the way, in the base frame (x, |y| on its own side, z), pointing down:
                           # 0.57 m from its door's hinge (outside the door's swing), its chain 13 cm from the other
                           # arm's pushing (at (0.22, 0.20, 0.80): 9 cm; the arms do not collide in the Sim)
DOOR_THICKNESS = 0.018  # [m] the catalog's hinged doors (asset_catalog.generators._parts.hinged_door)


def other(arm: str) -> str:
    """The other arm's name."""
    return ARMS[1 - ARMS.index(arm)]


def _turn(v, angle: float) -> np.ndarray:
    """Horizontal vector ``v`` (3,) turned ``angle`` [rad] about +Z."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]])


def grasp_rotation(door: Door, angle: float) -> np.ndarray:
    """TCP rotation (3, 3) gripping ``door``'s vertical bar handle with the door ``angle`` [rad]
    open: TCP +Z (the fingers) into the door's front, turning with the door, the fingers closing
    horizontally across the bar, TCP +X down."""
    z = _turn((1.0, 0.0, 0.0), door.opening * angle)
    x = np.array([0.0, 0.0, -1.0])
    return np.stack([x, np.cross(z, x), z], axis=1)


def leaf_point(door: Door, angle: float, along: float, *, behind: float = 0.0) -> np.ndarray:
    """A point (3,) [m] at the handle's height, ``along`` [m] from the hinge line across ``door``
    opened ``angle`` [rad], ``behind`` [m] behind the hinge line (its front face; the catalog's
    doors hinge at their outer front corner): the back face is ``DOOR_THICKNESS`` behind, the space
    between the open door's back and the carcass further (negative: before the front)."""
    r = np.asarray(door.handle, float) - np.asarray(door.hinge, float)
    u = np.array([0.0, r[1], 0.0])   # across the shut door (world Y)
    u /= np.linalg.norm(u)
    q = along * u + behind * np.array([1.0, 0.0, 0.0])
    p = np.asarray(door.hinge, float) + _turn(q, door.opening * angle)
    p[2] = door.handle[2]
    return p


def door_frame(door: Door, p, angle: float) -> tuple[float, float]:
    """(along, front) [m] of point ``p`` (3,) in the frame of ``door`` opened ``angle`` [rad]:
    along the door from its hinge line (its free edge at the door's width), and off its front face
    (positive before it, negative behind; the back face at -``DOOR_THICKNESS``)."""
    a = door.opening * angle
    u = _turn(np.array([0.0, -np.sign(door.hinge[1]), 0.0]), a)
    front = _turn(np.array([-1.0, 0.0, 0.0]), a)
    r = np.asarray(p, float) - np.asarray(door.hinge, float)
    return float(r[:2] @ u[:2]), float(r[:2] @ front[:2])


@dataclass(frozen=True, kw_only=True)
class DoorPlan:
    """One arm's TCP poses (4, 4), world, for its own door's pull: pre_grasp (``standoff`` before
    the handle), grasp (on the bar), pull (the handle's path to ``PULL_DEG``), release (backed off
    the handle)."""

    pre_grasp: np.ndarray
    grasp: np.ndarray
    pull: list[np.ndarray]
    release: np.ndarray


@dataclass(frozen=True, kw_only=True)
class PushPlan:
    """The other arm's TCP poses (4, 4), world, pushing a door on from behind: past (beyond the
    door's free edge, behind its back: reached from the tuck through the gap between the doors),
    behind (behind its back, ``PUSH_AT`` from the hinge), push (along the door's swing to
    ``PUSH_DEG``), away (backed off the door's back towards the middle)."""

    past: np.ndarray
    behind: np.ndarray
    push: list[np.ndarray]
    away: np.ndarray


def door_plan(door: Door, *, pull_deg: float = PULL_DEG, standoff: float = 0.08, step_deg: float = 10.0) -> DoorPlan:
    """The pull of ``door`` by its own arm (see :class:`DoorPlan`): along the handle's circle to
    ``pull_deg`` in steps of at most ``step_deg`` [deg]."""
    from stages.simulate.control import pose

    a1 = math.radians(pull_deg)
    r0, r1 = grasp_rotation(door, 0.0), grasp_rotation(door, a1)
    pulls = [pose(handle_on_swing(door, a), grasp_rotation(door, a))
             for a in np.linspace(0.0, a1, int(math.ceil(pull_deg / step_deg)) + 1)[1:]]
    return DoorPlan(pre_grasp=pose(door.handle - standoff * r0[:, 2], r0), grasp=pose(door.handle, r0),
                    pull=pulls, release=pose(handle_on_swing(door, a1) - standoff * r1[:, 2], r1))


def push_plan(door: Door, from_deg: float, *, push_deg: float = PUSH_DEG, push_at: float = PUSH_AT,
              push_below: float = PUSH_BELOW, step_deg: float = 10.0, gap: float = 0.03, width: float = 0.455,
              clear: float = 0.10) -> PushPlan:
    """The push of ``door`` (``width`` [m] from its hinge line to its free edge), now ``from_deg``
    [deg] open, by the other arm (see :class:`PushPlan`): to ``push_deg`` in steps of at most
    ``step_deg`` [deg], ``push_below`` [m] below the handle, the gripper pointing down with its
    fingers closing along the door (its 12 cm wide finger bar across, its edge hit the free edge on the
    way in and pushed the door shut), the TCP ``gap`` [m] behind the door's back face (a
    finger's thickness and a margin: the fingers lead the door by a few degrees); ``clear`` [m]
    beyond the free edge on the way in."""
    from stages.simulate.control import pose, top_down

    a0, a2 = math.radians(from_deg), math.radians(push_deg)
    back = DOOR_THICKNESS + gap
    z = float(door.handle[2]) - push_below

    def down(p, a):
        p = np.array(p, float)
        p[2] = z
        # TCP +X into the door (the gripper's narrow side to it), the wrist camera (at TCP -X) away from it
        return pose(p, top_down(door.opening * a + math.pi))

    n = max(1, int(math.ceil((push_deg - from_deg) / step_deg)))
    pushes = [down(leaf_point(door, a, push_at, behind=back), a) for a in np.linspace(a0, a2, n + 1)[1:]]
    away = down(leaf_point(door, a2, push_at + 0.05, behind=back + clear), a2)
    return PushPlan(past=down(leaf_point(door, a0, width + clear, behind=back), a0),
                    behind=down(leaf_point(door, a0 - math.radians(4.0), push_at, behind=back), a0),
                    push=pushes, away=away)


def tuck_pose(arm: str, base) -> np.ndarray:
    """``arm``'s TCP out of the way (4, 4), world (``TUCK`` in the frame of the base at ``base``
    (x, y, yaw) [m, rad], world), pointing down."""
    from stages.simulate.control import pose, top_down

    x, y, yaw = base
    side = 1.0 if arm == ARMS[0] else -1.0
    p = np.array([x, y, 0.0]) + _turn((TUCK[0], side * TUCK[1], 0.0), yaw)
    p[2] = TUCK[2]
    return pose(p, top_down(yaw + math.pi))   # fingers closing along the base's Y, as the default posture's


ARM_LINKS = ("upper_arm_link", "upper_forearm_link", "lower_forearm_link", "wrist_link", "gripper_link", "tcp")


def arm_points(ik, q: np.ndarray, arm: str, spawn=(0.0, 0.0, 0.0), per_segment: int = 4) -> np.ndarray:
    """Points (N, 3) [m], world, along ``arm``'s chain at configuration ``q`` (Pinocchio, ``ik`` a
    ``BimanualIk``; the robot spawned at ``spawn`` (x, y, yaw)): its links' origins from the upper
    arm to the TCP (``ARM_LINKS``) and ``per_segment`` - 1 points between consecutive ones."""
    from stages.simulate.control import Clik

    world = np.linalg.inv(Clik.root_from_world(spawn))
    o = np.array([(world @ ik.clik.kin.frame_pose(q, f"{arm}_{link}"))[:3, 3] for link in ARM_LINKS])
    t = np.linspace(0.0, 1.0, per_segment, endpoint=False)
    pts = [o[k] + s * (o[k + 1] - o[k]) for k in range(len(o) - 1) for s in t]
    return np.array([*pts, o[-1]])


def leaf_clearance(door: Door, angle: float, points, *, width: float = 0.455, reach: float = 0.04) -> float:
    """How far [m] the ``points`` (N, 3) that lie across ``door`` opened ``angle`` [rad] (between
    its hinge line and ``reach`` beyond its free edge) keep behind its front face: the smallest
    -front (:func:`door_frame`; positive: behind the front, the side the door opens away from);
    inf when none lies across it. A link pressing the door's front has clearance < 0."""
    c = [-f for a, f in (door_frame(door, p, angle) for p in np.asarray(points, float)) if 0.0 <= a <= width + reach]
    return min(c) if c else math.inf


def base_pose(sim, world: int = 0) -> tuple[float, float, float]:
    """The base's (x, y, yaw) [m, m, rad] in the robot's root (spawn) frame, from the Sim."""
    q = sim.state_0.joint_q.numpy()
    return tuple(float(q[sim.world_coord(n, world)]) for n in sim.desc.base_joints)


def drive_base(sim, ctl, target, *, world: int = 0, speed: float = 0.15, turn: float = 0.3, tol: float = 0.003,
               yaw_tol: float = 0.005, timeout: float = 4.0) -> None:
    """Drive the holonomic base to ``target`` (x, y, yaw) [m, m, rad] (root frame) at up to
    ``speed`` [m/s] and ``turn`` [rad/s] (a proportional command re-sent every 10 steps), then stop
    it. Raises RuntimeError when it is not within 1 cm / 0.02 rad after ``timeout`` [s] (something
    blocks it)."""
    steps = int(round(timeout / sim.settings.dt))
    for _ in range(0, steps, 10):
        x, y, yaw = base_pose(sim, world)
        e = np.array([target[0] - x, target[1] - y])
        e_yaw = math.remainder(target[2] - yaw, math.tau)
        if np.linalg.norm(e) < tol and abs(e_yaw) < yaw_tol:
            break
        v = 4.0 * e
        v *= min(1.0, speed / max(np.linalg.norm(v), 1e-9))
        c, s = math.cos(yaw), math.sin(yaw)
        ctl.set_base_velocity(c * v[0] + s * v[1], -s * v[0] + c * v[1], float(np.clip(4.0 * e_yaw, -turn, turn)),
                              world)
        sim.step(10)
    ctl.set_base_velocity(0.0, 0.0, 0.0, world)
    sim.step(int(round(0.1 / sim.settings.dt)))
    x, y, yaw = base_pose(sim, world)
    if math.hypot(target[0] - x, target[1] - y) > max(tol, 0.01) or abs(math.remainder(target[2] - yaw, math.tau)) > 0.02:
        raise RuntimeError(f"drive_base: the base stopped at ({x:.3f}, {y:.3f}, {yaw:.3f}), short of {tuple(target)}")


@dataclass(frozen=True, kw_only=True)
class DoorOpening:
    """What the double-door expert measured, per arm's door: gripped (fingers on the handle's door
    after closing, 0-2), pulled_deg (the door's angle [deg] when its arm let go), pushed_from_deg
    (when the other arm began its push), door_deg (at the end)."""

    gripped: dict[str, int]
    pulled_deg: dict[str, float]
    pushed_from_deg: dict[str, float]
    door_deg: dict[str, float]


def open_doors(sim, ctl, ik, scene: DoubleDoorScene, *, world: int = 0) -> DoorOpening:
    """The double-door expert in ``sim`` with ``ctl`` (a
    :class:`stages.simulate.bimanual_control.BimanualControl`) and ``ik`` (``BimanualIk``): both
    arms at once, each on its door of ``scene`` (:func:`door_plan`): open grippers to the
    pre-grasp, onto the bar handles, close, pull the doors open along the handles' swing to
    ``PULL_DEG``, let go and back off, close the grippers, tuck both arms; then door after door
    (left first): the base drives to ``BASE_SHIFT`` beside its spawn pose towards it (the spawn's
    x and yaw: the push's last waypoints are 1-2 cm inside the arm's reach), the other arm reaches in through the
    gap between the doors to behind it and pushes it on along its swing to ``PUSH_DEG``
    (:func:`push_plan`), backs off and tucks again. Raises RuntimeError (the CLIK's "unreachable")
    when a waypoint is out of reach."""
    from stages.demos.bimanual import close_gripper, gripper_contacts
    from stages.simulate.bimanual_control import move_arms

    plans = {a: door_plan(d) for a, d in scene.doors.items()}

    def move(key, duration, segments, settle=0.0, k=None):
        targets = {a: (getattr(p, key) if k is None else getattr(p, key)[k]) for a, p in plans.items()}
        move_arms(sim, ctl, ik, targets, duration, segments=segments, settle=settle, world=world)

    def deg() -> dict[str, float]:
        return {a: round(math.degrees(v), 2) for a, v in scene.angles(sim).items()}

    def world_base() -> tuple[float, float, float]:
        x, y, yaw = base_pose(sim, world)
        sx, sy, syaw = sim.spawn
        p = _turn((x, y, 0.0), syaw)
        return sx + p[0], sy + p[1], syaw + yaw

    ctl.set_gripper(0.0, world)
    move("pre_grasp", 2.0, 8, 0.2)
    move("grasp", 1.0, 4, 0.2)
    close_gripper(sim, ctl, None, 0.5, world=world)
    gripped = {a: gripper_contacts(sim, ik.desc, sim.body_of_path(d.body, world), world)[a]
               for a, d in scene.doors.items()}
    for k in range(len(plans["left"].pull)):
        move("pull", 0.5, 2, k=k)
    sim.step(int(round(0.2 / sim.settings.dt)))
    pulled = deg()
    close_gripper(sim, ctl, None, 0.4, world=world, opening=True, settle=0.1)
    move("release", 0.6, 2)
    close_gripper(sim, ctl, None, 0.3, world=world, settle=0.0)
    move_joints(sim, ctl, ik, {a: tuck_pose(a, world_base()) for a in ARMS}, 1.5, world=world)
    pushed_from = {}
    for arm in ARMS:
        side = 1.0 if arm == ARMS[0] else -1.0
        drive_base(sim, ctl, (0.0, side * BASE_SHIFT, 0.0), world=world)   # from the spawn pose, whatever the start
        pusher, now = other(arm), deg()[arm]
        pushed_from[arm] = now
        p = push_plan(scene.doors[arm], now)
        move_arms(sim, ctl, ik, {pusher: p.past}, 1.2, segments=6, world=world)
        move_arms(sim, ctl, ik, {pusher: p.behind}, 1.0, segments=4, world=world)
        for t in p.push:
            move_arms(sim, ctl, ik, {pusher: t}, 0.5, segments=2, world=world)
        move_arms(sim, ctl, ik, {pusher: p.away}, 0.6, segments=2, world=world)
        move_arms(sim, ctl, ik, {pusher: tuck_pose(pusher, world_base())}, 1.2, segments=6, settle=0.2, world=world)
    return DoorOpening(gripped=gripped, pulled_deg=pulled, pushed_from_deg=pushed_from, door_deg=deg())


def move_joints(sim, ctl, ik, targets_world, duration: float, *, world: int = 0, tol: float = 0.003) -> None:
    """Move the arms named in ``targets_world`` (arm -> 4x4 world TCP pose) in joint space: their IK
    solution from the default posture (not from where the arms are; the base where it is in the
    Sim), the joint targets interpolated linearly over ``duration`` [s]. Raises RuntimeError when a
    target is missed by more than ``tol`` [m]."""
    from stages.simulate.control import Clik

    goals = {a: Clik.world_to_root(sim.spawn, t) for a, t in targets_world.items()}
    q0 = ik.clik.default_q()
    now = ik.from_sim(sim, world)
    for n in sim.desc.base_joints:
        q0[ik.idx_q[n]] = now[ik.idx_q[n]]
    res = ik.solve(goals, q0)
    if res.position_error.max() > tol:
        raise RuntimeError(f"CLIK: joint-space target of {tuple(goals)} unreachable "
                           f"(errors {np.round(res.position_error, 4).tolist()} m)")
    arms0 = ctl.arm_targets()
    arms1 = arms0.copy()
    i = 0
    for a, info in ik.desc.arms.items():
        if a in goals:
            arms1[i:i + len(info.joints)] = ik.arm_q(res.q[0], a)
        i += len(info.joints)
    steps = max(1, int(round(duration / sim.settings.dt)))
    for k in range(0, steps, 10):
        ctl.set_arm_targets(arms0 + (arms1 - arms0) * min(1.0, (k + 10) / steps), world)
        sim.step(10)
