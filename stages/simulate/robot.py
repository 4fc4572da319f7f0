"""The embodiment: a Franka Panda arm on a holonomic mobile base, written as one URDF.

The robot is described once, as a URDF file written by :func:`write_robot_urdf`, and that same
file is loaded into Newton (:func:`stages.simulate.robot_load.add_robot`, through
``ModelBuilder.add_urdf``) and into Pinocchio (:func:`stages.simulate.robot_load.build_pinocchio_model`)
for inverse kinematics, so the two models agree by construction (tests compare their forward kinematics).

Kinematic tree (Z up, metres, radians)::

    mobile_root (fixed to the world at the spawn pose)
      base_x   prismatic, axis +X of the spawn frame       -> base_x_link
      base_y   prismatic, axis +Y of the spawn frame       -> base_y_link
      base_yaw revolute,  axis +Z                          -> base_link (chassis box, 0.6 x 0.5 x 0.3 m)
        mast (fixed) -> head_camera (fixed, camera optical frame: looks along -Z, +Y up)
        panda_link0 (fixed, on the chassis top) ... panda_joint1..7 ... panda_link8
          panda_hand (Franka hand, 2 prismatic fingers)        | robotiq_base (2F-85, approximated)
            panda_hand_tcp (end-effector frame)                |   robotiq_tcp
            wrist_camera (fixed, optical frame)                |   wrist_camera

The Panda description is the example-robot-data URDF (``panda_description``): taken from the pip
package ``example_robot_data`` if it is installed, else from an explicit folder (the third-party
assets in tests). Its visual meshes are COLLADA files; trimesh needs ``pycollada`` to read them,
so without it the collision STL meshes are used as visuals too (grey, same shapes, coarser).

Simplifications, documented here once:
- The second Panda finger's ``<mimic>`` tag is dropped: both finger joints are driven to the same
  target by the gripper command, which is what the mimic expresses, and Pinocchio and Newton then
  see the same independent joints.
- The Robotiq 2F-85 (MuJoCo Menagerie MJCF) closes through a 4-bar linkage with a tendon and
  equality constraints. It is approximated as a parallel two-finger gripper: the real base meshes,
  two prismatic fingers with the 2F-85's stroke (0-42.5 mm per finger, 85 mm opening) and its pad
  boxes (22 x 8 x 37.5 mm, friction pads), at the real fingertip height. The fingertip follows a
  straight line instead of the 4-bar's arc.
"""

from __future__ import annotations

import importlib.util
import logging
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path

import numpy as np

from pipeline.types import ItemError

log = logging.getLogger(__name__)

BASE_JOINTS = ("base_x", "base_y", "base_yaw")
ARM_JOINTS = tuple(f"panda_joint{i}" for i in range(1, 8))
PANDA_PACKAGE = "example-robot-data"
PANDA_URDF_REL = Path("robots/panda_description/urdf/panda.urdf")
# A comfortable, collision-free arm configuration (rad): elbow up, hand pointing down.
ARM_HOME = (0.0, -0.5, 0.0, -2.3, 0.0, 1.8, 0.785)


class GripperKind(StrEnum):
    PANDA_HAND = "panda_hand"
    ROBOTIQ_2F85 = "robotiq_2f85"
    ALLEGRO = "allegro"          # dexterous hands: stages.simulate.hands
    SHADOW = "shadow"


@dataclass(frozen=True, kw_only=True)
class CameraMount:
    """A camera rigidly attached to a link.

    link: name of the camera link in the URDF (its frame is the optical frame: looks along -Z,
    +Y up, +X right); parent: the link it is fixed to; xyz [m] and rpy [rad]: the camera frame in
    the parent frame; width, height [px]; vertical_fov [rad].
    """

    link: str
    parent: str
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]
    width: int = 128
    height: int = 128
    vertical_fov: float = 1.0


@dataclass(frozen=True, kw_only=True)
class BaseGeometry:
    """The mobile base. chassis: box size (x, y, z) [m]; clearance: chassis bottom above the floor
    [m]; mass [kg]; arm_mount: Panda link0 position on the chassis top, in base_link [m];
    mast_xy: mast position in base_link [m]; mast_height: mast top above the floor [m];
    max_force: base joint force limit [N]; max_torque: yaw torque limit [N m]."""

    chassis: tuple[float, float, float] = (0.60, 0.50, 0.30)
    clearance: float = 0.02
    mass: float = 40.0
    arm_mount: tuple[float, float] = (0.12, 0.0)
    mast_xy: tuple[float, float] = (-0.22, 0.0)
    mast_height: float = 1.40
    max_force: float = 400.0
    max_torque: float = 200.0


@dataclass(frozen=True, kw_only=True)
class GripperSpec:
    """finger_joints: joint names; open_q / closed_q: finger joint position [m] at command 0 (open)
    and 1 (closed); squeeze [m]: how far past ``closed_q`` the command-1 target lies, so that a
    grasped object is squeezed with about ``finger_ke * (squeeze + penetration)``, capped at
    max_force [N] per finger; tcp: end-effector frame name; hand_link: the link the fingers hang
    from. A dexterous hand (``hand``: :class:`stages.simulate.hands.HandInfo`) has one open /
    closed position per joint (its closing synergy) and its own drives; open_q / closed_q are then
    unused."""

    kind: GripperKind
    finger_joints: tuple[str, ...]
    open_q: float
    closed_q: float
    max_force: float
    tcp: str
    hand_link: str
    squeeze: float = 0.02
    hand: object | None = None

    def finger_targets(self, command: float) -> np.ndarray:
        """Finger joint targets (n,) [m or rad] for a command in [0, 1] (0 open, 1 closed): a
        parallel gripper's fingers go ``squeeze`` past closed at 1; a hand interpolates its synergy."""
        c = float(np.clip(command, 0.0, 1.0))
        if self.hand is not None:
            o, k = np.asarray(self.hand.open), np.asarray(self.hand.closed)
            return o + c * (k - o)
        q = self.open_q + c * (self.closed_q - self.open_q) - c * self.squeeze * np.sign(self.open_q - self.closed_q)
        return np.full(len(self.finger_joints), q)


@dataclass(frozen=True, kw_only=True)
class RobotDescription:
    """A written robot URDF and the names the controllers and sensors need.

    urdf: the combined URDF file (absolute mesh paths); joints: every actuated joint in control
    order (base, arm, fingers); cameras: camera mounts by name ("head", "wrist").
    """

    urdf: Path
    gripper: GripperSpec
    base: BaseGeometry
    cameras: dict[str, CameraMount] = field(default_factory=dict)
    base_joints: tuple[str, ...] = BASE_JOINTS
    arm_joints: tuple[str, ...] = ARM_JOINTS
    arm_home: tuple[float, ...] = ARM_HOME

    @property
    def joints(self) -> tuple[str, ...]:
        return self.base_joints + self.arm_joints + self.gripper.finger_joints

    @property
    def ee_frame(self) -> str:
        return self.gripper.tcp


# --------------------------------------------------------------------------------------------
# Finding the Panda description
# --------------------------------------------------------------------------------------------


def find_panda_description(explicit: Path | None = None) -> Path:
    """The package root that holds ``robots/panda_description`` (the folder that
    ``package://example-robot-data/`` resolves to).

    ``explicit``: that root, or a folder holding ``example-robot-data/`` (as the shared assets do);
    without it, the pip package ``example-robot-data`` (the default). Raises ItemError naming what
    was tried (an explicit folder that lacks the URDF is an error, not a fallback).
    """
    if explicit is not None:
        tried = []
        for root in (Path(explicit), Path(explicit) / PANDA_PACKAGE):
            if (root / PANDA_URDF_REL).is_file():
                return root.resolve()
            tried.append(str(root / PANDA_URDF_REL))
        raise ItemError(f"{explicit}: Panda description not found; tried: {'; '.join(tried)}")
    root = _pip_panda_root()
    if root is None:
        raise ItemError(f"{PANDA_URDF_REL}: Panda description not found: the pip package example-robot-data "
                        "is not installed (or has no panda_description); pass panda_root")
    return root


def _pip_panda_root() -> Path | None:
    """The data root of the pip package ``example-robot-data`` (a cmeel package: its files live
    under ``site-packages/cmeel.prefix/share/example-robot-data``), or None."""
    from importlib import metadata

    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        return _path_panda_root()
    suffix = PANDA_URDF_REL.as_posix()
    for f in dist.files or ():
        if f.as_posix().endswith(suffix):
            urdf = Path(dist.locate_file(f))
            if urdf.is_file():
                return urdf.parents[3].resolve()
    return None


def _path_panda_root() -> Path | None:
    """Without the pip package: a ``cmeel.prefix/share/example-robot-data`` holding the Panda
    under a ``sys.path`` entry (the package's files copied there, as the GPU machine gets them),
    or None."""
    import sys

    for entry in sys.path:
        root = Path(entry or ".") / "cmeel.prefix" / "share" / "example-robot-data"
        if (root / PANDA_URDF_REL).is_file():
            return root.resolve()
    return None


def find_robotiq_description(explicit: Path) -> Path:
    """The folder of the Menagerie 2F-85 (``2f85.xml`` and ``assets/*.stl``)."""
    for root in (Path(explicit), Path(explicit) / "robots" / "robotiq_2f85__menagerie"):
        if (root / "assets" / "base.stl").is_file():
            return root.resolve()
    raise ItemError(f"{explicit}: Robotiq 2F-85 meshes (assets/base.stl) not found")


# --------------------------------------------------------------------------------------------
# URDF writing
# --------------------------------------------------------------------------------------------


def _fmt(v) -> str:
    return " ".join(f"{float(x):.9g}" for x in v)


def _rpy_from_matrix(r: np.ndarray) -> tuple[float, float, float]:
    from scipy.spatial.transform import Rotation

    return tuple(float(a) for a in Rotation.from_matrix(r).as_euler("xyz"))  # URDF rpy = extrinsic xyz


def look_rotation(forward: np.ndarray, up_hint: np.ndarray) -> np.ndarray:
    """Rotation (3, 3) of a camera frame whose -Z looks along ``forward`` with +Y towards
    ``up_hint`` (both in the parent frame)."""
    f = np.asarray(forward, float)
    f = f / np.linalg.norm(f)
    z = -f
    x = np.cross(np.asarray(up_hint, float), z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=1)


def _sub(parent: ET.Element, tag: str, **attrs) -> ET.Element:
    return ET.SubElement(parent, tag, {k: str(v) for k, v in attrs.items()})


def _inertial(link: ET.Element, mass: float, size: tuple[float, float, float], xyz=(0, 0, 0)) -> None:
    """Box inertia for ``mass`` [kg] and box ``size`` [m]."""
    a, b, c = size
    ixx, iyy, izz = (
        mass / 12.0 * (b * b + c * c),
        mass / 12.0 * (a * a + c * c),
        mass / 12.0 * (a * a + b * b),
    )
    ine = _sub(link, "inertial")
    _sub(ine, "origin", xyz=_fmt(xyz), rpy="0 0 0")
    _sub(ine, "mass", value=f"{mass:.9g}")
    _sub(ine, "inertia", ixx=ixx, ixy=0, ixz=0, iyy=iyy, iyz=0, izz=izz)


def _box_geom(link: ET.Element, size, xyz=(0, 0, 0), rpy=(0, 0, 0), rgba=None, visual=True, collision=True):
    for tag, on in (("visual", visual), ("collision", collision)):
        if not on:
            continue
        el = _sub(link, tag)
        _sub(el, "origin", xyz=_fmt(xyz), rpy=_fmt(rpy))
        _sub(_sub(el, "geometry"), "box", size=_fmt(size))
        if tag == "visual" and rgba is not None:
            _sub(_sub(el, "material", name=f"{link.get('name')}_{len(link)}"), "color", rgba=_fmt(rgba))


def _mesh_geom(
    link: ET.Element,
    path: Path,
    *,
    scale=1.0,
    xyz=(0, 0, 0),
    rpy=(0, 0, 0),
    rgba=None,
    visual=True,
    collision=True,
):
    for tag, on in (("visual", visual), ("collision", collision)):
        if not on:
            continue
        el = _sub(link, tag)
        _sub(el, "origin", xyz=_fmt(xyz), rpy=_fmt(rpy))
        _sub(_sub(el, "geometry"), "mesh", filename=str(path), scale=_fmt((scale,) * 3))
        if tag == "visual" and rgba is not None:
            _sub(_sub(el, "material", name=f"{link.get('name')}_{len(link)}"), "color", rgba=_fmt(rgba))


def _joint(
    robot: ET.Element,
    name: str,
    jtype: str,
    parent: str,
    child: str,
    *,
    xyz=(0, 0, 0),
    rpy=(0, 0, 0),
    axis=None,
    lower=None,
    upper=None,
    effort=None,
    velocity=None,
) -> None:
    j = _sub(robot, "joint", name=name, type=jtype)
    _sub(j, "parent", link=parent)
    _sub(j, "child", link=child)
    _sub(j, "origin", xyz=_fmt(xyz), rpy=_fmt(rpy))
    if axis is not None:
        _sub(j, "axis", xyz=_fmt(axis))
    if lower is not None:
        _sub(
            j,
            "limit",
            lower=f"{lower:.9g}",
            upper=f"{upper:.9g}",
            effort=f"{effort:.9g}",
            velocity=f"{velocity:.9g}",
        )


def _add_base(robot: ET.Element, base: BaseGeometry) -> None:
    cx, cy, cz = base.chassis
    tiny = (0.05, 0.05, 0.05)
    for name in ("mobile_root", "base_x_link", "base_y_link"):
        link = _sub(robot, "link", name=name)
        _inertial(link, 1.0, tiny)
    _joint(
        robot,
        "base_x",
        "prismatic",
        "mobile_root",
        "base_x_link",
        axis=(1, 0, 0),
        lower=-50,
        upper=50,
        effort=base.max_force,
        velocity=2.0,
    )
    _joint(
        robot,
        "base_y",
        "prismatic",
        "base_x_link",
        "base_y_link",
        axis=(0, 1, 0),
        lower=-50,
        upper=50,
        effort=base.max_force,
        velocity=2.0,
    )
    chassis = _sub(robot, "link", name="base_link")
    zc = base.clearance + cz / 2
    _inertial(chassis, base.mass, base.chassis, xyz=(0, 0, zc))
    _box_geom(chassis, base.chassis, xyz=(0, 0, zc), rgba=(0.25, 0.27, 0.3, 1))
    _joint(
        robot,
        "base_yaw",
        "revolute",
        "base_y_link",
        "base_link",
        axis=(0, 0, 1),
        lower=-100.0,
        upper=100.0,
        effort=base.max_torque,
        velocity=3.0,
    )
    top = base.clearance + cz
    mast = _sub(robot, "link", name="mast")
    mast_len = base.mast_height - top
    _inertial(mast, 2.0, (0.06, 0.06, mast_len), xyz=(0, 0, mast_len / 2))
    _box_geom(mast, (0.06, 0.06, mast_len), xyz=(0, 0, mast_len / 2), rgba=(0.6, 0.6, 0.62, 1))
    _joint(robot, "mast_joint", "fixed", "base_link", "mast", xyz=(*base.mast_xy, top))


def _camera_link(robot: ET.Element, cam: CameraMount) -> None:
    link = _sub(robot, "link", name=cam.link)
    _inertial(link, 0.05, (0.03, 0.03, 0.03))
    _joint(robot, f"{cam.link}_joint", "fixed", cam.parent, cam.link, xyz=cam.xyz, rpy=cam.rpy)


def _has_collada() -> bool:
    return importlib.util.find_spec("collada") is not None


def _panda_elements(panda_root: Path, gripper: GripperKind) -> list[ET.Element]:
    """The Panda URDF's links and joints with absolute mesh paths, mimic tags dropped, and the
    Franka hand removed when another gripper is used."""
    src = panda_root / PANDA_URDF_REL
    try:
        tree = ET.parse(src)
    except (ET.ParseError, OSError) as e:
        raise ItemError(f"{src}: cannot read the Panda URDF: {e}") from None
    collada = _has_collada()
    hand_parts = {
        "panda_hand",
        "panda_hand_tcp",
        "panda_leftfinger",
        "panda_rightfinger",
        "panda_hand_joint",
        "panda_hand_tcp_joint",
        "panda_finger_joint1",
        "panda_finger_joint2",
    }
    out: list[ET.Element] = []
    for el in tree.getroot():
        if el.tag not in ("link", "joint"):
            continue
        if gripper != GripperKind.PANDA_HAND and el.get("name") in hand_parts:
            continue
        for mimic in el.findall("mimic"):
            el.remove(mimic)
        for mesh in el.iter("mesh"):
            fn = mesh.get("filename", "")
            if fn.startswith(f"package://{PANDA_PACKAGE}/"):
                fn = str(panda_root / fn[len(f"package://{PANDA_PACKAGE}/") :])
            if fn.endswith(".dae") and not collada:
                fn = fn.replace("/meshes/visual/", "/meshes/collision/")[:-4] + ".stl"
            if not Path(fn).is_file():
                raise ItemError(f"{src}: mesh {fn} not found")
            mesh.set("filename", fn)
        if el.tag == "link":
            for vis in el.findall("visual"):
                if vis.find("material") is None:
                    dark = el.get("name") in ("panda_leftfinger", "panda_rightfinger", "panda_link7")
                    rgba = (0.2, 0.2, 0.22, 1) if dark else (0.92, 0.92, 0.92, 1)
                    _sub(_sub(vis, "material", name=f"{el.get('name')}_white"), "color", rgba=_fmt(rgba))
        out.append(el)
    return out


ROBOTIQ_STROKE = 0.0425  # [m] per finger
ROBOTIQ_PAD_Z = 0.1305  # fingertip pad centre below the mount face [m] (Menagerie pad position at rest)


def _add_robotiq(robot: ET.Element, robotiq_root: Path) -> None:
    """The 2F-85 approximated as a parallel gripper mounted on panda_link8 (see module doc)."""
    assets = robotiq_root / "assets"
    base = _sub(robot, "link", name="robotiq_base")
    _inertial(base, 0.9, (0.08, 0.08, 0.1), xyz=(0, 0, 0.04))
    # Menagerie: base_mount at z 0.007 rotated +90 deg about z; base 0.0038 above it, rotated back.
    _mesh_geom(
        base,
        assets / "base_mount.stl",
        scale=0.001,
        xyz=(0, 0, 0.007),
        rpy=(0, 0, np.pi / 2),
        rgba=(0.15, 0.15, 0.15, 1),
    )
    _mesh_geom(base, assets / "base.stl", scale=0.001, xyz=(0, 0, 0.0108), rgba=(0.15, 0.15, 0.15, 1))
    _joint(robot, "robotiq_mount", "fixed", "panda_link8", "robotiq_base", rpy=(0, 0, -np.pi / 4))
    for side, sign in (("left", 1.0), ("right", -1.0)):
        f = _sub(robot, "link", name=f"robotiq_{side}_finger")
        _inertial(f, 0.05, (0.022, 0.016, 0.06), xyz=(0, sign * 0.008, -0.02))
        # finger body (link from the base to the pad) and the pad itself; the pad's inner face is at
        # y = 0 of the finger frame at q = 0, so q is the gap between pad and centre line.
        _box_geom(f, (0.022, 0.010, 0.045), xyz=(0, sign * 0.013, -0.035), rgba=(0.2, 0.2, 0.2, 1))
        _box_geom(f, (0.022, 0.008, 0.0375), xyz=(0, sign * 0.004, 0.0), rgba=(0.45, 0.45, 0.45, 1))
        _joint(
            robot,
            f"robotiq_{side}_finger_joint",
            "prismatic",
            "robotiq_base",
            f"robotiq_{side}_finger",
            xyz=(0, 0, ROBOTIQ_PAD_Z),
            axis=(0, sign, 0),
            lower=0.0,
            upper=ROBOTIQ_STROKE,
            effort=100.0,
            velocity=0.15,
        )
    tcp = _sub(robot, "link", name="robotiq_tcp")
    _inertial(tcp, 0.01, (0.01, 0.01, 0.01))
    _joint(
        robot, "robotiq_tcp_joint", "fixed", "robotiq_base", "robotiq_tcp", xyz=(0, 0, ROBOTIQ_PAD_Z + 0.005)
    )


def default_cameras(base: BaseGeometry, hand_link: str) -> dict[str, CameraMount]:
    """Head camera on the mast top looking forward and 45 deg down; wrist camera on the hand
    looking along the fingers."""
    pitch = np.deg2rad(45.0)
    fwd = np.array([np.cos(pitch), 0.0, -np.sin(pitch)])
    r_head = look_rotation(fwd, np.array([0.0, 0.0, 1.0]))
    mast_len = base.mast_height - (base.clearance + base.chassis[2])
    head = CameraMount(
        link="head_camera",
        parent="mast",
        xyz=(0.05, 0.0, mast_len - 0.02),
        rpy=_rpy_from_matrix(r_head),
        vertical_fov=np.deg2rad(70.0),
    )
    r_wrist = look_rotation(np.array([-0.2, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]))
    wrist = CameraMount(
        link="wrist_camera",
        parent=hand_link,
        xyz=(0.075, 0.0, -0.01),
        rpy=_rpy_from_matrix(r_wrist),
        vertical_fov=np.deg2rad(75.0),
    )
    return {"head": head, "wrist": wrist}


def write_robot_urdf(
    out_dir: Path,
    *,
    gripper: GripperKind | str = GripperKind.PANDA_HAND,
    panda_root: Path | None = None,
    robotiq_root: Path | None = None,
    base: BaseGeometry | None = None,
    shared_assets: Path | None = None,
) -> RobotDescription:
    """Write ``<out_dir>/mobile_panda_<gripper>.urdf`` and return its description.

    panda_root: see :func:`find_panda_description`; robotiq_root: folder of the Menagerie 2F-85
    (needed for ``gripper="robotiq_2f85"``); shared_assets: the third-party assets folder (the
    hands, ``gripper="allegro"`` or ``"shadow"``; default ``stages.embodiment.sources.default_shared_assets``).
    """
    gripper = GripperKind(gripper)
    base = base or BaseGeometry()
    root = find_panda_description(panda_root)
    robot = ET.Element("robot", name=f"mobile_panda_{gripper.value}")
    _add_base(robot, base)
    for el in _panda_elements(root, gripper):
        robot.append(el)
    cz = base.clearance + base.chassis[2]
    _joint(robot, "arm_mount", "fixed", "base_link", "panda_link0", xyz=(*base.arm_mount, cz))
    if gripper == GripperKind.PANDA_HAND:
        spec = GripperSpec(
            kind=gripper,
            finger_joints=("panda_finger_joint1", "panda_finger_joint2"),
            open_q=0.04,
            closed_q=0.0,
            max_force=70.0,
            tcp="panda_hand_tcp",
            hand_link="panda_hand",
        )
    elif gripper in (GripperKind.ALLEGRO, GripperKind.SHADOW):
        from stages.embodiment.sources import default_shared_assets
        from stages.simulate.hands import add_hand

        hand = add_hand(robot, gripper.value, Path(shared_assets) if shared_assets else default_shared_assets())
        spec = GripperSpec(kind=gripper, finger_joints=hand.joints, open_q=0.0, closed_q=0.0,
                           max_force=max(hand.drive.effort), tcp=hand.tcp, hand_link=hand.palm_link,
                           squeeze=0.0, hand=hand)
    else:
        if robotiq_root is None:
            raise ItemError("robotiq_2f85: robotiq_root (the Menagerie 2F-85 folder) is required")
        _add_robotiq(robot, find_robotiq_description(robotiq_root))
        spec = GripperSpec(
            kind=gripper,
            finger_joints=("robotiq_left_finger_joint", "robotiq_right_finger_joint"),
            open_q=ROBOTIQ_STROKE,
            closed_q=0.0,
            max_force=100.0,
            tcp="robotiq_tcp",
            hand_link="robotiq_base",
        )
    cameras = default_cameras(base, spec.hand_link)
    for cam in cameras.values():
        _camera_link(robot, cam)
    ET.indent(robot)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / f"mobile_panda_{gripper.value}.urdf"
    tmp = path.with_suffix(".urdf.tmp")
    ET.ElementTree(robot).write(tmp, encoding="unicode", xml_declaration=True)
    tmp.replace(path)
    log.info("wrote robot URDF %s", path)
    return RobotDescription(urdf=path, gripper=spec, base=base, cameras=cameras)
