"""Humanoid demonstrations on the batched engine: an embodiment whose base is a legged robot walking
by its locomotion policy (``[base] kind = "legged_policy"``: the G1, the H1) in N copies of a task kitchen.

The world: the kitchen's scene USD loaded as the engine loads it (``stages.simulate.world.load_scene``,
the engine's contact stiffness), the humanoid as trained (``stages.locomotion.robot.humanoid_builder`` of
the robot the spec's policy was trained on, ``policy.json``'s ``humanoid``:
inertials, sole spheres, mjlab's drives) plus one collision sphere per hand at the spec's
end-effector frame (``ee_xyz`` on the arm's tip link: the palm centre), so that the hands push and
touch the scene (a spec with hands, ``g1_29dof_dex3``: the G1 with its Dex3 joints and one
collision box per hand link instead, ``stages.engine.humanoid_hands``; the hands open and close by
``WorldHandle.set_hand``); replicated to ``worlds`` worlds of one Newton model (MuJoCo C for one
world on a CPU, else MuJoCo-Warp; ``stages.locomotion.runtime.HumanoidWorlds``). The legs and waist follow the
policy, the arms CLIK (``LeggedPolicyRuntime``: base commands vx, vy, v_theta and the mode through
the wheeled base's interface).

Episodes: every world runs its own sequence. ``next_instance(w)`` gives a task instance
(``stages.demos.sampling.TaskInstance``) or None; at the next synchronisation point (every
``frame_every`` control steps, so that all worlds' frames fall on the same steps and one render
serves them all) the engine resets that world alone (every coordinate of the world back to the
kitchen's, the instance's scene joints and free objects' poses, the robot standing at the
instance's start pose), and runs
``program(handle, inst)``: a generator that sets commands through its :class:`WorldHandle` and
yields the number of control steps to wait. Every ``frame_every`` control steps of an episode the
engine reads a frame before stepping: ``observation.state`` and ``action`` in the embodiment's
layout (``stages.locomotion.embodiment.frame_vectors``) and, with cameras, one render of every
camera in every world. The episode ends when the program returns (or raises
``ExpertFailure``) or at ``max_seconds``; the task's success predicate decides, ``end(w, inst,
result)`` hears of it.

Clock: control period ``dt`` = the policy's (0.02 s, 4 physics steps of 5 ms); ``fps`` = 1 /
(``frame_every`` dt) recorded frames per second (25 by default).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Generator
from dataclasses import dataclass
from typing import Any

import numpy as np

from stages.demos.driver import ExpertFailure
from stages.engine.programs import EpisodeResult

log = logging.getLogger(__name__)

Program = Callable[["WorldHandle", Any], Generator[int, None, None]]


@dataclass(frozen=True, kw_only=True)
class HumanoidEngineConfig:
    """spec: embodiment spec with a legged-with-policy base; worlds; device ("cpu" | "cuda[:n]");
    frame_every: control steps per recorded frame; max_seconds: an episode's time limit [s];
    cameras: recorded cameras of the spec (empty: state and action only), at width x height [px];
    hand_radius: the collision spheres [m] of hands of kind "none" (hand end effectors get a box
    per link, friction hand_mu: ``humanoid_hands``); foot_mu: the feet's friction; contact_ke /
    contact_kd: the scene shapes' contact stiffness and damping (the engine's)."""

    spec: str = "g1_29dof"
    worlds: int = 1
    device: str = "cpu"
    frame_every: int = 2
    max_seconds: float = 40.0
    cameras: tuple[str, ...] = ()
    width: int = 128
    height: int = 96
    hand_radius: float = 0.045
    hand_mu: float = 1.0
    foot_mu: float = 0.6
    contact_ke: float = 4.0e4
    contact_kd: float = 400.0


@dataclass
class _Episode:
    inst: Any
    program: Generator[int, None, None]
    sink: Callable | None
    start_step: int
    wall0: float
    wait: int = 0
    frames: int = 0


class _SceneJoints:
    """``state.scene_joints`` of the task predicates for one world: prim path -> joint value [m or rad]."""

    def __init__(self, engine: HumanoidEngine, world: int) -> None:
        self._engine, self._world = engine, world

    def __getitem__(self, path: str) -> float:
        return self._engine.joint_value(self._world, path)


class _Objects:
    """``state.objects`` of the task predicates for one world: body prim path -> Pose."""

    def __init__(self, engine: HumanoidEngine, world: int) -> None:
        self._engine, self._world = engine, world

    def __getitem__(self, path: str) -> Any:
        return self._engine.object_pose(self._world, path)


def _quat_xyzw(r: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(r).as_quat()


class WorldHandle:
    """What a world's program sees and commands: its base, arms and scene joints (world frame, metres,
    radians). Commands persist until changed; the program yields control steps to wait."""

    def __init__(self, engine: HumanoidEngine, world: int) -> None:
        self.engine, self.world = engine, world
        self.rt = engine.sim.runtime
        self.dt: float = self.rt.control_dt
        """control period [s]"""

    def base_pose(self) -> tuple[float, float, float]:
        """(x [m], y [m], yaw [rad]) of the base (pelvis) in the world."""
        pos, quat, _, _ = self.rt.base_state(self.engine.sim.state)
        p = pos[self.world].double().cpu().numpy()
        x, y, z, w = quat[self.world].double().cpu().numpy()
        return float(p[0]), float(p[1]), float(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))

    def base_height(self) -> float:
        """pelvis height [m]"""
        return float(self.rt.base_state(self.engine.sim.state)[0][self.world, 2])

    def set_command(self, vx: float, vy: float, vtheta: float) -> None:
        """base-frame velocity command [m/s, m/s, rad/s] (locomotion mode)"""
        self.rt.set_command(np.array([[vx, vy, vtheta]]), [self.world])

    def set_mode(self, mode: int) -> None:
        self.rt.set_mode([int(mode)], [self.world])

    def ee_pose(self, arm: str) -> np.ndarray:
        """measured end-effector pose (4, 4), world frame"""
        return self.rt.ee_pose_world(self.engine.sim.state, arm)[self.world]

    def set_ee_target(self, arm: str, pose: np.ndarray, frame: str = "world") -> None:
        self.rt.set_ee_target(arm, np.asarray(pose, float)[None], [self.world], frame=frame)

    def set_hand(self, arm: str, value: float) -> None:
        """``arm``'s hand command: 0 open .. 1 closed (the spec's hand poses); the arm whose hand
        closes last is the one the task predicates check for a release."""
        self.rt.hands.set(arm, value, [self.world])
        if value > 0.5:
            self.engine.grasp_arm[self.world] = arm

    def object_pose(self, path: str) -> Any:
        """The pose (``asset_model.Pose``: position [m], quaternion w, x, y, z) of scene body ``path``."""
        return self.engine.object_pose(self.world, path)

    def release_arm(self, arm: str) -> None:
        self.rt.release_arm(arm, [self.world])

    def joint_value(self, path: str) -> float:
        return self.engine.joint_value(self.world, path)


class HumanoidEngine:
    """N copies of a task world (:class:`~stages.demos.kitchen.KitchenWorld`) with a humanoid each
    (see the module docstring)."""

    def __init__(self, world: Any, config: HumanoidEngineConfig | None = None) -> None:
        from stages.embodiment import load_spec
        from stages.locomotion.embodiment import runtime_config_for

        self.world, self.cfg = world, config or HumanoidEngineConfig()
        self.spec = load_spec(self.cfg.spec)
        self.runtime_cfg = runtime_config_for(self.spec, device=self.cfg.device)
        t0 = time.perf_counter()
        self.sim, self.scene, self._joints_per_world = self._build()
        self.build_seconds = time.perf_counter() - t0
        self.dt: float = self.sim.runtime.control_dt
        self.fps: int = int(round(1.0 / (self.dt * self.cfg.frame_every)))
        model = self.sim.model
        self._q_start = model.joint_q_start.numpy()
        self._qd_start = model.joint_qd_start.numpy()
        self._path_joint = {p: j for j, p in self.scene.joint_path.items()}
        jtype, child = model.joint_type.numpy(), model.joint_child.numpy()
        self._free_joint = {self.scene.body_path[int(child[j])]: j for j in range(self._joints_per_world)
                            if jtype[j] == 4 and int(child[j]) in self.scene.body_path}
        """scene free body prim path -> its free joint in world 0 (newton.JointType.FREE = 4)"""
        self._path_body = {p: b for b, p in self.scene.body_path.items()}
        self.bodies_per_world: int = model.body_count // self.cfg.worlds
        self.grasp_arm: dict[int, str] = {}
        """world -> the arm whose hand last closed (the task predicates' robot)"""
        self._home_q = self.sim.state.joint_q.numpy().copy()
        self._home_qd = np.zeros_like(self.sim.state.joint_qd.numpy())
        self.rig = self._rig() if self.cfg.cameras else None
        self.step_count = 0

    # ------------------------------------------------------------------ building
    def _build(self) -> tuple[Any, Any, int]:
        import newton
        import warp as wp

        from stages.engine.humanoid_hands import add_hand_colliders
        from stages.locomotion.hands import hand_arms, humanoid_for_spec
        from stages.locomotion.humanoids import humanoid
        from stages.locomotion.policy import policy_humanoid
        from stages.locomotion.robot import humanoid_builder
        from stages.locomotion.runtime import HumanoidWorlds, HumanoidWorldsConfig
        from stages.simulate.contacts import size_contact_buffers
        from stages.simulate.world import load_scene

        cfg = self.cfg
        tpl = newton.ModelBuilder()
        tpl.default_shape_cfg.ke, tpl.default_shape_cfg.kd = cfg.contact_ke, cfg.contact_kd
        newton.solvers.SolverMuJoCo.register_custom_attributes(tpl)
        scene = load_scene(tpl, self.world.usd)
        desc = humanoid(policy_humanoid(self.runtime_cfg.policy))  # the robot the spec's policy walks
        robot, layout = humanoid_builder(humanoid_for_spec(self.spec, desc), foot_mu=cfg.foot_mu,
                                         base_pose=self.world.spawn)
        hands = (add_hand_colliders(robot, self.spec, mu=cfg.hand_mu) if hand_arms(self.spec)
                 else add_hand_spheres(robot, self.spec, cfg.hand_radius))
        tpl.add_builder(robot)
        main = newton.ModelBuilder()
        newton.solvers.SolverMuJoCo.register_custom_attributes(main)
        main.replicate(tpl, cfg.worlds)
        model = main.finalize(device=wp.get_device(cfg.device))
        cap = size_contact_buffers(model, model.body_q.numpy(),
                                   robot_shapes=len(layout.foot_shapes) + len(hands),
                                   dofs_per_world=tpl.joint_dof_count)
        sim = HumanoidWorlds(HumanoidWorldsConfig(num_worlds=cfg.worlds, device=cfg.device,
                                                  runtime=self.runtime_cfg, foot_mu=cfg.foot_mu),
                             model=model, solver_options={"nconmax": cap.nconmax, "njmax": cap.njmax})
        return sim, scene, tpl.joint_count

    def _rig(self):
        from stages.engine.humanoid_cameras import mounted_rig

        return mounted_rig(self.sim, self.spec, self.scene, self.cfg.cameras, self.cfg.width, self.cfg.height,
                           bodies_per_world=self.sim.model.body_count // self.cfg.worlds)

    def dataset_spec(self, **options: Any):
        """The :class:`~stages.dataset.DatasetSpec` of this engine's frames: the embodiment's state
        and action layout and robot type, ``fps``, the recorded cameras (RGB + depth)."""
        from stages.dataset import CameraSpec, DatasetSpec
        from stages.embodiment.layout import action_names, state_names

        cams = tuple(CameraSpec(c, height=self.cfg.height, width=self.cfg.width) for c in self.cfg.cameras)
        return DatasetSpec(arm_dof=self.spec.arm_dof, fps=self.fps, robot_type=self.spec.robot_type,
                           cameras=cams, state_layout=tuple(state_names(self.spec)),
                           action_layout=tuple(action_names(self.spec)), **options)

    # ------------------------------------------------------------------ world state
    def joint_value(self, world: int, path: str) -> float:
        """The value [m or rad] of scene joint ``path`` (prim path) in ``world``."""
        j = self._path_joint.get(path)
        if j is None:
            raise KeyError(f"joint {path} is not in the simulated scene {self.world.usd}")
        q = self.sim.state.joint_q.numpy()
        return float(q[self._q_start[world * self._joints_per_world + j]])

    def _world_coords(self, world: int) -> tuple[slice, slice]:
        jn = self._joints_per_world
        q0, qd0 = self._q_start[world * jn], self._qd_start[world * jn]
        q1 = self._q_start[(world + 1) * jn] if world + 1 < self.cfg.worlds else len(self._home_q)
        qd1 = self._qd_start[(world + 1) * jn] if world + 1 < self.cfg.worlds else len(self._home_qd)
        return slice(q0, q1), slice(qd0, qd1)

    def reset_world(self, world: int, inst: Any) -> None:
        """World ``world`` back to the kitchen at rest, the instance's scene joints set, the robot
        standing at ``inst.start_base``; its commands, mode and arm targets cleared."""
        import newton
        import warp as wp

        from stages.demos.sampling import object_coords

        sq, sqd = self._world_coords(world)
        jn = self._joints_per_world
        for st in (self.sim.state, self.sim._next):
            q, qd = wp.to_torch(st.joint_q), wp.to_torch(st.joint_qd)
            q[sq] = q.new_tensor(self._home_q[sq])
            qd[sqd] = 0.0
            for path, value in inst.joints.items():
                j = self._path_joint.get(path)
                if j is None:
                    raise KeyError(f"joint {path} of {inst.task} is not in the simulated scene "
                                   f"{self.world.usd}")
                q[int(self._q_start[world * jn + j])] = float(value)
            for path, pose in inst.objects.items():
                j = self._free_joint.get(path)
                if j is None:
                    raise KeyError(f"object {path} of {inst.task} is not a free body of the simulated scene "
                                   f"{self.world.usd}")
                q0 = int(self._q_start[world * jn + j])
                q[q0:q0 + 7] = q.new_tensor(object_coords(pose))
        x, y, yaw = inst.start_base
        self.grasp_arm.pop(world, None)
        self.sim.reset([world], xy=[[x, y]], yaw=[yaw])
        st = self.sim.state
        newton.eval_fk(self.sim.model, st.joint_q, st.joint_qd, st)

    def object_pose(self, world: int, path: str) -> Any:
        """The pose (``asset_model.Pose``, world frame) of the scene body ``path`` in ``world``."""
        from stages.engine.humanoid_hands import pose_of

        b = self._path_body.get(path)
        if b is None:
            raise KeyError(f"body {path} is not in the simulated scene {self.world.usd}")
        return pose_of(self.sim.state.body_q.numpy()[b + world * self.bodies_per_world])

    def predicate_state(self, world: int) -> Any:
        """The task predicates' view of ``world`` now (``humanoid_hands.HumanoidPredicateState``):
        scene joints, free objects, and the hand that last closed (none: the right arm's)."""
        from stages.engine.humanoid_hands import HandRobot, HumanoidPredicateState, pose_of

        rt = self.sim.runtime
        robot = None
        if rt.hands.arms:
            arm = self.grasp_arm.get(world, rt.hands.arms[-1])
            ee = rt.ee_pose_world(self.sim.state, arm)[world]
            closed = float(rt.hands.command[world, rt.hands.arms.index(arm)])
            robot = HandRobot(ee_pose=pose_of(np.concatenate([ee[:3, 3], _quat_xyzw(ee[:3, :3])])),
                              gripper_opening=0.08 * (1.0 - closed))
        return HumanoidPredicateState(objects=_Objects(self, world), robot=robot,
                                      scene_joints=_SceneJoints(self, world))

    # ------------------------------------------------------------------ the loop
    def run(self, next_instance: Callable[[int], Any], program: Program, *,
            begin: Callable[[int, Any], Callable | None] | None = None,
            end: Callable[[int, Any, EpisodeResult], None] | None = None) -> None:
        """Run every world's episodes until ``next_instance`` has none left for any world (module
        docstring). ``begin(w, inst)`` may return a frame sink (``add_frame(Frame)``)."""
        from stages.locomotion.embodiment import frame_vectors

        n = self.cfg.worlds
        eps: dict[int, _Episode | None] = {}
        waiting = set(range(n))   # worlds to start at the next synchronisation point
        done: set[int] = set()
        limit = int(round(self.cfg.max_seconds / self.dt))
        while len(done) < n:
            if self.step_count % self.cfg.frame_every == 0:
                for w in sorted(waiting):
                    inst = next_instance(w)
                    if inst is None:
                        done.add(w)
                        eps[w] = None
                        self.sim.runtime.set_mode([1], [w])
                        continue
                    self.reset_world(w, inst)
                    sink = begin(w, inst) if begin else None
                    eps[w] = _Episode(inst, program(WorldHandle(self, w), inst), sink, self.step_count,
                                      time.perf_counter())
                waiting.clear()
            for w in range(n):                        # the programs, in world order
                ep = eps.get(w)
                if ep is None:
                    continue
                reason = self._resume(ep)
                if reason is None and self.step_count - ep.start_step >= limit:
                    reason = ("timeout", f"time limit {self.cfg.max_seconds} s")
                if reason is not None:
                    self._finish(w, ep, reason, end)
                    eps[w] = None
                    waiting.add(w)
            recording = [w for w in range(n) if eps.get(w) is not None and eps[w].sink is not None
                         and (self.step_count - eps[w].start_step) % self.cfg.frame_every == 0]
            if recording:
                self._record(recording, eps, frame_vectors)
            if all(eps.get(w) is None for w in range(n)) and len(done) == n:
                break
            self.sim.step()
            self.step_count += 1

    def _resume(self, ep: _Episode) -> tuple[str, str] | None:
        """Run the program if its wait is over; None while it runs, else (reason, detail) ("" on return)."""
        if ep.wait > 1:
            ep.wait -= 1
            return None
        try:
            ep.wait = int(next(ep.program))
        except StopIteration:
            return ("", "")
        except ExpertFailure as e:
            return (e.reason, str(e))
        return None

    def _finish(self, w: int, ep: _Episode, reason: tuple[str, str], end: Callable | None) -> None:
        from stages.demos.tasks import task

        ok, why = task(ep.inst.task).success(ep.inst, self.predicate_state(w))
        if reason[0]:
            ok, why = False, reason[0]
        res = EpisodeResult(success=bool(ok), reason="" if ok else why, detail=reason[1], frames=ep.frames,
                            sim_seconds=(self.step_count - ep.start_step) * self.dt,
                            wall_seconds=time.perf_counter() - ep.wall0)
        if end:
            end(w, ep.inst, res)

    def _record(self, worlds: list[int], eps: dict, frame_vectors) -> None:
        from stages.dataset import Frame, depth_m_to_mm

        state, action = frame_vectors(self.sim.runtime, self.sim.state)
        images = self.rig.render() if self.rig is not None else {}
        mode = self.sim.runtime.mode.cpu().numpy()
        for w in worlds:
            rgb = {c: f.rgb[w] for c, f in images.items()}
            depth = {c: depth_m_to_mm(f.depth[w]) for c, f in images.items()}
            eps[w].sink(Frame.of_vectors(state[w], action[w], int(mode[w]), rgb, depth))
            eps[w].frames += 1


def add_hand_spheres(robot: Any, spec: Any, radius: float) -> list[int]:
    """One collision sphere of ``radius`` [m] per arm of ``spec`` on its tip link at the end-effector
    offset ``ee_xyz`` (the hands' contact with the scene); returns the shape indices. The spheres are
    massless: the links keep the description's inertials, which the arms' gravity feed-forward
    (Pinocchio) assumes (at the default density of 1000 kg/m^3 a 4.5 cm sphere added 0.38 kg to
    each hand, which then held a point 30 mm low and short)."""
    import dataclasses

    import warp as wp

    cfg = dataclasses.replace(robot.default_shape_cfg, density=0.0)
    bodies = [label.rsplit("/", 1)[-1] for label in robot.body_label]
    out = []
    for arm in spec.arms:
        if arm.tip_link not in bodies:
            raise ValueError(f"{spec.name}: arm {arm.name}'s tip link {arm.tip_link} is not a body of the "
                             "robot")
        out.append(robot.shape_count)
        robot.add_shape_sphere(bodies.index(arm.tip_link),
                               xform=wp.transform(tuple(arm.ee_xyz), wp.quat_identity()), radius=radius,
                               cfg=cfg)
    return out
