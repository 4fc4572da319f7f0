"""The task objects' state in the robot's base frame: ``observation.environment_state`` (issue 17).

Sim benchmarks (robomimic's low-dim observations, LeRobot's pusht keypoints) give policies the task
objects' state beside the robot's; lerobot's ACT and Diffusion Policy take it natively as
``observation.environment_state`` (a dataset feature of that key is a ``FeatureType.ENV`` input).
Here it is an option of the recorder (``EngineConfig.environment_state``: the feature's names) and
an input of the closed-loop evaluator when the policy was trained with it; both compute it with
:func:`engine_environment_state` from the same state read as ``observation.state`` (the engine's
snapshot at the frame step), so a policy sees in closed loop what it was trained on.

Key points per task (world positions read from the simulation, then expressed in the robot's base
frame: origin at the base pose (x, y) on the floor (z = 0, the frame of ``observation.state``'s
end-effector pose), x forward, y left, z up [m]):

- ``pick_place_bowl``: the mug's body origin (3), the bowl's (3);
- ``push_object``: the pushed object's body origin (3), the push goal (3): the object's start
  position moved 0.15 m along the push direction (the instance's ``target``, fixed for the episode,
  at the object's start height);
- ``open_<part>`` / ``close_<part>`` (``open_drawer`` ...): the handle's grasp centre where the
  simulated joint value puts it (3: :meth:`~stages.demos.parts.ArticulatedPart.handle_at` of the
  joint coordinate, the rigid link's kinematics) and the joint opening from closed (1) [m for a
  drawer, rad for a door].

With the gripper entry (``gripper=True`` of :func:`state_names`; the recorder's option
``environment_gripper``), one more number ends the row: ``gripper_opening``, the sum of the
parallel gripper's finger joint positions (the Panda hand: the distance between its fingers [m];
0 closed). ``observation.state`` holds the arm, its end-effector pose and the base, not the
fingers: without this entry a policy cannot tell a closed hand from an open one at the same arm
pose (the grasp's dwell, the release).

With the base-velocity entries (``base_velocity=True``; the recorder's option
``environment_base_velocity``), three numbers come before the gripper's: ``base_vx``, ``base_vy``
[m/s] and ``base_vtheta`` [rad/s], the base's measured velocity in its own frame (the planar
joints' velocities turned by the base's yaw). ``observation.state`` holds poses only: without them a
policy cannot tell a base that has stopped from one still braking at the same pose, nor a base
pushing against furniture from one driving (session 28: the drawer policies' stalls and pushes).

With the front entries (``front=True``, open/close tasks only; the recorder's option
``environment_front``), two numbers follow the part's opening: ``front_x``, ``front_y``, the
planar direction of the part's front (its outward normal where the joint value puts it,
:meth:`~stages.demos.parts.ArticulatedPart.front_at`) in the base frame ((-1, 0) when the robot
stands square to it). The handle's point alone does not say how the robot stands to the bar: a
policy that keeps the hand's base-frame orientation from a turned stance grips the bar rolled and
the fingers stop wide and slip (session 29's drawer failures).

The dimension D is fixed per task (:func:`state_names`); a dataset holds one layout.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from itertools import product

import numpy as np

from stages.dataset.schema import ENV_STATE_KEY
_XYZ = ("x", "y", "z")
_PICK = tuple(f"object_{c}" for c in _XYZ) + tuple(f"container_{c}" for c in _XYZ)
_PUSH = tuple(f"object_{c}" for c in _XYZ) + tuple(f"goal_{c}" for c in _XYZ)
_PART = (*(f"handle_{c}" for c in _XYZ), "opening")
_BODIES = {"pick_place_bowl": ("mug", "bowl"), "push_object": ("pusher",)}
GRIPPER = "gripper_opening"  # the optional last entry: the fingers' opening [m]
BASE_VELOCITY = ("base_vx", "base_vy", "base_vtheta")  # optional, before the gripper's: [m/s, m/s, rad/s]
FRONT = ("front_x", "front_y")  # optional for open/close tasks, after the opening: unit direction, base frame


def has_gripper(names: Sequence[str]) -> bool:
    """Whether an environment-state layout ``names`` ends with the gripper's opening."""
    return bool(names) and names[-1] == GRIPPER


def has_base_velocity(names: Sequence[str]) -> bool:
    """Whether an environment-state layout ``names`` holds the base's velocity entries."""
    return BASE_VELOCITY[-1] in tuple(names)


def has_front(names: Sequence[str]) -> bool:
    """Whether an environment-state layout ``names`` holds the part front's direction."""
    return FRONT[0] in tuple(names)


def _part_target(task: str) -> str | None:
    """The articulated target of an open/close task (``drawer`` of ``open_drawer``), else None."""
    from stages.demos.tasks import ARTICULATED

    kind, _, which = task.partition("_")
    return which if kind in ("open", "close") and which in ARTICULATED else None


def state_names(task: str, gripper: bool = False, base_velocity: bool = False,
                front: bool = False) -> tuple[str, ...]:
    """The names of ``task``'s environment state (D entries; module docstring), with the part
    front's direction when ``front`` (open/close tasks), then the base's velocity when
    ``base_velocity``, ending with ``gripper_opening`` when ``gripper``; ValueError for a task
    without one, or ``front`` for a task without a part."""
    tail = (BASE_VELOCITY if base_velocity else ()) + ((GRIPPER,) if gripper else ())
    if front and _part_target(task) is None:
        raise ValueError(f"environment_state: task {task!r} has no articulated part: {list(FRONT)} are for "
                         f"open_/close_ tasks")
    if task == "pick_place_bowl":
        return _PICK + tail
    if task == "push_object":
        return _PUSH + tail
    if _part_target(task) is not None:
        return _PART + (FRONT if front else ()) + tail
    raise ValueError(f"environment_state: task {task!r} has no environment state (supported: pick_place_bowl, "
                     f"push_object, open_/close_ of an articulated part)")


def common_layout(tasks: Sequence[str], gripper: bool = False, base_velocity: bool = False,
                  front: bool = False) -> tuple[str, ...]:
    """The one environment-state layout of ``tasks`` (a dataset or a policy holds one; with the
    optional entries as in :func:`state_names`); ValueError naming a task without one, or the
    layouts when they differ."""
    layouts = {t: state_names(t, gripper, base_velocity, front) for t in tasks}
    if len(set(layouts.values())) > 1:
        raise ValueError(f"environment_state: the tasks' layouts differ ({layouts}); one step, one layout")
    return next(iter(layouts.values()), ())


def optional_layouts(tasks: Sequence[str]) -> list[tuple[str, ...]]:
    """Every layout ``tasks`` share, with and without each optional entry (the front's direction
    where the tasks have a part, the base's velocity, the gripper's opening); ValueError as
    :func:`common_layout` for the plain layout."""
    fronts = (False, True) if all(_part_target(t) is not None for t in tasks) else (False,)
    return [common_layout(tasks, gripper=g, base_velocity=b, front=f)
            for f, b, g in product(fronts, (False, True), (False, True))]


def episode_goal(inst) -> tuple[float, ...]:
    """The fixed world points (3 each) of an episode's environment state, from its task instance:
    the push goal of ``push_object`` (x, y of the instance's target, the object's start z [m]);
    () for the other tasks (their points are read from the simulation at every frame)."""
    if inst.task != "push_object":
        return ()
    body = inst.world.placed["pusher"].body()
    return (float(inst.target[0]), float(inst.target[1]), float(inst.objects[body][2]))


@dataclass(frozen=True)
class EnvKeys:
    """What one episode's environment state reads: ``bodies`` world-local body indices whose
    origins are key points; ``goal`` (3 g,) fixed world points [m]; ``part`` the articulated part
    and ``coord`` its joint's world-local coordinate (open/close tasks; None otherwise);
    ``fingers`` the world-local coordinates of the gripper's finger joints whose sum is the
    ``gripper_opening`` entry (() without it); ``base`` the world-local coordinate of the base's yaw
    joint, then the dofs of its planar joints x, y, yaw, whose velocities are the base-velocity
    entries (() without them); ``front``: whether the part front's direction is in (open/close
    tasks)."""

    task: str
    bodies: tuple[int, ...] = ()
    goal: tuple[float, ...] = ()
    part: object = None
    coord: int = -1
    fingers: tuple[int, ...] = ()
    base: tuple[int, ...] = ()
    front: bool = False

    @property
    def dim(self) -> int:
        return (3 * len(self.bodies) + len(self.goal) + (4 if self.part is not None else 0)
                + (2 if self.front else 0) + (3 if self.base else 0) + (1 if self.fingers else 0))


class EnvResolver:
    """Builds :class:`EnvKeys` for episodes in one task world (a kitchen) simulated by an engine:
    body and joint indices resolved once per task. ``body_index``: scene prim path -> world-local
    body index; ``scene_coord``: scene joint prim path -> world-local joint coordinate;
    ``fingers``: the world-local coordinates of the robot's finger joints; ``base``: the world-local
    yaw coordinate and x, y, yaw dofs of its planar base (:attr:`EnvKeys.base`)."""

    def __init__(self, world, body_index: dict[str, int], scene_coord: dict[str, int],
                 fingers: Sequence[int] = (), base: Sequence[int] = ()) -> None:
        self.world, self.body_index, self.scene_coord = world, body_index, scene_coord
        self.fingers = tuple(int(c) for c in fingers)
        self.base = tuple(int(i) for i in base)
        self._parts: dict[str, object] = {}

    @classmethod
    def of_engine(cls, engine) -> EnvResolver:
        sim = engine.banks[0].sim
        grip = sim.desc.gripper
        fingers = [sim.robot.coord[n] for n in grip.finger_joints] if grip is not None else []
        joints = tuple(sim.desc.base_joints)  # x, y, yaw
        base = (sim.robot.coord[joints[2]], *(sim.robot.dof[n] for n in joints)) if len(joints) == 3 else ()
        return cls(engine.world, {p: b for b, p in sim.scene.body_path.items()}, dict(engine._scene_coord), fingers,
                   base)

    def keys(self, task: str, goal: Sequence[float] = (), gripper: bool = False,
             base_velocity: bool = False, front: bool = False) -> EnvKeys:
        """The keys of an episode of ``task`` with the fixed points ``goal`` (:func:`episode_goal`),
        with the gripper's opening when ``gripper`` (ValueError for a robot without finger joints),
        the base's velocity when ``base_velocity`` (ValueError for a robot without a planar base)
        and the part front's direction when ``front`` (ValueError for a task without a part)."""
        state_names(task, front=front)  # raises for a task without an environment state
        if gripper and not self.fingers:
            raise ValueError(f"environment_state: {GRIPPER} needs a robot with a parallel gripper's finger joints")
        if base_velocity and not self.base:
            raise ValueError("environment_state: the base velocity needs a robot with planar base joints x, y, yaw")
        keys = self._keys(task, goal)
        return replace(keys, fingers=self.fingers if gripper else (), base=self.base if base_velocity else (),
                       front=front)

    def _keys(self, task: str, goal: Sequence[float]) -> EnvKeys:
        which = _part_target(task)
        if which is not None:
            if task not in self._parts:
                from stages.demos.sampling import world_part

                self._parts[task] = world_part(self.world, which)
            part = self._parts[task]
            return EnvKeys(task=task, part=part, coord=int(self.scene_coord[part.joint_path]))
        roles = _BODIES[task]
        return EnvKeys(task=task, bodies=tuple(self.body_index[self.world.placed[r].body()] for r in roles),
                       goal=tuple(float(v) for v in goal))


def to_base_frame(points: np.ndarray, base: np.ndarray) -> np.ndarray:
    """World points (K, P, 3) [m] -> the base frame of base poses (K, 3) (x, y [m], theta [rad] in
    the world): p_b = R(theta)^T (p - (x, y, 0)); (K, P, 3)."""
    p = np.asarray(points, np.float64)
    b = np.asarray(base, np.float64)
    c, s = np.cos(b[:, 2])[:, None], np.sin(b[:, 2])[:, None]
    dx, dy = p[..., 0] - b[:, :1], p[..., 1] - b[:, 1:2]
    return np.stack([c * dx + s * dy, -s * dx + c * dy, p[..., 2]], axis=-1)


def _in_base(x: float, y: float, yaw: float) -> tuple[float, float]:
    """A world planar vector (x, y) in the frame of a base of heading ``yaw`` [rad]: R(yaw)^T (x, y)."""
    c, s = np.cos(yaw), np.sin(yaw)
    return float(c * x + s * y), float(-s * x + c * y)


def environment_state(keys: Sequence[EnvKeys], base: np.ndarray, body_xyz: np.ndarray,
                      joint_q: np.ndarray, joint_qd: np.ndarray | None = None) -> np.ndarray:
    """The environment state of K worlds at one instant, float32 (K, D).

    keys: per world its episode's :class:`EnvKeys` (all of one dimension D); base (K, 3): base
    poses (x, y [m], theta [rad]) in the world; body_xyz (K, B, 3): world positions of each world's
    bodies [m] (world-local body index); joint_q (K, C): each world's joint coordinates (world-local);
    joint_qd (K, D): its joint velocities (world-local dofs; needed by keys with ``base``).
    Row k: the key points (bodies', then the goal's, then an articulated handle's) in world k's
    base frame, then an articulated part's opening [m or rad], then its front's planar direction
    in the base frame (keys with ``front``), then the base's velocity in its own
    frame [m/s, m/s, rad/s] (keys with ``base``), then the gripper's opening [m] (keys with
    ``fingers``)."""
    k = len(keys)
    dims = {kk.dim for kk in keys}
    if len(dims) > 1:
        raise ValueError(f"environment_state: the worlds' tasks have different dimensions {sorted(dims)}: "
                         f"{sorted({kk.task for kk in keys})}")
    if k == 0:
        return np.zeros((0, 0), np.float32)
    rows = []
    for j, kk in enumerate(keys):
        pts = [body_xyz[j, b] for b in kk.bodies]
        pts += [np.asarray(kk.goal[i:i + 3], np.float64) for i in range(0, len(kk.goal), 3)]
        extra = []
        if kk.part is not None:
            q = float(joint_q[j, kk.coord])
            pts.append(kk.part.handle_at(q))
            extra.append(q - kk.part.closed)
            if kk.front:
                n = kk.part.front_at(q)
                fx, fy = _in_base(n[0], n[1], base[j, 2])
                r = float(np.hypot(fx, fy))  # the planar part (an oven door's front tilts down)
                extra += [fx / r, fy / r] if r > 1e-9 else [0.0, 0.0]
        if kk.base:
            if joint_qd is None:
                raise ValueError("environment_state: the base velocity needs the joint velocities")
            cyaw, dx, dy, dyaw = kk.base
            extra += [*_in_base(float(joint_qd[j, dx]), float(joint_qd[j, dy]), joint_q[j, cyaw]),
                      float(joint_qd[j, dyaw])]
        if kk.fingers:
            extra.append(float(sum(joint_q[j, c] for c in kk.fingers)))
        rows.append((np.asarray(pts, np.float64).reshape(-1, 3), extra))
    pts = to_base_frame(np.stack([r[0] for r in rows]), base).reshape(k, -1)
    extra = np.asarray([r[1] for r in rows], np.float64).reshape(k, -1)
    return np.concatenate([pts, extra], axis=1).astype(np.float32)


def engine_environment_state(engine, worlds: Sequence[int], keys: Sequence[EnvKeys],
                             base: np.ndarray) -> np.ndarray:
    """:func:`environment_state` of ``worlds`` of a :class:`~stages.engine.BatchEngine` from its
    snapshot of this step (the state read that gives ``observation.state``); ``base`` (K, 3): their
    base poses (:meth:`~stages.engine.capture.FrameCapture.robot_state`). float32 (K, D)."""
    sim = engine.banks[0].sim
    nb, nc, nd = sim.bodies_per_world, sim.coords_per_world, sim.dofs_per_world
    need_qd = any(kk.base for kk in keys)
    body, jq, jqd = [], [], []
    for w in worlds:
        bank, i = engine._where[w]
        body.append(bank.snapshot.get("body_q")[i * nb:(i + 1) * nb, :3])
        jq.append(bank.snapshot.get("joint_q")[i * nc:(i + 1) * nc])
        if need_qd:
            jqd.append(bank.snapshot.get("joint_qd")[i * nd:(i + 1) * nd])
    k = len(worlds)
    body_xyz = np.asarray(body, np.float64).reshape(k, nb, 3)
    qd = np.asarray(jqd, np.float64).reshape(k, nd) if need_qd else None
    return environment_state(keys, base, body_xyz, np.asarray(jq, np.float64).reshape(k, nc), qd)


def ticket_keys(engine, ticket) -> EnvKeys:
    """The :class:`EnvKeys` of an episode the engine begins (its :class:`~stages.engine.programs.Ticket`:
    task and goal); ValueError if the task's layout is not the engine's ``environment_state``."""
    check_names(engine.config.environment_state, ticket.task, "engine")
    return episode_keys(engine, ticket.task, ticket.goal)


def episode_keys(engine, task: str, goal: Sequence[float] = ()) -> EnvKeys:
    """:meth:`EnvResolver.keys` of an episode of ``task`` (fixed points ``goal``) on ``engine``, with
    the engine's one resolver (made on first use): the recorder's and the evaluator's. The gripper's
    opening is in when the engine's ``environment_state`` names end with it, the base's velocity
    and the front's direction when they hold them."""
    res = getattr(engine, "_env_resolver", None)
    if res is None:
        res = engine._env_resolver = EnvResolver.of_engine(engine)
    names = tuple(engine.config.environment_state)
    return res.keys(task, goal, gripper=has_gripper(names), base_velocity=has_base_velocity(names),
                    front=has_front(names))


def recorded_environment_state(engine, worlds: Sequence[int], base: np.ndarray) -> np.ndarray:
    """The recorder's ``environment_state`` column of ``worlds`` at this frame step, float32 (K, D):
    each world's episode keys (set when the episode began) on this step's state read; zeros for a
    world without an episode (its frame is dropped)."""
    out = np.zeros((len(worlds), len(engine.config.environment_state)), np.float32)
    live = [j for j, w in enumerate(worlds) if engine.recs[w].env is not None]
    if live:
        ws = [worlds[j] for j in live]
        out[live] = engine_environment_state(engine, ws, [engine.recs[w].env for w in ws], np.asarray(base)[live])
    return out


def check_names(names: Sequence[str], task: str, where: str) -> None:
    """ValueError when ``task``'s environment state is not laid out as ``names`` (a dataset or a
    policy holds one layout; with or without the gripper's entry)."""
    mine = state_names(task, gripper=has_gripper(names), base_velocity=has_base_velocity(names),
                       front=has_front(names) and _part_target(task) is not None)
    if tuple(names) != mine:
        raise ValueError(f"{where}: task {task!r} has environment state {list(mine)}, but "
                         f"{len(names)} entries {list(names)} are recorded or expected")


__all__ = ["BASE_VELOCITY", "ENV_STATE_KEY", "FRONT", "GRIPPER", "EnvKeys", "EnvResolver", "check_names", "common_layout", "engine_environment_state",
           "environment_state", "episode_goal", "episode_keys", "has_base_velocity", "has_front", "has_gripper", "optional_layouts", "recorded_environment_state", "state_names",
           "ticket_keys", "to_base_frame"]

