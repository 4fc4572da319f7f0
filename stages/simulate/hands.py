"""Dexterous hands mounted on the Panda's flange: the Allegro hand (16 DoF, RobotLocomotion's URDF)
and the Shadow hand (22 finger DoF, gymnasium-robotics' MJCF), written into the robot URDF of
:func:`stages.simulate.robot.write_robot_urdf` (``gripper="allegro"`` / ``"shadow"``).

Mount: the hand's back (dorsum) sits on a 10 mm adapter on ``panda_link8``, its palm facing along
the flange's +Z, so that the Panda approaches a grasp along the flange axis as it does with a
parallel gripper. The end-effector frame ``<hand>_tcp`` lies on the palm surface: +Z is the palm
normal (out of the palm), +X points along the fingers, and it is ``panda_link8`` turned -45 deg
about Z and moved ``tcp_z`` along Z (as ``panda_hand_tcp``). A grasped cylinder lies along the
TCP's Y axis, in front of the palm.

Sources and what is kept:
- Allegro (``allegro_hand_description_right.urdf``): links, joints, limits, inertias, collision
  boxes and fingertip spheres, glTF visuals; the names get the prefix ``allegro_``. Its
  ``<dynamics friction="5..10">`` (a Drake value, a 5-10 N m Coulomb friction that would lock
  0.7 N m joints in MuJoCo) is dropped; its damping (0.015 N m s/rad) is kept.
- Shadow (``hand/robot.xml``): the palm and the five fingers below it (the forearm and the two
  wrist joints are left out: the Panda's wrist replaces them); MJCF bodies become links (pos /
  quat / axis-angle frames, inertials), hinge joints with their ranges, collision capsules become
  a cylinder and two spheres, boxes stay boxes, STL meshes are the visuals. The names lose
  ``robot0:`` and get ``shadow_``. The MJCF couples each finger's distal joint J0 to J1 with a
  tendon and has no actuator on J0; here J0 has its own drive and the closing synergy moves it
  with J1 (the tendon's ratio, about 1.14).

Drives (``HandDrive``): the Allegro's 0.7 N m effort limit from its URDF with kp 3 N m/rad, kd
0.1 (the values IsaacGymEnvs' Allegro task uses); the Shadow's actuator gains of its MJCF (kp 1,
force ranges 0.72-2.37 N m per joint, damping 0.1, armature 0.001). Joint armature for both is
raised to ``armature`` (reflected inertia of geared finger drives) so that MuJoCo's soft contacts
stay stiff at the fingertips (see ``stages.simulate.robot_load.DriveGains``).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.types import ItemError

ALLEGRO_REL = Path("robots/allegro_hand__robotlocomotion/drake_models/allegro_hand_description")
SHADOW_REL = Path("robots/shadow_hand__gymnasium_robotics")
ADAPTER = 0.010  # [m] flange adapter between panda_link8 and the back of the hand


@dataclass(frozen=True, kw_only=True)
class HandDrive:
    """Per-joint drive of a hand: kp [N m/rad], kd [N m s/rad], armature [kg m^2], effort
    limits [N m] (one per joint, joint order of the hand)."""

    kp: float
    kd: float
    armature: float
    effort: tuple[float, ...]


@dataclass(frozen=True, kw_only=True)
class HandInfo:
    """What controllers and grasp synthesis need of a mounted hand. joints: finger joints in
    control order; open / closed: the closing synergy's end postures [rad] (command 0 / 1);
    tips: fingertip link names, thumb tip first; palm_link; tcp: the end-effector frame; tcp_z:
    TCP height above panda_link8's flange [m]; palm_half: the palm's half extent along the TCP's
    X and Y [m] (how far the palm reaches along the fingers' direction and across); reach: the
    largest object radius the synergy wraps [m]; grasp_x: where along the TCP's X (the fingers'
    direction) a grasped cylinder's axis lies [m]; fingers: finger name ("thumb", "index", ...)
    -> its link names; drive; handle_side: the side of the TCP's Y a mug's handle must be on in a
    top grasp (+1 / -1; 0: either; :func:`stages.demos.hand_grasps.plan_top_grasp`);
    hook_open / hook_closed: the end postures [rad] of the hook synergy that grips a bar handle
    with the fingers alone, the thumb folded out of the way (empty: the closing synergy's;
    :meth:`synergy`)."""

    kind: str
    joints: tuple[str, ...]
    open: tuple[float, ...]
    closed: tuple[float, ...]
    tips: tuple[str, ...]
    palm_link: str
    tcp: str
    tcp_z: float
    palm_half: tuple[float, float]
    reach: float
    grasp_x: float
    fingers: dict[str, tuple[str, ...]]
    drive: HandDrive
    handle_side: int = 0
    hook_open: tuple[float, ...] = ()
    hook_closed: tuple[float, ...] = ()

    def synergy(self, command: float, *, hook: bool = False) -> np.ndarray:
        """Finger joint targets (n,) [rad] for a command in [0, 1] (0 open, 1 closed) along the
        closing synergy, or with ``hook`` along the hook synergy (the closing one where the hand
        has none)."""
        o, k = (self.hook_open, self.hook_closed) if hook and self.hook_open else (self.open, self.closed)
        c = float(np.clip(command, 0.0, 1.0))
        return np.asarray(o, float) + c * (np.asarray(k, float) - np.asarray(o, float))


def _fmt(v) -> str:
    return " ".join(f"{float(x):.9g}" for x in v)


def _rpy(r: np.ndarray) -> tuple[float, float, float]:
    """URDF rpy [rad] of a rotation (3, 3); at gimbal lock (pitch +-90 deg) any split of roll and
    yaw is exact, so scipy's warning about it is silenced."""
    import warnings

    from scipy.spatial.transform import Rotation

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return tuple(float(a) for a in Rotation.from_matrix(r).as_euler("xyz"))


def _mount(robot: ET.Element, palm: str, r_tcp_palm: np.ndarray, palm_point: np.ndarray, tcp: str,
           tcp_z: float) -> None:
    """Fixed joints panda_link8 -> palm and panda_link8 -> tcp (see the module docstring)."""
    rz = np.array([[np.cos(-np.pi / 4), -np.sin(-np.pi / 4), 0], [np.sin(-np.pi / 4), np.cos(-np.pi / 4), 0],
                   [0, 0, 1.0]])
    # palm frame in link8: T(link8 -> tcp) * T(tcp -> palm); the tcp is at palm_point in the palm
    p_tcp = np.array([0.0, 0.0, tcp_z])
    r = rz @ r_tcp_palm
    p = p_tcp - r @ palm_point
    j = ET.SubElement(robot, "joint", name=f"{palm}_mount", type="fixed")
    ET.SubElement(j, "parent", link="panda_link8")
    ET.SubElement(j, "child", link=palm)
    ET.SubElement(j, "origin", xyz=_fmt(p), rpy=_fmt(_rpy(r)))
    link = ET.SubElement(robot, "link", name=tcp)
    ine = ET.SubElement(link, "inertial")
    ET.SubElement(ine, "mass", value="0.001")
    ET.SubElement(ine, "inertia", ixx="1e-8", ixy="0", ixz="0", iyy="1e-8", iyz="0", izz="1e-8")
    j = ET.SubElement(robot, "joint", name=f"{tcp}_joint", type="fixed")
    ET.SubElement(j, "parent", link="panda_link8")
    ET.SubElement(j, "child", link=tcp)
    ET.SubElement(j, "origin", xyz=_fmt(p_tcp), rpy=_fmt(_rpy(rz)))


# --------------------------------------------------------------------------------------------
# Allegro
# --------------------------------------------------------------------------------------------

ALLEGRO_JOINTS = tuple(f"allegro_joint_{i}" for i in range(16))
# fingers (index 0-3, middle 4-7, ring 8-11): abduction, three flexions; thumb 12-15
ALLEGRO_OPEN = (0.0, 0.0, 0.0, 0.0) * 3 + (1.2, 0.2, 0.0, 0.0)
ALLEGRO_CLOSED = (0.0, 1.45, 1.6, 1.5) * 3 + (1.35, 0.9, 1.5, 1.6)
# the hook synergy (bar handles): the fingers close as in ALLEGRO_CLOSED, the thumb lies folded
# against the palm's side (joint 12 at its lower limit, 13 flexed): open, it stands 11-13 cm out of
# the palm and met a drawer's front 6-7 cm before the palm reached the drawer's bar (record-table,
# open_drawer); folded, nothing of it stands more than 3.1 cm out of the palm plane
ALLEGRO_HOOK_THUMB = (0.27, 1.1, 0.0, 0.0)
ALLEGRO_PALM_FACE = 0.0111  # [m] palm surface along +X of palm_link (collision box -0.0093 + 0.0204)


def allegro_info() -> HandInfo:
    return HandInfo(kind="allegro", joints=ALLEGRO_JOINTS, open=ALLEGRO_OPEN, closed=ALLEGRO_CLOSED,
                    tips=("allegro_link_15_tip", "allegro_link_3_tip", "allegro_link_7_tip", "allegro_link_11_tip"),
                    palm_link="allegro_palm_link", tcp="allegro_tcp", tcp_z=0.0508,   # ADAPTER + the palm box (40.8 mm)
                    palm_half=(0.05, 0.056), reach=0.05, grasp_x=0.015,
                    fingers={name: tuple(f"allegro_link_{i}" for i in range(4 * k, 4 * k + 4)) + (f"allegro_link_{4 * k + 3}_tip",)
                             for k, name in ((3, "thumb"), (0, "index"), (1, "middle"), (2, "ring"))},
                    drive=HandDrive(kp=3.0, kd=0.1, armature=0.01, effort=(0.7,) * 16),
                    # a handle on the ring finger's side (+Y) takes the ring finger's grip: the mug
                    # slipped out in the lift (2 of 2 episodes with the handle there; record-table)
                    handle_side=-1, hook_open=ALLEGRO_OPEN[:12] + ALLEGRO_HOOK_THUMB,
                    hook_closed=ALLEGRO_CLOSED[:12] + ALLEGRO_HOOK_THUMB)


def add_allegro(robot: ET.Element, shared_assets: Path, *, palm_z: float = -0.035) -> HandInfo:
    """Append the Allegro right hand's links and joints to ``robot`` mounted on panda_link8.
    ``palm_z``: where along the palm (palm_link Z [m], the finger bases are at 0, the wrist at
    -0.095) the TCP lies."""
    root = Path(shared_assets) / ALLEGRO_REL
    src = root / "urdf" / "allegro_hand_description_right.urdf"
    try:
        tree = ET.parse(src)
    except (ET.ParseError, OSError) as e:
        raise ItemError(f"{src}: cannot read the Allegro URDF: {e}") from None
    info = allegro_info()
    for el in tree.getroot():
        if el.tag not in ("link", "joint") or el.get("name") in ("hand_root", "root_to_base"):
            continue
        el.set("name", "allegro_" + el.get("name"))
        for tag in ("parent", "child"):
            for ref in el.findall(tag):
                ref.set("link", "allegro_" + ref.get("link"))
        for dyn in el.findall("dynamics"):
            dyn.attrib.pop("friction", None)
        for mesh in el.iter("mesh"):
            fn = mesh.get("filename", "")
            fn = str(root / fn.split("allegro_hand_description/", 1)[1]) if "allegro_hand_description/" in fn else fn
            if not Path(fn).is_file():
                raise ItemError(f"{src}: mesh {fn} not found")
            mesh.set("filename", fn)
        robot.append(el)
    r_tcp_palm = np.array([[0, 0, 1], [0, -1, 0], [1, 0, 0]], float).T   # columns: palm x, y, z in the tcp
    _mount(robot, info.palm_link, r_tcp_palm, np.array([ALLEGRO_PALM_FACE, 0.0, palm_z]), info.tcp, info.tcp_z)
    return info


# --------------------------------------------------------------------------------------------
# Shadow
# --------------------------------------------------------------------------------------------

_SH_FINGERS = ("FF", "MF", "RF", "LF")
SHADOW_JOINTS = tuple(f"shadow_{f}J{i}" for f in _SH_FINGERS for i in (3, 2, 1, 0)) + ("shadow_LFJ4",) + tuple(
    f"shadow_THJ{i}" for i in (4, 3, 2, 1, 0))
# per finger: J3 abduction, J2 / J1 / J0 flexion (J0 = 1.14 J1, the tendon); LFJ4 (little finger
# metacarpal); thumb: THJ4 rotation, THJ3 opposition, THJ2, THJ1 flexion, THJ0 distal
SHADOW_OPEN = (0.0, 0.0, 0.0, 0.0) * 4 + (0.0,) + (-1.0, 1.2, 0.0, 0.0, 0.0)
SHADOW_CLOSED = (0.0, 1.4, 1.2, 1.37) * 4 + (0.3,) + (0.4, 1.22, 0.2, 0.52, -1.0)
_SH_EFFORT = {"J3": 0.9, "J2": 0.9, "J1": 0.7245, "J0": 0.7245, "LFJ4": 0.9,
              "THJ4": 2.3722, "THJ3": 1.45, "THJ2": 0.99, "THJ1": 0.99, "THJ0": 0.81}


def shadow_info() -> HandInfo:
    effort = tuple(_SH_EFFORT.get(j.removeprefix("shadow_"), _SH_EFFORT.get(j[-2:], 0.9)) for j in SHADOW_JOINTS)
    return HandInfo(kind="shadow", joints=SHADOW_JOINTS, open=SHADOW_OPEN, closed=SHADOW_CLOSED,
                    tips=("shadow_thdistal", "shadow_ffdistal", "shadow_mfdistal", "shadow_rfdistal", "shadow_lfdistal"),
                    palm_link="shadow_palm", tcp="shadow_tcp", tcp_z=0.0322,   # ADAPTER + the palm box (22.2 mm)
                    palm_half=(0.05, 0.035), reach=0.05, grasp_x=0.02,
                    fingers={"thumb": tuple(f"shadow_th{p}" for p in ("base", "proximal", "hub", "middle", "distal")),
                             **{name: tuple(f"shadow_{f}{p}" for p in ("knuckle", "proximal", "middle", "distal"))
                                for f, name in (("ff", "index"), ("mf", "middle"), ("rf", "ring"), ("lf", "little"))}},
                    drive=HandDrive(kp=1.0, kd=0.1, armature=0.01, effort=effort))


def _quat_of(el: ET.Element) -> np.ndarray:
    """Rotation (3, 3) of an MJCF element's quat / axisangle / euler (radians, xyz intrinsic)."""
    from scipy.spatial.transform import Rotation

    if el.get("quat"):
        return Rotation.from_quat([float(v) for v in el.get("quat").split()], scalar_first=True).as_matrix()
    if el.get("axisangle"):
        a = np.array([float(v) for v in el.get("axisangle").split()])
        return Rotation.from_rotvec(a[:3] / np.linalg.norm(a[:3]) * a[3]).as_matrix()
    if el.get("euler"):
        return Rotation.from_euler("XYZ", [float(v) for v in el.get("euler").split()]).as_matrix()
    return np.eye(3)


def _vec(el: ET.Element, key: str, default=(0.0, 0.0, 0.0)) -> np.ndarray:
    return np.array([float(v) for v in el.get(key).split()]) if el.get(key) else np.array(default, float)


def _geom(link: ET.Element, tag: str, xyz, r, shape: str, **attrs) -> None:
    g = ET.SubElement(link, tag)
    ET.SubElement(g, "origin", xyz=_fmt(xyz), rpy=_fmt(_rpy(r)))
    ET.SubElement(ET.SubElement(g, "geometry"), shape, **{k: str(v) for k, v in attrs.items()})


def urdf_inertial(link: ET.Element, ine: ET.Element) -> None:
    """Add to URDF ``link`` the inertial of an MJCF ``<inertial>`` (mass, pos, diaginertia turned by
    its quat / axisangle / euler into the link frame's full tensor)."""
    r = _quat_of(ine)
    i3 = r @ np.diag(_vec(ine, "diaginertia")) @ r.T
    el = ET.SubElement(link, "inertial")
    ET.SubElement(el, "origin", xyz=_fmt(_vec(ine, "pos")), rpy="0 0 0")
    ET.SubElement(el, "mass", value=ine.get("mass"))
    ET.SubElement(el, "inertia", ixx=f"{i3[0, 0]:.9g}", ixy=f"{i3[0, 1]:.9g}", ixz=f"{i3[0, 2]:.9g}",
                  iyy=f"{i3[1, 1]:.9g}", iyz=f"{i3[1, 2]:.9g}", izz=f"{i3[2, 2]:.9g}")


def _shadow_link(robot: ET.Element, body: ET.Element, name: str, stl: Path) -> None:
    link = ET.SubElement(robot, "link", name=name)
    ine = body.find("inertial")
    if ine is not None:
        urdf_inertial(link, ine)
    for g in body.findall("geom"):
        pos, r = _vec(g, "pos"), _quat_of(g)
        if g.get("class") == "robot0:D_Vizual" and g.get("mesh"):
            mesh = g.get("mesh").removeprefix("robot0:")
            _geom(link, "visual", pos, r, "mesh", filename=str(stl / f"{mesh}.stl"), scale="0.001 0.001 0.001")
        elif g.get("class") == "robot0:DC_Hand":
            size = _vec(g, "size")
            if g.get("type") == "capsule":
                rad, half = size[0], size[1]
                _geom(link, "collision", pos, r, "cylinder", radius=f"{rad:.9g}", length=f"{2 * half:.9g}")
                for s in (-1, 1):
                    _geom(link, "collision", pos + r @ [0, 0, s * half], np.eye(3), "sphere", radius=f"{rad:.9g}")
            elif g.get("type") == "box":
                _geom(link, "collision", pos, r, "box", size=_fmt(2 * size))


def add_shadow(robot: ET.Element, shared_assets: Path, *, palm_z: float = 0.045) -> HandInfo:
    """Append the Shadow hand's palm and fingers to ``robot`` mounted on panda_link8. ``palm_z``:
    where along the palm (palm Z [m]; knuckles at 0.095) the TCP lies."""
    root = Path(shared_assets) / SHADOW_REL
    src = root / "hand" / "robot.xml"
    try:
        tree = ET.parse(src)
    except (ET.ParseError, OSError) as e:
        raise ItemError(f"{src}: cannot read the Shadow hand MJCF: {e}") from None
    palm = next((b for b in tree.iter("body") if b.get("name") == "robot0:palm"), None)
    if palm is None:
        raise ItemError(f"{src}: no body 'robot0:palm'")
    info = shadow_info()
    stl = root / "stls" / "hand"

    def walk(body: ET.Element, parent: str | None) -> None:
        name = "shadow_" + body.get("name").removeprefix("robot0:")
        _shadow_link(robot, body, name, stl)
        if parent is not None:
            joints = body.findall("joint")
            j = ET.SubElement(robot, "joint", name="shadow_" + joints[0].get("name").removeprefix("robot0:")
                              if joints else f"{name}_weld", type="revolute" if joints else "fixed")
            ET.SubElement(j, "parent", link=parent)
            ET.SubElement(j, "child", link=name)
            ET.SubElement(j, "origin", xyz=_fmt(_vec(body, "pos")), rpy=_fmt(_rpy(_quat_of(body))))
            if joints:
                lo, hi = (float(v) for v in joints[0].get("range").split())
                ET.SubElement(j, "axis", xyz=_fmt(_vec(joints[0], "axis")))
                ET.SubElement(j, "limit", lower=f"{lo:.9g}", upper=f"{hi:.9g}", effort="2.5", velocity="4")
                ET.SubElement(j, "dynamics", damping="0.1")
        for child in body.findall("body"):
            walk(child, name)

    walk(palm, None)
    r_tcp_palm = np.array([[0, -1, 0], [0, 0, -1], [1, 0, 0]], float).T
    _mount(robot, info.palm_link, r_tcp_palm, np.array([0.011, -0.0111, palm_z]), info.tcp, info.tcp_z)
    return info


def add_hand(robot: ET.Element, kind: str, shared_assets: Path) -> HandInfo:
    """Append hand ``kind`` ("allegro" | "shadow") to the robot URDF element, mounted on panda_link8."""
    if kind == "allegro":
        return add_allegro(robot, shared_assets)
    if kind == "shadow":
        return add_shadow(robot, shared_assets)
    raise ItemError(f"unknown hand {kind!r} (allegro | shadow)")
