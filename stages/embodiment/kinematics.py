"""The kinematic model of an embodiment (Pinocchio): frames, arm chains, and checks of a spec
against its description.

:func:`build_model` loads a URDF (``pin.buildModelFromUrdf``) or an MJCF and adds the spec's
end-effector frames and link-camera frames as operational frames. An MJCF is compiled by MuJoCo (as the MJCF loader does) and its kinematic tree written as
a URDF for Pinocchio: Pinocchio 4.1's own MJCF parser builds newton-assets' G1 twice (88 joints for
44). A free joint at the root is dropped (the root link is fixed where the file puts it); bodies
without joints are welded to their parent with a fixed joint; a joint's anchor (``pos``) becomes its
link's frame origin. Poses of :class:`Kinematics` are 4x4 matrices in the base's root-link frame
(``spec.base.root_link``; the pelvis of a humanoid, ``mobile_root`` of the mobile Panda), so they
do not depend on where the root is in the world. Pinocchio is imported lazily.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from stages.embodiment.spec import EmbodimentError, EmbodimentSpec


def _rpy_matrix(rpy) -> np.ndarray:
    """URDF rpy (extrinsic x, y, z) [rad] -> rotation (3, 3)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_euler("xyz", np.asarray(rpy, float)).as_matrix()


def look_rotation(forward, up) -> np.ndarray:
    """Rotation (3, 3) of a camera optical frame (looks along -Z, +Y up) whose -Z points along
    ``forward`` and +Y towards ``up`` (both in the parent frame)."""
    f = np.asarray(forward, float)
    z = -f / np.linalg.norm(f)
    x = np.cross(np.asarray(up, float), z)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z], axis=1)


def camera_mount_pose(spec: EmbodimentSpec, name: str) -> np.ndarray:
    """4x4 pose of link camera ``name``'s optical frame in its parent link."""
    cam = spec.cameras[name]
    if cam.fixed:
        raise EmbodimentError(f"{spec.name}: camera {name!r} is fixed in the world, not on a link")
    m = np.eye(4)
    m[:3, :3] = look_rotation(cam.forward, cam.up)
    m[:3, 3] = cam.xyz
    return m


def build_model(spec: EmbodimentSpec, path: Path):
    """The Pinocchio model of ``spec`` from the description file ``path`` (for assembly
    ``mobile_base``: the assembled URDF stages.simulate.robot writes), with the spec's
    end-effector and camera frames added where the file lacks them."""
    import pinocchio as pin

    path = Path(path)
    try:
        if path.suffix.lower() == ".urdf":
            model = pin.buildModelFromUrdf(str(path))
        else:
            model = pin.buildModelFromXML(mjcf_as_urdf(path))
    except (RuntimeError, ValueError) as e:
        raise EmbodimentError(f"{path}: Pinocchio cannot load the description: {str(e).splitlines()[0]}") from None
    for arm in spec.arms:
        if not model.existFrame(arm.ee_frame) and model.existFrame(arm.tip_link):
            local = np.eye(4)
            local[:3, :3] = _rpy_matrix(arm.ee_rpy)
            local[:3, 3] = arm.ee_xyz
            _add_frame(pin, model, arm.ee_frame, arm.tip_link, local)
    for name, cam in spec.link_cameras().items():
        if not model.existFrame(cam.link) and model.existFrame(cam.parent):
            _add_frame(pin, model, cam.link, cam.parent, camera_mount_pose(spec, name))
    return model


def mjcf_as_urdf(path: Path) -> str:
    """The kinematic tree of an MJCF (compiled by MuJoCo) as URDF text: links (body names) with
    their inertia, hinge/slide joints with axis and range (unlimited hinges: continuous), fixed
    joints for welded bodies; the root's free joint is dropped. Raises EmbodimentError naming the
    file for a ball joint or a body with several joints."""
    import mujoco
    from scipy.spatial.transform import Rotation

    try:
        m = mujoco.MjModel.from_xml_path(str(path))
    except ValueError as e:
        raise EmbodimentError(f"{path}: MuJoCo cannot compile it: {str(e).splitlines()[0]}") from None
    name = lambda kind, i: mujoco.mj_id2name(m, kind, i)  # noqa: E731
    body_name = [name(mujoco.mjtObj.mjOBJ_BODY, b) or f"body{b}" for b in range(m.nbody)]
    anchor = np.zeros((m.nbody, 3))
    out = ['<robot name="mjcf">']
    for b in range(1, m.nbody):
        jids = [j for j in range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b])
                if m.jnt_type[j] != mujoco.mjtJoint.mjJNT_FREE]
        if len(jids) > 1 or any(m.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL for j in jids):
            raise EmbodimentError(f"{path}: body {body_name[b]!r}: only one hinge or slide joint per body is supported")
        if jids:
            anchor[b] = m.jnt_pos[jids[0]]
        ipos = m.body_ipos[b] - anchor[b]
        r_i = Rotation.from_quat(m.body_iquat[b], scalar_first=True).as_matrix()
        i3 = r_i @ np.diag(m.body_inertia[b]) @ r_i.T      # inertia about the COM, in the body frame
        out.append(f'<link name="{body_name[b]}"><inertial><origin xyz="{_f(ipos)}" rpy="0 0 0"/>'
                   f'<mass value="{max(m.body_mass[b], 1e-6):.9g}"/><inertia ixx="{i3[0, 0]:.9g}" '
                   f'ixy="{i3[0, 1]:.9g}" ixz="{i3[0, 2]:.9g}" iyy="{i3[1, 1]:.9g}" iyz="{i3[1, 2]:.9g}" '
                   f'izz="{i3[2, 2]:.9g}"/></inertial></link>')
        p = int(m.body_parentid[b])
        if p == 0:
            continue
        rot = Rotation.from_quat(m.body_quat[b], scalar_first=True)
        xyz = m.body_pos[b] + rot.apply(anchor[b]) - anchor[p]
        head = f'<origin xyz="{_f(xyz)}" rpy="{_f(rot.as_euler("xyz"))}"/><parent link="{body_name[p]}"/>' \
               f'<child link="{body_name[b]}"/>'
        if not jids:
            out.append(f'<joint name="{body_name[b]}_weld" type="fixed">{head}</joint>')
            continue
        j = jids[0]
        hinge = m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
        kind = ("revolute" if hinge else "prismatic") if m.jnt_limited[j] else ("continuous" if hinge else "prismatic")
        lo, hi = m.jnt_range[j] if m.jnt_limited[j] else (-1e3, 1e3)
        out.append(f'<joint name="{name(mujoco.mjtObj.mjOBJ_JOINT, j) or f"joint{j}"}" type="{kind}">{head}'
                   f'<axis xyz="{_f(m.jnt_axis[j])}"/><limit lower="{lo:.9g}" upper="{hi:.9g}" effort="1" '
                   f'velocity="1"/></joint>')
    out.append("</robot>")
    return "\n".join(out)


def _f(v) -> str:
    return " ".join(f"{float(x):.9g}" for x in v)


def _add_frame(pin, model, name: str, parent_frame: str, local: np.ndarray) -> None:
    pf = model.frames[model.getFrameId(parent_frame)]
    placement = pf.placement * pin.SE3(local[:3, :3], local[:3, 3])
    model.addFrame(pin.Frame(name, pf.parentJoint, model.getFrameId(parent_frame), placement,
                             pin.FrameType.OP_FRAME))


def chain_joints(model, root_link: str, tip_link: str) -> tuple[str, ...] | None:
    """Names of the moving joints from ``root_link`` to ``tip_link`` (root first), or None when
    ``tip_link`` does not hang below ``root_link``."""
    if not (model.existFrame(root_link) and model.existFrame(tip_link)):
        return None
    stop = model.frames[model.getFrameId(root_link)].parentJoint
    j = model.frames[model.getFrameId(tip_link)].parentJoint
    out = []
    while j != stop:
        if j == 0:
            return None
        out.append(model.names[j])
        j = model.parents[j]
    return tuple(reversed(out))


def check_spec(spec: EmbodimentSpec, model) -> list[str]:
    """Every disagreement between ``spec`` and the kinematic ``model`` (from :func:`build_model`):
    missing links and joints, arm chains that are not the named joints, an existing end-effector
    frame elsewhere than ee_xyz/ee_rpy, end-effector and default positions outside the joint
    limits, joints without a drive. Empty when they agree."""
    problems: list[str] = []
    joints = {model.names[j]: j for j in range(1, model.njoints)}
    lo, hi = model.lowerPositionLimit, model.upperPositionLimit

    def in_limits(name: str, value: float, what: str) -> None:
        if name not in joints:
            problems.append(f"{what}: joint {name!r} not in the description")
            return
        q = model.joints[joints[name]].idx_q
        if not lo[q] - 1e-9 <= value <= hi[q] + 1e-9:
            problems.append(f"{what}: {name} = {value} outside its limits [{lo[q]:.4g}, {hi[q]:.4g}]")

    def link(name: str, what: str) -> None:
        if not model.existFrame(name):
            problems.append(f"{what}: link {name!r} not in the description")

    link(spec.base.root_link, "base.root_link")
    for j in spec.base.joints:
        if j not in joints:
            problems.append(f"base.joints: joint {j!r} not in the description")
    for arm in spec.arms:
        what = f"arm {arm.name!r}"
        link(arm.root_link, what)
        link(arm.tip_link, what)
        chain = chain_joints(model, arm.root_link, arm.tip_link)
        if chain is None:
            problems.append(f"{what}: {arm.tip_link!r} does not hang below {arm.root_link!r}")
        elif chain != arm.joints:
            problems.append(f"{what}: chain {arm.root_link} -> {arm.tip_link} has joints {list(chain)}, "
                            f"the spec names {list(arm.joints)}")
        if model.existFrame(arm.ee_frame) and model.existFrame(arm.tip_link):
            tip = model.frames[model.getFrameId(arm.tip_link)]
            ee = model.frames[model.getFrameId(arm.ee_frame)]
            if ee.parentJoint == tip.parentJoint:
                rel = tip.placement.inverse() * ee.placement
                want = np.eye(4)
                want[:3, :3], want[:3, 3] = _rpy_matrix(arm.ee_rpy), arm.ee_xyz
                if not np.allclose(rel.homogeneous, want, atol=1e-6):
                    problems.append(f"{what}: frame {arm.ee_frame!r} is at {np.round(rel.homogeneous[:3, 3], 6)} "
                                    f"in {arm.tip_link}, not at ee_xyz/ee_rpy")
        if arm.end_effector:
            ee = spec.end_effectors[arm.end_effector]
            link(ee.mount_link, f"end effector {arm.end_effector!r}")
            for name, a, b in zip(ee.joints, ee.open, ee.closed, strict=True):
                in_limits(name, a, f"end effector {arm.end_effector!r} open")
                in_limits(name, b, f"end effector {arm.end_effector!r} closed")
    for name, cam in spec.link_cameras().items():
        link(cam.parent, f"camera {name!r}")
    for name, value in spec.default_pose.items():
        in_limits(name, value, "default_pose")
    undriven = [n for n in joints if model.joints[joints[n]].nq > 0 and spec.drive_for(n) is None]
    if undriven:
        problems.append(f"no drive matches joints {undriven}")
    return problems


def require_spec_matches(spec: EmbodimentSpec, model, where: Path | str) -> None:
    """Raise EmbodimentError (naming ``where``, the description) with every problem of
    :func:`check_spec`."""
    problems = check_spec(spec, model)
    if problems:
        raise EmbodimentError(f"{where}: embodiment spec {spec.name!r} does not match: {'; '.join(problems)}")


class Kinematics:
    """Forward kinematics of a spec's model in the root-link frame.

    q: Pinocchio configurations, one (nq,) or a batch (W, nq). ``default_q()`` is the spec's
    default pose with end effectors open (other joints 0, clipped to their limits)."""

    def __init__(self, spec: EmbodimentSpec, model) -> None:
        import pinocchio as pin

        self.spec, self.model, self._pin = spec, model, pin
        self.data = model.createData()
        self.root = model.getFrameId(spec.base.root_link)
        self.idx_q = {model.names[j]: model.joints[j].idx_q for j in range(1, model.njoints)}
        self.idx_v = {model.names[j]: model.joints[j].idx_v for j in range(1, model.njoints)}

    def default_q(self) -> np.ndarray:
        q = self._pin.neutral(self.model)
        values = dict(self.spec.default_pose)
        for arm in self.spec.arms:
            if arm.end_effector:
                ee = self.spec.end_effectors[arm.end_effector]
                values.update(zip(ee.joints, ee.open, strict=True))
        for name, v in values.items():
            if name in self.idx_q:
                q[self.idx_q[name]] = v
        return np.clip(q, self.model.lowerPositionLimit, self.model.upperPositionLimit)

    def frame_pose(self, q: np.ndarray, frame: str) -> np.ndarray:
        """4x4 pose(s) of ``frame`` in the root-link frame: (4, 4) for q (nq,), (W, 4, 4) for (W, nq)."""
        q = np.asarray(q, float)
        fid = self.model.getFrameId(frame)
        if fid >= len(self.model.frames):
            raise EmbodimentError(f"{self.spec.name}: no frame {frame!r} in the model")
        flat = q.reshape(-1, q.shape[-1])
        out = np.empty((len(flat), 4, 4))
        for i, qi in enumerate(flat):
            self._pin.framesForwardKinematics(self.model, self.data, qi)
            out[i] = self.data.oMf[self.root].actInv(self.data.oMf[fid]).homogeneous
        out = out.reshape(*q.shape[:-1], 4, 4)
        return out

    def ee_pose(self, q: np.ndarray, arm: str) -> np.ndarray:
        """End-effector pose(s) of ``arm`` in the root-link frame (see :meth:`frame_pose`)."""
        return self.frame_pose(q, self.spec.arm(arm).ee_frame)
