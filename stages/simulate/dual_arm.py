"""The dual-arm platform: two ViperX 300s arms (6 DoF each, the open counterpart of the X-Trainer's
arms; ALOHA's MJCF from gym-aloha) side by side on the project's holonomic base, written as one
URDF from an embodiment spec (``stages/embodiment/specs/mobile_aloha_viperx.toml``) and loaded
into Newton with the spec's drives (:mod:`stages.embodiment.drives`) and into Pinocchio for the
per-arm CLIK (:mod:`stages.embodiment.clik`).

Kinematic tree (Z up, metres, radians)::

    mobile_root -- base_x, base_y, base_yaw -- base_link (chassis box; mast, as robot.py's base)
      <arm>_base_link (fixed, on the chassis top at the spec's base.mobile.arm_mounts[<arm>])
        <arm>_waist ... <arm>_wrist_rotate -> <arm>_gripper_link
          <arm>_left_finger / <arm>_right_finger (prismatic, mirrored)
          <arm>_tcp (fixed: the point between the finger pads; +Z along the fingers, the
                     fingers close along +-Y, as the Panda's TCP)
          <arm>_wrist_camera (fixed, optical frame)

Source and what is kept (``vx300s_left.xml``; ``vx300s_right.xml`` is the same arm): every body
becomes a link with its inertial (pos / quat / diaginertia turned into a full tensor in the link
frame), every hinge / slide joint a revolute / prismatic joint with its range, every mesh geom a
visual and a collision mesh (MuJoCo collides its convex hull, as the source's own MJCF does);
bodies without a joint (the gripper prop) are welded. The fingers collide as boxes (the pad, the
finger's inner 8 mm over the 55 mm next to the tip, 16 mm wide, and the finger's root) instead of
their mesh's convex hull: MuJoCo gives a box pair up to 8 contact points, so a pinched object
resists turning between the pads through friction across the pad, as a real pad's contact patch
does (a hull gives one point, whose torsional friction alone lets a block held by one end creep
round, measured 5 deg/s). The right finger mimics the left one
(multiplier -1: one servo drives both, so the pair stays centred on what it grips; Pinocchio ignores
the tag and sees two joints). Names lose ``vx300s_left/`` and get
``<arm>_``. Dropped: the base mesh's collision (contype 0 in the source), the camera-focus body
and sites, the joints' ``frictionloss`` (30-60 N m of Coulomb friction in MuJoCo: with the
source's gains it stood in for damping; here the spec's drives damp) and the source's
actuators (the spec's drives replace them: the real arm's servo torques as effort limits).
"""

from __future__ import annotations

import logging
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pipeline.types import ItemError
from stages.embodiment.spec import EmbodimentSpec
from stages.simulate.hands import urdf_inertial
from stages.simulate.robot import BASE_JOINTS, BaseGeometry, CameraMount, _add_base, _camera_link

log = logging.getLogger(__name__)

VIPERX_REL = Path("robots/aloha__gym_aloha")
VIPERX_FILE = "vx300s_left.xml"
_SRC_PREFIX = "vx300s_left/"
PAD_TORSION = 0.01   # [m] torsional friction length of the finger pads (MuJoCo condim 4), as the Panda's


@dataclass(frozen=True, kw_only=True)
class ArmInfo:
    """One arm as loaded: name ("left" | "right"); joints: its 6 joints, root first; fingers: the
    two finger joints; finger_links; open / closed: finger positions [m] at gripper command 0 / 1;
    squeeze: how far past ``closed`` the command-1 target lies [m]; tcp: the end-effector frame;
    gripper_link: the link the fingers hang from; home: the arm's start posture [rad]."""

    name: str
    joints: tuple[str, ...]
    fingers: tuple[str, ...]
    finger_links: tuple[str, ...]
    open: tuple[float, ...]
    closed: tuple[float, ...]
    squeeze: float
    tcp: str
    gripper_link: str
    home: tuple[float, ...]

    def finger_targets(self, command: float) -> np.ndarray:
        """Finger targets (2,) [m] for a command in [0, 1]: linear from open to closed, at 1
        ``squeeze`` past closed (the drive then presses with up to its force limit)."""
        c = float(np.clip(command, 0.0, 1.0))
        o, k = np.asarray(self.open), np.asarray(self.closed)
        return o + c * (k - o) - c * self.squeeze * np.sign(o - k)


@dataclass(frozen=True, kw_only=True)
class DualArmDescription:
    """A written dual-arm URDF (absolute mesh paths), the spec it was written from, its arms in
    control order and its link cameras (name -> mount)."""

    urdf: Path
    spec: EmbodimentSpec
    arms: dict[str, ArmInfo]
    base: BaseGeometry
    cameras: dict[str, CameraMount] = field(default_factory=dict)
    base_joints: tuple[str, ...] = BASE_JOINTS

    @property
    def arm_joints(self) -> tuple[str, ...]:
        return tuple(j for a in self.arms.values() for j in a.joints)

    @property
    def finger_joints(self) -> tuple[str, ...]:
        return tuple(j for a in self.arms.values() for j in a.fingers)

    @property
    def joints(self) -> tuple[str, ...]:
        return self.base_joints + self.arm_joints + self.finger_joints

    def add_to_builder(self, builder, spawn_xy_yaw=(0.0, 0.0, 0.0)):
        """Add the robot to a Newton ``ModelBuilder`` (:func:`add_dual_arm`, with the spec's
        drives); ``stages.simulate.world.build_sim`` calls this for descriptions that have it."""
        return add_dual_arm(builder, self, spawn_xy_yaw=spawn_xy_yaw)


# --------------------------------------------------------------------------------------------
# URDF writing
# --------------------------------------------------------------------------------------------


def _fmt(v) -> str:
    return " ".join(f"{float(x):.9g}" for x in v)


def _rot(el: ET.Element) -> np.ndarray:
    """Rotation (3, 3) of an MJCF element's quat (w first) or euler (MuJoCo's default 'xyz':
    intrinsic, radians here: the source compiles with angle="radian")."""
    from scipy.spatial.transform import Rotation

    if el.get("quat"):
        return Rotation.from_quat([float(v) for v in el.get("quat").split()], scalar_first=True).as_matrix()
    if el.get("euler"):
        return Rotation.from_euler("XYZ", [float(v) for v in el.get("euler").split()]).as_matrix()
    return np.eye(3)


def _vec(el: ET.Element, key: str) -> np.ndarray:
    return np.array([float(v) for v in el.get(key).split()]) if el.get(key) else np.zeros(3)


def _rpy(r: np.ndarray) -> np.ndarray:
    import warnings

    from scipy.spatial.transform import Rotation

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)     # gimbal lock: any split is exact
        return Rotation.from_matrix(r).as_euler("xyz")


def _origin(parent: ET.Element, xyz, r) -> None:
    ET.SubElement(parent, "origin", xyz=_fmt(xyz), rpy=_fmt(_rpy(r)))


def _arm_link(robot: ET.Element, body: ET.Element, name: str, meshes: dict[str, Path], rgba: str) -> None:
    link = ET.SubElement(robot, "link", name=name)
    ine = body.find("inertial")
    if ine is not None:
        urdf_inertial(link, ine)
    else:   # the root (base plate) has no inertial in the source; it is welded to the chassis
        el = ET.SubElement(link, "inertial")
        ET.SubElement(el, "mass", value="0.5")
        ET.SubElement(el, "inertia", ixx="1e-3", ixy="0", ixz="0", iyy="1e-3", iyz="0", izz="1e-3")
    pads = _finger_boxes(name)
    for xyz, size in pads:
        el = ET.SubElement(link, "collision")
        ET.SubElement(el, "origin", xyz=_fmt(xyz), rpy="0 0 0")
        ET.SubElement(ET.SubElement(el, "geometry"), "box", size=_fmt(size))
    for g in body.findall("geom"):
        if g.get("type") != "mesh":
            continue
        path = meshes[g.get("mesh")]
        collide = not (g.get("contype") == "0" and g.get("conaffinity") == "0") and not pads
        for tag in ("visual", "collision") if collide else ("visual",):
            el = ET.SubElement(link, tag)
            _origin(el, _vec(g, "pos"), _rot(g))
            ET.SubElement(ET.SubElement(el, "geometry"), "mesh", filename=str(path),
                          scale="0.001 0.001 0.001")
            if tag == "visual":
                ET.SubElement(ET.SubElement(el, "material", name=f"{name}_{len(link)}"), "color", rgba=rgba)


# the finger's inner face lies PAD_FACE inboard of the finger link's origin (along -+Y for the left / right
# finger); measured on vx300s_10_custom_finger_*.stl as the source places it
PAD_FACE = 0.0224   # [m]


def _finger_boxes(link: str) -> list[tuple[tuple[float, float, float], tuple[float, float, float]]]:
    """Collision boxes (centre, size) [m] in a finger link's frame: the pad (the finger's inner 8 mm
    over the 55 mm next to the tip, 16 mm wide) and the finger's root; none for other links."""
    side = 1.0 if link.endswith("_left_finger_link") else -1.0 if link.endswith("_right_finger_link") else 0.0
    if not side:
        return []
    y = -side * (PAD_FACE - 0.004)
    return [((0.0575, y, 0.0), (0.055, 0.008, 0.016)), ((0.0125, y, 0.0), (0.035, 0.008, 0.05))]


def _add_arm(robot: ET.Element, side: str, src: Path, mount_xyz, tcp_xyz, tcp_rpy) -> None:
    """Append one ViperX 300s as ``<side>_*`` links and joints, its base link on base_link at
    ``mount_xyz`` [m], and the TCP frame on the gripper link."""
    try:
        tree = ET.parse(src)
        deps = ET.parse(src.parent / "vx300s_dependencies.xml")
    except (ET.ParseError, OSError) as e:
        raise ItemError(f"{src}: cannot read the ViperX 300s MJCF: {e}") from None
    meshes = {m.get("name"): src.parent / m.get("file") for m in deps.iter("mesh")}
    missing = [str(p) for p in meshes.values() if not p.is_file()]
    if missing:
        raise ItemError(f"{src}: meshes not found: {missing}")
    root = tree.getroot().find("body")
    if root is None:
        raise ItemError(f"{src}: no arm body")

    def name_of(body_name: str) -> str:
        short = body_name.removeprefix(_SRC_PREFIX)
        return f"{side}_{'base_link' if short == body_name else short}"

    def walk(body: ET.Element, parent: str | None) -> None:
        if body.find("inertial") is None and parent is not None:
            return                                    # the camera focus marker
        name = name_of(body.get("name"))
        _arm_link(robot, body, name, meshes, "0.15 0.15 0.15 1" if "finger" in name else "0.25 0.25 0.27 1")
        if parent is None:
            j = ET.SubElement(robot, "joint", name=f"{side}_arm_mount", type="fixed")
            ET.SubElement(j, "parent", link="base_link")
            ET.SubElement(j, "child", link=name)
            ET.SubElement(j, "origin", xyz=_fmt(mount_xyz), rpy="0 0 0")
        else:
            joints = body.findall("joint")
            kind = {"slide": "prismatic", None: "revolute", "hinge": "revolute"}
            jname = f"{side}_{joints[0].get('name').removeprefix(_SRC_PREFIX)}" if joints else f"{name}_weld"
            jtype = kind[joints[0].get("type")] if joints else "fixed"
            j = ET.SubElement(robot, "joint", name=jname, type=jtype)
            ET.SubElement(j, "parent", link=parent)
            ET.SubElement(j, "child", link=name)
            _origin(j, _vec(body, "pos"), _rot(body))
            if joints:
                lo, hi = (float(v) for v in joints[0].get("range").split())
                ET.SubElement(j, "axis", xyz=_fmt(_vec(joints[0], "axis")))
                ET.SubElement(j, "limit", lower=f"{lo:.9g}", upper=f"{hi:.9g}", effort="10", velocity="3")
                if jname == f"{side}_right_finger":   # one servo moves both fingers (rack and pinion)
                    ET.SubElement(j, "mimic", joint=f"{side}_left_finger", multiplier="-1", offset="0")
        for child in body.findall("body"):
            walk(child, name)

    walk(root, None)
    tcp = ET.SubElement(robot, "link", name=f"{side}_tcp")
    ine = ET.SubElement(tcp, "inertial")
    ET.SubElement(ine, "mass", value="0.001")
    ET.SubElement(ine, "inertia", ixx="1e-8", ixy="0", ixz="0", iyy="1e-8", iyz="0", izz="1e-8")
    j = ET.SubElement(robot, "joint", name=f"{side}_tcp_joint", type="fixed")
    ET.SubElement(j, "parent", link=f"{side}_gripper_link")
    ET.SubElement(j, "child", link=f"{side}_tcp")
    ET.SubElement(j, "origin", xyz=_fmt(tcp_xyz), rpy=_fmt(tcp_rpy))


def _base_geometry(spec: EmbodimentSpec) -> BaseGeometry:
    m = spec.base.mobile
    if m is None:
        raise ItemError(f"{spec.name}: the dual-arm platform needs [base.mobile] "
                        "(the holonomic base's geometry)")
    return BaseGeometry(chassis=m.chassis, clearance=m.clearance, mass=m.mass, arm_mount=m.arm_mount,
                        mast_xy=m.mast_xy, mast_height=m.mast_height, max_force=spec.base.max_force or 400.0,
                        max_torque=spec.base.max_torque or 200.0)


def _camera_mount(spec: EmbodimentSpec, name: str) -> CameraMount:
    from stages.embodiment.kinematics import camera_mount_pose

    cam = spec.cameras[name]
    m = camera_mount_pose(spec, name)
    return CameraMount(link=cam.link, parent=cam.parent, xyz=tuple(float(v) for v in m[:3, 3]),
                       rpy=tuple(float(v) for v in _rpy(m[:3, :3])), width=cam.width, height=cam.height,
                       vertical_fov=cam.vertical_fov)


def write_dual_arm_urdf(out_dir: Path, spec: EmbodimentSpec | str = "mobile_aloha_viperx", *,
                        shared_assets: Path | None = None) -> DualArmDescription:
    """Write ``<out_dir>/<spec name>.urdf`` from the spec (base geometry, arm mounts, TCP frames,
    link cameras) and the ViperX MJCF in the shared assets (default
    ``stages.embodiment.sources.default_shared_assets``); returns its description."""
    from stages.embodiment.sources import default_shared_assets
    from stages.embodiment.spec import load_spec

    spec = load_spec(spec) if isinstance(spec, str | Path) else spec
    base = _base_geometry(spec)
    src = Path(shared_assets or default_shared_assets()) / VIPERX_REL / VIPERX_FILE
    mounts = spec.base.mobile.arm_mounts
    robot = ET.Element("robot", name=spec.name)
    _add_base(robot, base)
    top = base.clearance + base.chassis[2]
    arms = {}
    for arm in spec.arms:
        if arm.name not in mounts:
            raise ItemError(f"{spec.name}: arm {arm.name!r} has no mount in base.mobile.arm_mounts")
        _add_arm(robot, arm.name, src, (*mounts[arm.name], top), arm.ee_xyz, arm.ee_rpy)
        ee = spec.end_effectors[arm.end_effector]
        arms[arm.name] = ArmInfo(name=arm.name, joints=arm.joints, fingers=ee.joints,
                                 finger_links=tuple(j.replace("_finger", "_finger_link") for j in ee.joints),
                                 open=ee.open, closed=ee.closed, squeeze=ee.squeeze, tcp=arm.ee_frame,
                                 gripper_link=ee.mount_link,
                                 home=tuple(spec.default_pose.get(j, 0.0) for j in arm.joints))
    cameras = {n: _camera_mount(spec, n) for n in spec.link_cameras()}
    for cam in cameras.values():
        _camera_link(robot, cam)
    ET.indent(robot)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"{spec.name}.urdf"
    tmp = path.with_suffix(".urdf.tmp")
    ET.ElementTree(robot).write(tmp, encoding="unicode", xml_declaration=True)
    tmp.replace(path)
    log.info("wrote dual-arm URDF %s", path)
    return DualArmDescription(urdf=path, spec=spec, arms=arms, base=base, cameras=cameras)


# --------------------------------------------------------------------------------------------
# loading into Newton
# --------------------------------------------------------------------------------------------


def add_dual_arm(builder, desc: DualArmDescription, *, spawn_xy_yaw=(0.0, 0.0, 0.0)):
    """Add the platform to a Newton ``ModelBuilder`` with its root at the spawn pose (x, y [m],
    yaw [rad]): the URDF (no self-collisions), the spec's drives, start posture and gravity
    compensation, torsional friction on the finger pads. Returns
    :class:`stages.simulate.robot_load.RobotIndices`."""
    import warp as wp

    from stages.embodiment.drives import apply_drives
    from stages.simulate.robot_load import RobotIndices, mujoco_attribute

    x, y, yaw = spawn_xy_yaw
    body0, shape0, joint0 = builder.body_count, builder.shape_count, builder.joint_count
    xform = wp.transform(wp.vec3(x, y, 0.0), wp.quat_from_axis_angle(wp.vec3(0.0, 0.0, 1.0), float(yaw)))
    builder.add_urdf(str(desc.urdf), xform=xform, floating=False, enable_self_collisions=False,
                     joint_ordering="dfs", collapse_fixed_joints=False)
    joints = apply_drives(builder, desc.spec, joint_start=joint0)
    missing = [n for n in desc.joints if n not in joints.dof]
    if missing:
        raise ItemError(f"{desc.urdf}: joints {missing} not found after loading into Newton")
    body = {builder.body_label[b].rsplit("/", 1)[-1]: b for b in range(body0, builder.body_count)}
    condim = mujoco_attribute(builder, "mujoco:condim")
    pads = {body[link] for a in desc.arms.values() for link in a.finger_links}
    for s in range(shape0, builder.shape_count):
        if builder.shape_body[s] in pads:          # a pinched object does not spin between the pads
            condim.values[s] = 4
            builder.shape_material_mu_torsional[s] = PAD_TORSION
    return RobotIndices(dof=joints.dof, coord=joints.coord, body=body, shape_start=shape0,
                        shape_end=builder.shape_count)
