"""Robot control: base velocity, arm joint targets, gripper, and end-effector targets by CLIK.

- Base: a command a = (vx, vy, v_theta) in the base frame [m/s, m/s, rad/s] per world. Before
  every physics step it is rotated into the spawn frame with the current yaw and written as the
  velocity targets of the base's x, y, yaw joints (velocity drives with force limits, so a wall
  stops the base instead of the base going through it).
- Arm: position targets for the 7 joints [rad], clipped to the joint limits.
- Gripper: a command in [0, 1] (0 open, 1 closed) mapped linearly to both finger targets; the
  finger force limit bounds the grip force.
- End-effector: :class:`Clik`, closed-loop inverse kinematics on the Pinocchio model of the same
  URDF: damped least squares on the SE(3) log error, step clipped, joint limits enforced by
  clipping every iterate; optionally the base joints move too.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from stages.simulate.clik_lanes import IkResult, _solve1, solve_lanes
from stages.simulate.cooperative import checkpoint
from stages.simulate.launch_cache import LaunchCache
from stages.simulate.robot import RobotDescription

log = logging.getLogger(__name__)


def _base_kernel():
    import warp as wp

    @wp.kernel
    def base_velocity_to_joint_targets(
        cmd: wp.array[wp.vec3f],
        joint_q: wp.array[wp.float32],
        target_qd: wp.array[wp.float32],
        yaw_coord: int,
        dof_x: int,
        dof_y: int,
        dof_yaw: int,
        coords_per_world: int,
        dofs_per_world: int,
    ):
        w = wp.tid()
        c = cmd[w]
        th = joint_q[yaw_coord + w * coords_per_world]
        s = wp.sin(th)
        co = wp.cos(th)
        o = w * dofs_per_world
        target_qd[dof_x + o] = co * c[0] - s * c[1]
        target_qd[dof_y + o] = s * c[0] + co * c[1]
        target_qd[dof_yaw + o] = c[2]

    return base_velocity_to_joint_targets


_KERNEL = None


class CommandBuffers:
    """Host-side robot commands of every world: drive position targets (W*C,) in the model's
    joint-coordinate layout and base commands (W, 3) [m/s, m/s, rad/s]. ``coord``: the robot's
    world-0 coordinate index per joint name; ``coords_per_world``: C. The arrays may be shared
    memory (the engine's world programs in other processes write them); ``dirty`` flags say what
    changed since the last upload."""

    def __init__(self, desc: RobotDescription, coord: dict[str, int], coords_per_world: int,
                 arm_lower: np.ndarray, arm_upper: np.ndarray, targets: np.ndarray, cmd: np.ndarray) -> None:
        self.desc, self.coord, self.coords_per_world = desc, dict(coord), coords_per_world
        self.arm_lower, self.arm_upper = np.asarray(arm_lower, float), np.asarray(arm_upper, float)
        self._targets, self._cmd_np = targets, cmd
        self._dirty = self._cmd_dirty = False
        # world-0 coordinates of the arm's and the gripper's joints (a world's: + world * C)
        self._arm_idx = np.array([self.coord[n] for n in desc.arm_joints], np.int64)
        # a description without one gripper (the dual-arm platform: fingers per arm) sets its
        # fingers by name; the indices are needed only by the one-gripper calls
        grip = getattr(desc, "gripper", None)
        self._finger_idx = np.array([self.coord[n] for n in (grip.finger_joints if grip else ())], np.int64)

    def _at(self, idx: np.ndarray, world: int | None) -> np.ndarray:
        """Flat indices of world-0 coordinates ``idx`` in ``world`` (None: every world, world-major)."""
        if world is None:
            return (np.arange(len(self._cmd_np))[:, None] * self.coords_per_world + idx).ravel()
        return idx + world * self.coords_per_world

    def _c(self, name: str, world: int) -> int:
        return self.coord[name] + world * self.coords_per_world

    def _per_world(self, q: np.ndarray, world: int | None) -> np.ndarray:
        """Values ``q`` for the indices :meth:`_at` gives (repeated for every world when None)."""
        return q if world is not None else np.tile(q, len(self._cmd_np))

    def set_base_velocity(self, vx: float, vy: float, vtheta: float, world: int | None = None) -> None:
        """Base-frame velocity command [m/s, m/s, rad/s] for one world (or all)."""
        sel = slice(None) if world is None else world
        self._cmd_np[sel] = (vx, vy, vtheta)
        self._cmd_dirty = True

    def set_arm_targets(self, q: np.ndarray, world: int | None = None) -> None:
        """Arm joint position targets (7,) [rad], clipped to the limits."""
        q = np.clip(np.asarray(q, float), self.arm_lower, self.arm_upper)
        self._targets[self._at(self._arm_idx, world)] = self._per_world(q, world)
        self._dirty = True

    def set_gripper(self, command: float, world: int | None = None) -> None:
        """Gripper command in [0, 1]: 0 fully open, 1 fully closed. The finger targets go linearly
        from open to closed, and at 1 ``squeeze`` past closed so that the drive pushes with up to
        its force limit on whatever is between the fingers (joint limits stop empty fingers)."""
        q = np.asarray(self.desc.gripper.finger_targets(command), float)
        self._targets[self._at(self._finger_idx, world)] = self._per_world(q, world)
        self._dirty = True

    def set_finger_targets(self, q: np.ndarray, world: int | None = None) -> None:
        """Finger joint position targets (n,) [m or rad] in ``desc.gripper.finger_joints`` order (a
        dexterous hand's retargeted posture, not its synergy); the joint limits bound the motion."""
        g = self.desc.gripper
        q = np.asarray(q, float)
        if q.shape != (len(g.finger_joints),) or not np.all(np.isfinite(q)):
            raise ValueError(f"finger targets: expected {len(g.finger_joints)} finite values, got shape {q.shape}")
        for w in self._worlds(world):
            for n, v in zip(g.finger_joints, q, strict=True):
                self._targets[self._c(n, w)] = v
        self._dirty = True

    def finger_targets(self, world: int = 0) -> np.ndarray:
        """The finger joints' current position targets (n,) [m or rad]."""
        return self._targets[self._at(self._finger_idx, world)]

    def arm_targets(self, world: int = 0) -> np.ndarray:
        """The arm joints' current position targets (7,) [rad] (a copy)."""
        return self._targets[self._at(self._arm_idx, world)]

    def _worlds(self, world):
        return range(len(self._cmd_np)) if world is None else (world,)


class RobotControl(CommandBuffers):
    """Commands for the robot in every world of a Sim; registers itself as a pre-step callback
    that uploads what changed and turns base commands into base joint velocity targets.

    Arrays: base commands (W, 3); arm and finger targets (the model's joint-coordinate layout),
    written into ``sim.control.joint_target_q`` before the next step. Execution offsets per world
    (:meth:`set_execution_offset`) are added to the uploaded arm targets and base commands only.
    """

    def __init__(self, sim) -> None:
        import warp as wp

        global _KERNEL
        if _KERNEL is None:
            _KERNEL = _base_kernel()
        self.sim = sim
        nw = sim.world_count
        self._cmd = wp.zeros(nw, dtype=wp.vec3f, device=sim.model.device)
        lo = sim.model.joint_limit_lower.numpy()
        hi = sim.model.joint_limit_upper.numpy()
        desc = sim.desc
        super().__init__(desc, sim.robot.coord, sim.coords_per_world,
                         np.array([lo[sim.robot.dof[n]] for n in desc.arm_joints]),
                         np.array([hi[sim.robot.dof[n]] for n in desc.arm_joints]),
                         sim.control.joint_target_q.numpy().copy(), np.zeros((nw, 3), np.float32))
        self._default_targets = sim.model.joint_target_q.numpy().copy()
        # execution offsets (DART noise, stages.engine.action_noise): added to what is uploaded,
        # never stored in the command buffers (a recorder reads the clean commands there)
        self._arm_off = np.zeros((nw, len(desc.arm_joints)))
        self._base_off = np.zeros((nw, 3), np.float32)
        # the base kernel, replayed from recorded launches (one per state buffer: they alternate)
        self._launch = LaunchCache(_KERNEL, nw, sim.model.device)
        sim.pre_step.append(self._pre_step)

    def bind(self, targets: np.ndarray, cmd: np.ndarray) -> None:
        """Use ``targets`` (W*C,) and ``cmd`` (W, 3) (e.g. shared memory) as the command buffers,
        filled with the current commands."""
        targets[:] = self._targets
        cmd[:] = self._cmd_np
        self._targets, self._cmd_np = targets, cmd

    def set_execution_offset(self, world: int, arm: np.ndarray | None = None,
                             base: np.ndarray | None = None) -> None:
        """Offsets that world ``world`` executes on top of its commands from the next step on: arm
        joint offsets (A,) [rad] (A arm joints, 7 for the Panda) added to the arm targets (the sum clipped to the joint limits) and
        base velocity offsets (3,) [m/s, m/s, rad/s] added to the base-frame command; None: zero.
        Only the simulation sees them: ``_targets`` / ``_cmd_np`` (what a recorder reads) keep the
        commands as given."""
        arm = np.zeros(self._arm_off.shape[1]) if arm is None else np.asarray(arm, float)
        base = np.zeros(3, np.float32) if base is None else np.asarray(base, np.float32)
        if arm.shape != self._arm_off.shape[1:] or base.shape != (3,):
            raise ValueError(f"execution offset: arm {self._arm_off.shape[1:]} and base (3,) expected, "
                             f"got {arm.shape} and {base.shape}")
        if not np.array_equal(arm, self._arm_off[world]):
            self._arm_off[world] = arm
            self._dirty = True
        if not np.array_equal(base, self._base_off[world]):
            self._base_off[world] = base
            self._cmd_dirty = True

    def executed_targets(self) -> np.ndarray:
        """The drive position targets (W*C,) float32 uploaded to the simulation: the commands
        plus the arm execution offsets, clipped to the arm's joint limits."""
        t = self._targets.astype(np.float32)
        if self._arm_off.any():
            at = self._at(self._arm_idx, None).reshape(self._arm_off.shape)
            t[at] = np.clip(self._targets[at] + self._arm_off, self.arm_lower, self.arm_upper)
        return t

    def executed_base(self) -> np.ndarray:
        """The base-frame velocity commands (W, 3) float32 [m/s, m/s, rad/s] the simulation
        executes: the commands plus the base execution offsets."""
        return self._cmd_np + self._base_off if self._base_off.any() else self._cmd_np

    def mark_dirty(self) -> None:
        """Upload targets and base commands before the next step (they were written elsewhere)."""
        self._dirty = self._cmd_dirty = True

    def reset(self) -> None:
        """After ``sim.reset()``: zero base commands and take the drive targets from the sim."""
        self._cmd_np[:] = 0.0
        self._arm_off[:] = 0.0
        self._base_off[:] = 0.0
        self._cmd.assign(self._cmd_np)
        self._targets[:] = self.sim.control.joint_target_q.numpy()
        self._dirty = self._cmd_dirty = False

    def reset_world(self, world: int) -> None:
        """World ``world`` only: zero base command, drive targets back to the model's defaults
        (uploaded with the next step, with every other world's targets unchanged)."""
        c = self.sim.coords_per_world
        sl = slice(world * c, (world + 1) * c)
        self._targets[sl] = self._default_targets[sl]
        self._cmd_np[world] = 0.0
        self._arm_off[world] = 0.0
        self._base_off[world] = 0.0
        self._dirty = self._cmd_dirty = True

    # -- per-step --------------------------------------------------------------------------
    def _pre_step(self, sim) -> None:
        if self._dirty:
            sim.control.joint_target_q.assign(self.executed_targets())
            self._dirty = False
        if self._cmd_dirty:
            self._cmd.assign(self.executed_base())
            self._cmd_dirty = False
        r = sim.robot
        self._launch.launch([self._cmd, sim.state_0.joint_q, sim.control.joint_target_qd, r.coord["base_yaw"],
                             r.dof["base_x"], r.dof["base_y"], r.dof["base_yaw"], sim.coords_per_world,
                             sim.dofs_per_world])


# --------------------------------------------------------------------------------------------
# CLIK
# --------------------------------------------------------------------------------------------


class Clik:
    """Closed-loop IK for the robot's end-effector frame on its Pinocchio model.

    Poses are 4x4 in the robot root (spawn) frame; use :meth:`world_to_root` for world targets.
    ``move_base``: also use the base x, y, yaw joints.
    """

    #: iterations without 0.1% progress after which a solve gives up (0: run to max_iters)
    stall_iters: int = 30

    def __init__(
        self, desc: RobotDescription, *, damping: float = 1e-3, max_step: float = 0.2, move_base: bool = False
    ) -> None:
        import pinocchio as pin

        from stages.simulate.robot_load import build_pinocchio_model

        self.desc = desc
        self.model = build_pinocchio_model(desc)
        self.data = self.model.createData()
        self.frame = self.model.getFrameId(desc.ee_frame)
        self.damping = damping
        self.max_step = max_step
        names = list(desc.arm_joints) + (list(desc.base_joints) if move_base else [])
        self.v_idx = np.array([self.model.joints[self.model.getJointId(n)].idx_v for n in names])
        self.q_idx = {n: self.model.joints[self.model.getJointId(n)].idx_q for n in self.model.names[1:]}
        self.lower = self.model.lowerPositionLimit.copy()
        self.upper = self.model.upperPositionLimit.copy()
        self._pin = pin
        # the solver's invariants: the damping term, the Jacobian's columns as a slice where they
        # are contiguous, and whether pin.integrate is a plain sum (1-DoF joints of one coordinate)
        self._damp = self.damping * np.eye(6)
        lo = int(self.v_idx[0]) if len(self.v_idx) else 0
        contiguous = np.array_equal(self.v_idx, np.arange(lo, lo + len(self.v_idx)))
        self._cols = slice(lo, lo + len(self.v_idx)) if contiguous else self.v_idx
        self._additive = self.model.nq == self.model.nv and all(
            j.nq == 1 and j.nv == 1 and ("Revolute" in j.shortname() or "Prismatic" in j.shortname()
                                         or j.shortname()[-2:] in ("RX", "RY", "RZ", "PX", "PY", "PZ"))
            and "Unbounded" not in j.shortname() for j in self.model.joints[1:])

    def neutral(self) -> np.ndarray:
        q = self._pin.neutral(self.model)
        for n, v in zip(self.desc.arm_joints, self.desc.arm_home, strict=True):
            q[self.q_idx[n]] = v
        for n, v in zip(self.desc.gripper.finger_joints, self.desc.gripper.finger_targets(0.0), strict=True):
            q[self.q_idx[n]] = v
        return q

    def fk(self, q: np.ndarray, frame: str | None = None) -> np.ndarray:
        """4x4 pose of ``frame`` (default: the end-effector) in the root frame."""
        pin = self._pin
        pin.framesForwardKinematics(self.model, self.data, q)
        fid = self.frame if frame is None else self.model.getFrameId(frame)
        return self.data.oMf[fid].homogeneous.copy()

    def arm_q(self, q: np.ndarray) -> np.ndarray:
        return np.array([q[self.q_idx[n]] for n in self.desc.arm_joints])

    def with_arm(self, q: np.ndarray, arm: np.ndarray) -> np.ndarray:
        q = q.copy()
        for n, v in zip(self.desc.arm_joints, arm, strict=True):
            q[self.q_idx[n]] = v
        return q

    def solve(
        self,
        target: np.ndarray,
        q0: np.ndarray,
        *,
        max_iters: int = 300,
        pos_tol: float = 1e-4,
        rot_tol: float = 1e-3,
        restarts: int = 0,
        rng: np.random.Generator | None = None,
    ) -> IkResult:
        """Damped least squares: dq = J^T (J J^T + lambda I)^-1 e, with e the SE(3) log error in the
        local frame; iterates are clipped to the joint limits. ``target`` 4x4 in the root frame.

        When a solve ends in a local minimum (a joint limit), up to ``restarts`` more solves start
        from random in-limit arm configurations drawn from ``rng``; the best result is returned."""
        checkpoint()  # between solves: a cooperative scheduler may run another world here
        best = self._solve(target, q0, max_iters, pos_tol, rot_tol)
        for _ in range(restarts if not best.success else 0):
            if rng is None:
                raise ValueError("restarts need an rng")
            q = np.asarray(q0, float).copy()
            idx = self.v_idx[: len(self.desc.arm_joints)]
            q[idx] = rng.uniform(self.lower[idx], self.upper[idx])
            res = self._solve(target, q, max_iters, pos_tol, rot_tol)
            if (
                res.position_error + 0.1 * res.rotation_error
                < best.position_error + 0.1 * best.rotation_error
            ):
                best = res
            if best.success:
                break
        return best

    def solve_many(self, targets, q0s, *, max_iters: int = 300, pos_tol: float = 1e-4, rot_tol: float = 1e-3,
                   restarts: int = 0, rngs=None, width: int = 32) -> list[IkResult]:
        """:meth:`solve` for each (target, q0, rng) of ``targets``, ``q0s``, ``rngs`` (one
        generator per solve, for ``restarts``), the same results computed in lockstep
        (:mod:`stages.simulate.clik_lanes`), ``width`` at a time."""
        return solve_lanes(self, targets, q0s, max_iters=max_iters, pos_tol=pos_tol, rot_tol=rot_tol,
                           restarts=restarts, rngs=rngs, width=width)

    def _solve(self, target, q0, max_iters, pos_tol, rot_tol) -> IkResult:
        """One damped-least-squares solve from ``q0``. The arithmetic is that of the plain loop
        (``tests/stages/expert_reference.py``; same iterates bit for bit) with fewer Python calls:
        one kinematics pass per iteration (``computeJointJacobians`` places the joints, the
        end-effector frame alone is placed), the Jacobian's columns sliced (into the column-major
        layout that fancy indexing gives, so that the products sum in the same order), norms as
        sqrt(x . x) as ``np.linalg.norm`` computes them, the solve by its gufunc, and
        ``pin.integrate`` as a sum where the joints are 1-DoF (checked in ``__init__``)."""
        pin = self._pin
        model, data, frame, cols = self.model, self.data, self.frame, self._cols
        jjt_fn, getj, local = pin.computeJointJacobians, pin.getFrameJacobian, pin.LOCAL
        upd, log6, sqrt, lower, upper = pin.updateFramePlacement, pin.log6, math.sqrt, self.lower, self.upper
        damp, max_step, stall, additive = self._damp, self.max_step, self.stall_iters, self._additive
        goal = pin.SE3(np.asarray(target, float))
        q = np.minimum(np.maximum(np.asarray(q0, float), lower), upper)  # np.clip's values, a new array
        v = np.zeros(model.nv)
        it = 0
        best, best_it = np.inf, 0
        placed, m = False, None  # whether data (and m, the end-effector placement) hold q's kinematics
        for it in range(1, max_iters + 1):  # noqa: B007 (the count is reported)
            jjt_fn(model, data, q)
            m = upd(model, data, frame)
            err = log6(m.actInv(goal)).vector
            placed = True
            ep, er = err[:3], err[3:]
            pe, re = sqrt(ep.dot(ep)), sqrt(er.dot(er))
            if pe < pos_tol and re < rot_tol:
                break
            # stalled (a joint limit, an unreachable target): no 0.1% progress in STALL_ITERS
            e = pe + 0.1 * re
            if e < best * (1.0 - 1e-3):
                best, best_it = e, it
            elif stall and it - best_it >= stall:
                break
            jac = np.asfortranarray(getj(model, data, frame, local)[:, cols])  # as [:, v_idx] lays it out
            dv = jac.T @ _solve1(jac @ jac.T + damp, err, signature="dd->d")
            n = sqrt(dv.dot(dv))
            if n > max_step:
                dv *= max_step / n
            v[cols] = dv
            q = np.minimum(np.maximum(q + v if additive else pin.integrate(model, q, v), lower), upper)
            placed = False
        if not placed:
            pin.forwardKinematics(model, data, q)
            m = upd(model, data, frame)
        dp = m.translation - goal.translation
        pe = sqrt(dp.dot(dp))
        r = pin.log3(m.rotation.T @ goal.rotation)
        re = sqrt(r.dot(r))
        return IkResult(
            q=q,
            success=pe < max(pos_tol, 1e-3) and re < max(rot_tol, 1e-2),
            position_error=pe,
            rotation_error=re,
            iterations=it,
        )

    @staticmethod
    def world_to_root(spawn_xy_yaw, pose_world: np.ndarray) -> np.ndarray:
        """A world 4x4 pose expressed in the robot root (spawn) frame."""
        return Clik.root_from_world(spawn_xy_yaw) @ np.asarray(pose_world, float)

    @staticmethod
    def root_from_world(spawn_xy_yaw) -> np.ndarray:
        """The 4x4 transform taking world poses into the robot root (spawn) frame (``world_to_root``
        multiplies by it; a caller converting many poses computes it once)."""
        x, y, yaw = spawn_xy_yaw
        c, s = np.cos(yaw), np.sin(yaw)
        t = np.array([[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, 0], [0, 0, 0, 1.0]])
        return np.linalg.inv(t)

    def from_sim(self, sim, world: int = 0) -> np.ndarray:
        """The Pinocchio configuration (nq,) of the robot's current joint positions in ``sim``."""
        jq = sim.state_0.joint_q.numpy()
        q = self._pin.neutral(self.model)
        for n, i in self.q_idx.items():
            q[i] = jq[sim.world_coord(n, world)]
        return q


def pose(position, rotation=None) -> np.ndarray:
    """4x4 from a position (3,) and a rotation matrix (3, 3) (default identity)."""
    m = np.eye(4)
    m[:3, 3] = position
    if rotation is not None:
        m[:3, :3] = rotation
    return m


def top_down(yaw: float = 0.0) -> np.ndarray:
    """Rotation of a gripper pointing straight down (tool Z along world -Z), fingers closing along
    the world direction at angle ``yaw`` + 90 deg."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, s, 0.0], [s, -c, 0.0], [0.0, 0.0, -1.0]])


#: move_ee updates the joint targets at least every this many physics steps (a target that jumps by
#: a tenth of a long segment at once whips a light wrist joint to several rad/s)
TARGET_EVERY = 10


def move_ee(
    sim,
    ctl: RobotControl,
    ik: Clik,
    target_world: np.ndarray,
    duration: float,
    *,
    world: int = 0,
    segments: int = 1,
    settle: float = 0.0,
    rng: np.random.Generator | None = None,
    tol: float = 0.005,
    rot_tol: float = float(np.deg2rad(2.0)),
    max_joint_speed: float | None = None,
) -> IkResult:
    """Move the end-effector to ``target_world`` (4x4, world frame) in ``duration`` [s]: the
    straight Cartesian path is cut into ``segments`` poses (orientation slerped), each solved by
    CLIK from the previous solution, and the joint targets are interpolated linearly between them
    while the simulation steps; then ``settle`` [s] more. ``max_joint_speed`` [rad/s]: a segment
    whose joint targets would move faster takes longer. Returns the last IK result (raises
    RuntimeError if a waypoint cannot be reached within ``tol`` [m] and ``rot_tol`` [rad])."""
    from scipy.spatial.transform import Rotation, Slerp

    q_pin = ik.with_arm(ik.from_sim(sim, world), ctl.arm_targets(world))
    start = ik.fk(q_pin)
    goal = Clik.world_to_root(sim.spawn, target_world)
    slerp = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([start[:3, :3], goal[:3, :3]])))
    steps_total = max(1, int(round(duration / sim.settings.dt)))
    per_seg = max(1, steps_total // segments)
    res = None
    for k in range(1, segments + 1):
        a = k / segments
        wp_pose = pose(start[:3, 3] + a * (goal[:3, 3] - start[:3, 3]), slerp([a]).as_matrix()[0])
        res = ik.solve(wp_pose, q_pin, max_iters=600, restarts=10 if rng is not None else 0, rng=rng)
        if res.position_error > tol or res.rotation_error > rot_tol:
            raise RuntimeError(
                f"CLIK: waypoint {k}/{segments} unreachable (error {res.position_error:.4f} m)"
            )
        q0, q1 = ctl.arm_targets(world), ik.arm_q(res.q)
        n_seg = per_seg
        if max_joint_speed:
            n_seg = max(n_seg, int(np.ceil(np.abs(q1 - q0).max() / max_joint_speed / sim.settings.dt)))
        chunk = max(1, min(n_seg // 10, TARGET_EVERY))
        for i in range(0, n_seg, chunk):
            ctl.set_arm_targets(q0 + (q1 - q0) * min(1.0, (i + chunk) / n_seg), world)
            sim.step(chunk)
        q_pin = res.q
    if settle > 0:
        sim.step(int(round(settle / sim.settings.dt)))
    return res
