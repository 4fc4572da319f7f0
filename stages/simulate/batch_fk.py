"""Forward kinematics of the arm's end effector for many configurations at once (numpy).

The recorder needs, for every recording world and every frame, the end-effector pose in the base
frame for the measured arm joints and for the arm's joint targets: two FK solves per world-frame,
which Pinocchio does one configuration at a time (plus a rotation-to-quaternion conversion each).
:class:`ArmFK` walks the same Pinocchio model once, keeps the chain from the root to the
end-effector frame as fixed placements and revolute joints, and evaluates it for K configurations
as K-batched 4x4 products; :func:`pose7_batch` converts K poses to (x, y, z, qw, qx, qy, qz) in one
call. Joints of the chain that are not arm joints (the base's) stay at the configuration given at
construction. Equal to :meth:`~stages.simulate.control.Clik.fk` within float64 rounding.
"""

from __future__ import annotations

import numpy as np

_AXES = {"JointModelRX": (1.0, 0.0, 0.0), "JointModelRY": (0.0, 1.0, 0.0), "JointModelRZ": (0.0, 0.0, 1.0)}


def _rot(axis: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(K, 4, 4) rotations by angles ``q`` (K,) [rad] about the unit ``axis`` (3,) (Rodrigues)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    s, c = np.sin(q)[:, None, None], np.cos(q)[:, None, None]
    out = np.zeros((len(q), 4, 4))
    out[:, :3, :3] = np.eye(3) + s * k + (1.0 - c) * (k @ k)
    out[:, 3, 3] = 1.0
    return out


class ArmFK:
    """End-effector pose in the root frame for batches of arm configurations.

    ``ik``: a :class:`~stages.simulate.control.Clik` (its Pinocchio model, end-effector frame and
    arm joints); ``q_rest``: the full configuration (nq,) the other joints keep (default
    ``ik.neutral()``)."""

    def __init__(self, ik, q_rest: np.ndarray | None = None) -> None:
        import pinocchio as pin

        model = ik.model
        q_rest = ik.neutral() if q_rest is None else np.asarray(q_rest, float)
        arm = {model.getJointId(n): i for i, n in enumerate(ik.desc.arm_joints)}
        fr = model.frames[ik.frame]
        chain = []
        j = fr.parentJoint
        while j > 0:
            chain.append(j)
            j = model.parents[j]
        # steps from the root outwards: ("fixed", 4x4) or ("arm", index, axis)
        self._steps: list[tuple] = []
        for j in reversed(chain):
            self._steps.append(("fixed", model.jointPlacements[j].homogeneous.copy()))
            jm = model.joints[j]
            if j in arm:
                name = jm.shortname()
                if name in _AXES:
                    axis = np.array(_AXES[name])
                elif name == "JointModelRevoluteUnaligned":
                    axis = np.asarray(jm.extract().axis, float)
                else:
                    raise ValueError(f"ArmFK: arm joint {model.names[j]} is a {name}, not a revolute joint")
                self._steps.append(("arm", arm[j], axis / np.linalg.norm(axis)))
            else:
                jd = jm.createData()
                jm.calc(jd, q_rest)
                self._steps.append(("fixed", pin.SE3(jd.M).homogeneous.copy()))
        self._steps.append(("fixed", fr.placement.homogeneous.copy()))
        self.arm_count = len(arm)
        home = getattr(ik.desc, "arm_home", None)
        self.home_quat = None if home is None else pose7_batch(self(np.asarray(home, float)))[0, 3:]
        """(4,) w, x, y, z: the end effector's orientation at the arm's home pose (``desc.arm_home``;
        None without one), the reference hemisphere of recorded orientations (:func:`pose7_batch`)."""

    def __call__(self, arm_q: np.ndarray) -> np.ndarray:
        """(K, 4, 4) end-effector poses in the root frame for arm joint positions (K, arm_count) [rad]."""
        q = np.asarray(arm_q, float).reshape(-1, self.arm_count)
        out = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
        fixed = np.eye(4)
        for step in self._steps:
            if step[0] == "fixed":
                fixed = fixed @ step[1]
                continue
            out = out @ fixed @ _rot(step[2], q[:, step[1]])
            fixed = np.eye(4)
        return out @ fixed

    def pose7(self, arm_q: np.ndarray) -> np.ndarray:
        """(K, 7) x, y, z, qw, qx, qy, qz of the end effector for arm joint positions (K, arm_count)
        [rad], quaternions in the hemisphere of :attr:`home_quat` (what the recorders write)."""
        return pose7_batch(self(arm_q), self.home_quat)


def pose7_batch(m: np.ndarray, ref: np.ndarray | None = None) -> np.ndarray:
    """(K, 4, 4) -> (K, 7): x, y, z, qw, qx, qy, qz (as ``record.pose7``, per row), each quaternion
    in the hemisphere of ``ref`` (4,) w, x, y, z (q . ref >= 0; None: qw >= 0).

    q and -q are one rotation; the sign flips where q . ref changes sign, i.e. at rotations 180 deg
    from ``ref``. With qw >= 0 that is 180 deg from the identity, where a gripper pointing down
    lives (the Panda's home orientation is (0, 1, 0, 0)): its recorded quaternion then flipped
    with the sign of a qw of ~0.001 (666 flips within pick_place's 64 episodes, session 20). The
    engine passes the home orientation (:attr:`ArmFK.home_quat`): no flip in those episodes."""
    from scipy.spatial.transform import Rotation

    m = np.asarray(m, float).reshape(-1, 4, 4)
    xyzw = Rotation.from_matrix(m[:, :3, :3]).as_quat()
    q = np.concatenate([xyzw[:, 3:], xyzw[:, :3]], axis=1)
    d = q[:, 0] if ref is None else q @ np.asarray(ref, float)
    q[d < 0] *= -1.0
    return np.concatenate([m[:, :3, 3], q], axis=1)
