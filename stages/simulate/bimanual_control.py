"""Control of the dual-arm platform (:mod:`stages.simulate.dual_arm`) in a Sim: joint targets of
both arms, one gripper command per arm, and end-effector targets by per-arm CLIK.

- :class:`BimanualControl`: :class:`stages.simulate.control.RobotControl` (base velocity, arm
  targets, uploads before each step) with the grippers commanded per arm;
- :class:`BimanualIk`: the spec's CLIK (:class:`stages.embodiment.clik.UpperBodyClik`) on the
  Pinocchio model of the same URDF; poses in the robot's root frame (``mobile_root``, the spawn
  frame), configurations from the Sim;
- :func:`move_arms`: both TCPs along straight Cartesian paths (orientations slerped) at once,
  each waypoint solved for both arms from the previous solution, joint targets interpolated.

Frames: world and root frames Z up, metres, radians; 4x4 poses.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from stages.simulate.control import Clik, RobotControl, pose


class BimanualControl(RobotControl):
    """Commands for the dual-arm robot in every world of a Sim (see :class:`RobotControl`):
    ``set_arm_targets`` takes both arms' joints (12,) [rad] in the description's order."""

    def set_gripper(self, command: float, world: int | None = None, arm: str | None = None) -> None:
        """Gripper command in [0, 1] (0 open, 1 closed and squeezing) of ``arm`` (None: both)."""
        arms = self.desc.arms.values() if arm is None else (self.desc.arms[arm],)
        for a in arms:
            q = a.finger_targets(command)
            for w in self._worlds(world):
                for n, v in zip(a.fingers, q, strict=True):
                    self._targets[self._c(n, w)] = v
        self._dirty = True

    def arm_targets_of(self, arm: str, world: int = 0) -> np.ndarray:
        """The joint targets (6,) [rad] of one arm."""
        return np.array([self._targets[self._c(n, world)] for n in self.desc.arms[arm].joints])


class BimanualIk:
    """Per-arm CLIK of a :class:`stages.simulate.dual_arm.DualArmDescription` (its spec's arms on
    the Pinocchio model of its URDF); ``config``: a :class:`stages.embodiment.clik.ClikConfig`."""

    def __init__(self, desc, config=None) -> None:
        from stages.embodiment.clik import UpperBodyClik
        from stages.embodiment.kinematics import build_model

        self.desc = desc
        self.clik = UpperBodyClik(desc.spec, build_model(desc.spec, desc.urdf), config)
        self.model = self.clik.model
        self.idx_q = self.clik.kin.idx_q

    def from_sim(self, sim, world: int = 0, ctl: BimanualControl | None = None) -> np.ndarray:
        """Pinocchio configuration (nq,) of the robot in ``sim``; with ``ctl`` the arms at their
        joint targets instead of their measured positions (where the controller is heading)."""
        jq = sim.state_0.joint_q.numpy()
        q = self.clik.default_q()
        for n, i in self.idx_q.items():
            q[i] = jq[sim.world_coord(n, world)]
        if ctl is not None:
            for name, a in self.desc.arms.items():
                q[self.clik.arms[name].q_idx] = ctl.arm_targets_of(name, world)
        return q

    def ee_pose(self, q: np.ndarray, arm: str) -> np.ndarray:
        """TCP pose (4, 4) of ``arm`` in the root frame."""
        return self.clik.ee_pose(q, arm)

    def solve(self, targets: Mapping[str, np.ndarray], q0: np.ndarray):
        """Both (or the named) arms to ``targets`` (arm -> 4x4, root frame) from ``q0`` (nq,);
        returns the :class:`stages.embodiment.clik.ClikResult` of one world."""
        return self.clik.solve(dict(targets), q0)

    def arm_q(self, q: np.ndarray, arm: str) -> np.ndarray:
        return np.asarray(q)[..., self.clik.arms[arm].q_idx]


def move_arms(sim, ctl: BimanualControl, ik: BimanualIk, targets_world: Mapping[str, np.ndarray],
              duration: float, *, world: int = 0, segments: int = 1, settle: float = 0.0, tol: float = 0.003,
              rot_tol: float = float(np.deg2rad(2.0)), target_every: int = 10):
    """Move the TCPs of the arms named in ``targets_world`` (arm -> 4x4 world pose) to their targets
    in ``duration`` [s] along straight lines, in ``segments`` CLIK waypoints (both arms solved
    together at each), the joint targets interpolated between waypoints and updated every
    ``target_every`` physics steps; then ``settle`` [s] more. Returns the last CLIK result;
    raises RuntimeError when a waypoint is missed by more than ``tol`` [m] / ``rot_tol`` [rad]."""
    from scipy.spatial.transform import Rotation, Slerp

    names = tuple(targets_world)
    q_pin = ik.from_sim(sim, world, ctl)
    start = {a: ik.ee_pose(q_pin, a) for a in names}
    goal = {a: Clik.world_to_root(sim.spawn, targets_world[a]) for a in names}
    slerp = {a: Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([start[a][:3, :3], goal[a][:3, :3]])))
             for a in names}
    per_seg = max(1, int(round(duration / sim.settings.dt)) // segments)
    res = None
    for k in range(1, segments + 1):
        s = k / segments
        wps = {a: pose(start[a][:3, 3] + s * (goal[a][:3, 3] - start[a][:3, 3]), slerp[a]([s]).as_matrix()[0])
               for a in names}
        res = ik.solve(wps, q_pin)
        if res.position_error.max() > tol or res.rotation_error.max() > rot_tol:
            pe, re = np.round(res.position_error, 4).tolist(), np.round(res.rotation_error, 4).tolist()
            raise RuntimeError(f"CLIK: waypoint {k}/{segments} of {names} unreachable "
                               f"(errors {pe} m, {re} rad)")
        q1 = res.q[0]
        arms0 = ctl.arm_targets()
        arms1 = arms0.copy()
        i = 0
        for a, info in ik.desc.arms.items():   # the description's arm-joint order: arm after arm
            if a in names:
                arms1[i:i + len(info.joints)] = ik.arm_q(q1, a)
            i += len(info.joints)
        chunk = max(1, min(per_seg // 10, target_every))
        for i in range(0, per_seg, chunk):
            ctl.set_arm_targets(arms0 + (arms1 - arms0) * min(1.0, (i + chunk) / per_seg), world)
            sim.step(chunk)
        q_pin = q1
    if settle > 0:
        sim.step(int(round(settle / sim.settings.dt)))
    return res
