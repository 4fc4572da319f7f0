"""Unitree G1 (29 DoF, rubber hands fixed) for locomotion training: joints, gains, default pose, model.

The URDF comes from example-robot-data (a dependency, so CI and fresh clones have it). For speed
the URDF's meshes are dropped: the only collision shapes are one box per foot (the sole spanned by
mjlab's seven foot capsules) and the ground plane; links keep the URDF's inertials, so the
dynamics are the robot's. Gains follow mjlab's ``g1_constants.py``: armature is the reflected
inertia of each actuator's two-stage planetary gearbox, stiffness = armature * (2*pi*10 Hz)^2,
damping = 2 * 2.0 * armature * 2*pi*10 Hz; ankles and waist roll/pitch are two 5020 actuators.

``HumanoidDescription`` is what the locomotion stack needs of any humanoid (model file, sole
spheres, joints, default pose, drives, fall thresholds); ``G1`` holds this module's constants,
``stages.locomotion.h1.H1`` the H1's, ``stages.locomotion.humanoids`` names them.
``humanoid_builder`` / ``build_humanoid_model`` build either (``g1_builder`` / ``build_g1_model``:
the G1's).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

URDF_NAME = "g1_29dof_rev_1_0.urdf"

LEG_JOINTS: tuple[str, ...] = tuple(
    f"{side}_{j}_joint" for side in ("left", "right")
    for j in ("hip_pitch", "hip_roll", "hip_yaw", "knee", "ankle_pitch", "ankle_roll"))
WAIST_JOINTS: tuple[str, ...] = ("waist_yaw_joint", "waist_roll_joint", "waist_pitch_joint")
ARM_JOINTS: tuple[str, ...] = tuple(
    f"{side}_{j}_joint" for side in ("left", "right")
    for j in ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow", "wrist_roll", "wrist_pitch",
              "wrist_yaw"))
FOOT_BODIES: tuple[str, str] = ("left_ankle_roll_link", "right_ankle_roll_link")
BASE_BODY = "pelvis"

# mjlab KNEES_BENT_KEYFRAME (the default pose the actions are offsets from) [rad], base height [m]
DEFAULT_POSE: dict[str, float] = {
    "left_hip_pitch_joint": -0.312, "right_hip_pitch_joint": -0.312,
    "left_knee_joint": 0.669, "right_knee_joint": 0.669,
    "left_ankle_pitch_joint": -0.363, "right_ankle_pitch_joint": -0.363,
    "left_elbow_joint": 0.6, "right_elbow_joint": 0.6,
    "left_shoulder_roll_joint": 0.2, "right_shoulder_roll_joint": -0.2,
    "left_shoulder_pitch_joint": 0.2, "right_shoulder_pitch_joint": 0.2,
}
DEFAULT_BASE_HEIGHT = 0.76

# arm joint ranges [rad] of the wide ("reach") arm-target draw, left arm; the right arm mirrors the
# roll and yaw joints. They cover the hand from the thigh to above the head and 0.35 m in front of
# the chest (pinocchio FK of the G1 URDF, pelvis at 0.76 m: shoulder pitch -1.2, elbow 0.6 puts the
# hand at 1.10 m, 0.35 m forward), so counter-height reaching (0.9 m counters, hands 0.1-0.2 m
# above) is inside the training distribution, unlike the default +-0.6 rad around the default pose.
REACH_ARM_RANGES: dict[str, tuple[float, float]] = {
    "shoulder_pitch": (-2.0, 0.8), "shoulder_roll": (-0.2, 1.2), "shoulder_yaw": (-1.0, 1.0),
    "elbow": (-0.6, 1.8), "wrist_roll": (-1.0, 1.0), "wrist_pitch": (-1.0, 1.0), "wrist_yaw": (-1.0, 1.0),
}


def reach_arm_range(name: str) -> tuple[float, float]:
    """(low, high) [rad] of an arm joint's wide draw (``REACH_ARM_RANGES``, mirrored for the right arm)."""
    side, rest = name.split("_", 1)
    lo, hi = REACH_ARM_RANGES[rest.removesuffix("_joint")]
    if side == "right" and rest.split("_")[-2] in ("roll", "yaw"):
        lo, hi = -hi, -lo
    return lo, hi


# posture reward std per joint [rad] (mjlab UnitreeG1RoughEnvCfg), first matching pattern wins
POSTURE_STD: tuple[tuple[str, float], ...] = (
    (r".*hip_pitch.*", 0.3), (r".*hip_roll.*", 0.15), (r".*hip_yaw.*", 0.15), (r".*knee.*", 0.35),
    (r".*ankle_pitch.*", 0.25), (r".*ankle_roll.*", 0.1), (r".*waist_yaw.*", 0.15),
    (r".*waist_roll.*", 0.08), (r".*waist_pitch.*", 0.1), (r".*shoulder_pitch.*", 0.35),
    (r".*shoulder_roll.*", 0.15), (r".*shoulder_yaw.*", 0.1), (r".*elbow.*", 0.25), (r".*wrist.*", 0.3),
)

# foot sole: 4 spheres at the corners of the sole mjlab's seven foot capsules span, in the
# ankle_roll_link frame [m] (4 contacts per foot where a box gives 8: half the constraint rows)
FOOT_SPHERE_RADIUS = 0.01
SOLE_BELOW_ANKLE = 0.035
"""height of the ankle_roll_link origin over the sole's lowest point [m]"""
FOOT_SPHERES: tuple[tuple[float, float, float], ...] = tuple(
    (x, y, -0.025) for x in (-0.045, 0.125) for y in (-0.025, 0.025))


def _planetary(rotor: tuple[float, float, float], gear: tuple[float, float, float]) -> float:
    """reflected inertia of a two-stage planetary gearbox [kg m^2] (mjlab utils.actuator)"""
    return rotor[0] * (gear[1] * gear[2]) ** 2 + rotor[1] * gear[2] ** 2 + rotor[2]


_A5020 = _planetary((0.139e-4, 0.017e-4, 0.169e-4), (1.0, 1 + 46 / 18, 1 + 56 / 16))
_A7520_14 = _planetary((0.489e-4, 0.098e-4, 0.533e-4), (1.0, 4.5, 1 + 48 / 22))
_A7520_22 = _planetary((0.489e-4, 0.109e-4, 0.738e-4), (1.0, 4.5, 5.0))
_A4010 = _planetary((0.068e-4, 0.0, 0.0), (1.0, 5.0, 5.0))
_OMEGA = 10.0 * 2.0 * math.pi  # natural frequency [rad/s]
_ZETA = 2.0  # damping ratio

# (pattern, armature [kg m^2], effort limit [N m]); first match wins
_ACTUATORS: tuple[tuple[str, float, float], ...] = (
    (r".*_(elbow|shoulder_pitch|shoulder_roll|shoulder_yaw|wrist_roll)_joint", _A5020, 25.0),
    (r".*_(hip_pitch|hip_yaw)_joint|waist_yaw_joint", _A7520_14, 88.0),
    (r".*_(hip_roll|knee)_joint", _A7520_22, 139.0),
    (r".*_(wrist_pitch|wrist_yaw)_joint", _A4010, 5.0),
    (r"waist_(pitch|roll)_joint|.*_ankle_(pitch|roll)_joint", 2.0 * _A5020, 50.0),
)


@dataclass(frozen=True)
class JointGains:
    """PD drive of one joint."""

    armature: float
    """reflected rotor inertia [kg m^2]"""
    stiffness: float
    """position gain [N m / rad]"""
    damping: float
    """velocity gain [N m s / rad]"""
    effort_limit: float
    """[N m]"""

    @property
    def action_scale(self) -> float:
        """action-to-target scale 0.25 * effort / stiffness [rad] (mjlab G1_ACTION_SCALE)"""
        return 0.25 * self.effort_limit / self.stiffness


def joint_gains(name: str) -> JointGains:
    """PD gains of a G1 joint by name; raises KeyError for a joint no actuator drives."""
    for pattern, armature, effort in _ACTUATORS:
        if re.fullmatch(pattern, name):
            return JointGains(armature, armature * _OMEGA**2, 2.0 * _ZETA * armature * _OMEGA, effort)
    raise KeyError(f"no G1 actuator matches joint {name!r}")


def posture_std(name: str) -> float:
    """std of the posture reward for a joint [rad]"""
    for pattern, std in POSTURE_STD:
        if re.fullmatch(pattern, name):
            return std
    raise KeyError(f"no posture std for joint {name!r}")


@dataclass(frozen=True, kw_only=True)
class HumanoidDescription:
    """One humanoid as the locomotion stack trains it: where its model file is, its sole spheres,
    the policy's and the PD-held arms' joints, default pose, drives and fall thresholds.

    Joint-keyed tables are ``(regex, value)`` tuples, first full match wins. Positions in metres,
    angles in radians, gains in N m / rad and N m s / rad, efforts in N m, armature in kg m^2.
    """

    name: str
    """registry key (``humanoids.ROBOTS``), ``EnvConfig.robot``"""
    label: str
    """what the model is (written to ``policy.json`` as ``robot``)"""
    source_origin: str
    """"example-robot-data" (the installed package) or "shared" (the shared third-party assets)"""
    source_file: str
    """URDF (``.urdf``) or MJCF (``.xml``) path inside its origin"""
    num_joints: int
    """actuated joints (the model's coordinates are 7 + num_joints)"""
    base_body: str
    foot_bodies: tuple[str, str]
    """left, right"""
    foot_spheres: tuple[tuple[float, float, float], ...]
    """sole sphere centres in each foot body's frame [m] (the feet's only collision shapes)"""
    foot_sphere_radius: float
    sole_below_ankle: float
    """height of the foot body's origin over the sole's lowest point [m]"""
    leg_joints: tuple[str, ...]
    waist_joints: tuple[str, ...]
    """driven by the policy when ``EnvConfig.use_waist``, else held at the default pose"""
    arm_joints: tuple[str, ...]
    """held by PD at random targets redrawn every ``arm_resample_steps``"""
    default_pose: dict[str, float]
    """joint positions the actions are offsets from (others 0) [rad]"""
    base_height: float
    """base body height at the default pose with the soles on z = 0 [m]"""
    drives: tuple[tuple[str, JointGains], ...]
    action_scale: float | None
    """action-to-target scale [rad]; None: 0.25 * effort / stiffness per joint (mjlab)"""
    posture_std: tuple[tuple[str, float], ...]
    reach_ranges: dict[str, tuple[float, float]]
    """left-arm joint (name without side and ``_joint``) -> wide-draw range; the right arm mirrors
    the roll and yaw joints"""
    fall_height: float
    """base height under which a world has fallen [m]"""
    fall_tilt_deg: float = 70.0
    """base tilt over which a world has fallen [deg]"""

    @property
    def joints(self) -> tuple[str, ...]:
        """all actuated joints, legs, waist, arms (the model order of the G1 and H1)"""
        return self.leg_joints + self.waist_joints + self.arm_joints

    def gains(self, joint: str) -> JointGains:
        """PD drive of a joint; KeyError for a joint no drive matches."""
        for pattern, gains in self.drives:
            if re.fullmatch(pattern, joint):
                return gains
        raise KeyError(f"{self.name}: no drive matches joint {joint!r}")

    def joint_action_scale(self, joint: str) -> float:
        """action-to-target scale of a policy joint [rad]"""
        return self.gains(joint).action_scale if self.action_scale is None else self.action_scale

    def joint_posture_std(self, joint: str) -> float:
        """std of the posture reward for a joint [rad]"""
        for pattern, std in self.posture_std:
            if re.fullmatch(pattern, joint):
                return std
        raise KeyError(f"{self.name}: no posture std for joint {joint!r}")

    def reach_range(self, joint: str) -> tuple[float, float]:
        """(low, high) [rad] of an arm joint's wide draw (mirrored for the right arm)"""
        side, rest = joint.split("_", 1)
        lo, hi = self.reach_ranges[rest.removesuffix("_joint")]
        if side == "right" and rest.split("_")[-2] in ("roll", "yaw"):
            lo, hi = -hi, -lo
        return lo, hi

    def source_path(self) -> Path:
        """The model file; FileNotFoundError naming what is missing."""
        if self.source_origin == "example-robot-data":
            import sys
            for root in map(Path, sys.path):
                candidate = root / "cmeel.prefix/share/example-robot-data" / self.source_file
                if candidate.is_file():
                    return candidate
            raise FileNotFoundError(f"{self.source_file} not found: is example-robot-data installed?")
        from stages.embodiment.sources import default_shared_assets

        path = default_shared_assets() / self.source_file
        if not path.is_file():
            raise FileNotFoundError(f"{path}: the {self.name} model is missing (shared third-party assets)")
        return path



def g1_urdf_path() -> Path:
    """The G1 URDF inside the installed example-robot-data package."""
    return G1.source_path()


def _urdf_without_geometry(path: Path) -> str:
    text = path.read_text()
    text = re.sub(r"<collision>.*?</collision>", "", text, flags=re.S)
    return re.sub(r"<visual>.*?</visual>", "", text, flags=re.S)


def _mjcf_without_geometry(path: Path) -> str:
    """The MJCF's bodies, joints and inertials only: geoms, meshes, sites, actuators (the drives
    are set from the description), sensors and keyframes removed."""
    text = path.read_text()
    for tag in ("actuator", "sensor", "keyframe", "asset"):
        text = re.sub(rf"<{tag}>.*?</{tag}>", "", text, flags=re.S)
    text = re.sub(r"<geom\b[^>]*/>", "", text)
    return re.sub(r"<site\b[^>]*/>", "", text)


G1 = HumanoidDescription(
    name="g1", label="unitree_g1_29dof_rev_1_0 (example-robot-data)", source_origin="example-robot-data",
    source_file=f"robots/g1_description/urdf/{URDF_NAME}", num_joints=29, base_body=BASE_BODY,
    foot_bodies=FOOT_BODIES, foot_spheres=FOOT_SPHERES, foot_sphere_radius=FOOT_SPHERE_RADIUS,
    sole_below_ankle=SOLE_BELOW_ANKLE, leg_joints=LEG_JOINTS, waist_joints=WAIST_JOINTS,
    arm_joints=ARM_JOINTS,
    default_pose=DEFAULT_POSE, base_height=DEFAULT_BASE_HEIGHT,
    drives=tuple((pattern, JointGains(a, a * _OMEGA**2, 2.0 * _ZETA * a * _OMEGA, effort))
                 for pattern, a, effort in _ACTUATORS),
    action_scale=None, posture_std=POSTURE_STD, reach_ranges=REACH_ARM_RANGES, fall_height=0.3)
"""the G1 as trained for ``policies/g1_velocity`` (the module constants above)"""


@dataclass(frozen=True)
class G1Layout:
    """Where a humanoid's joints sit in one world's coordinate and DoF vectors.

    ``joint_names`` are the actuated joints in model order; coordinate ``7 + i`` and DoF ``6 + i``
    belong to joint ``i`` (7 free-base coordinates: position, quaternion xyzw; 6 base DoFs:
    linear then angular velocity, world frame).
    """

    joint_names: tuple[str, ...]
    coords_per_world: int
    dofs_per_world: int
    bodies_per_world: int
    shapes_per_world: int
    base_body: int
    foot_shapes: tuple[int, ...]
    """shape indices in a world of the feet's sole spheres (left foot's first)"""
    foot_bodies: tuple[int, ...] = ()
    """body indices in a world of the feet (``foot_bodies`` of the description: left, right)"""

    def index(self, names: tuple[str, ...]) -> list[int]:
        """joint indices of the named joints"""
        return [self.joint_names.index(n) for n in names]


HumanoidLayout = G1Layout


def humanoid_builder(desc: HumanoidDescription, *, foot_mu: float = 0.6,
                     base_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> tuple[Any, G1Layout]:
    """A Newton builder holding one humanoid as trained: inertials of its model file, sole spheres as
    the only collision shapes, position drives with the description's gains, the default pose
    standing with its base at ``base_pose`` = (x [m], y [m], yaw [rad]), ``desc.base_height`` above
    z = 0. Returns ``(builder, layout)``; add it to a scene with ``add_builder`` or ``replicate``."""
    import newton
    import warp as wp

    x, y, yaw = base_pose
    robot = newton.ModelBuilder()
    newton.solvers.SolverMuJoCo.register_custom_attributes(robot)
    robot.default_shape_cfg.mu = foot_mu
    rot = wp.quat(0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))
    xform = wp.transform((x, y, desc.base_height), rot)
    path = desc.source_path()
    if path.suffix == ".urdf":
        robot.add_urdf(_urdf_without_geometry(path), floating=True, collapse_fixed_joints=True,
                       enable_self_collisions=False, xform=xform)
    else:
        robot.add_mjcf(_mjcf_without_geometry(path), floating=True, collapse_fixed_joints=True,
                       enable_self_collisions=False, xform=xform, override_root_xform=True,
                       parse_sites=False, parse_visuals=False)
    body_names = [label.rsplit("/", 1)[-1] for label in robot.body_label]
    joint_names = tuple(label.rsplit("/", 1)[-1] for label in robot.joint_label[1:])
    if len(joint_names) != desc.num_joints or robot.joint_coord_count != 7 + desc.num_joints:
        raise RuntimeError(f"{path}: unexpected {desc.name} layout: {len(joint_names)} joints, "
                           f"{robot.joint_coord_count} coords "
                           f"(expected {desc.num_joints}, {7 + desc.num_joints})")
    foot_shapes = []
    for foot in desc.foot_bodies:
        for center in desc.foot_spheres:
            foot_shapes.append(robot.shape_count)
            robot.add_shape_sphere(body_names.index(foot), xform=wp.transform(center, wp.quat_identity()),
                                   radius=desc.foot_sphere_radius)
    for i, name in enumerate(joint_names):
        gains = desc.gains(name)
        dof = 6 + i
        robot.joint_armature[dof] = gains.armature
        robot.joint_target_ke[dof] = gains.stiffness
        robot.joint_target_kd[dof] = gains.damping
        robot.joint_effort_limit[dof] = gains.effort_limit
        robot.joint_target_mode[dof] = int(newton.JointTargetMode.POSITION)
        robot.joint_q[7 + i] = desc.default_pose.get(name, 0.0)
        robot.joint_target_q[7 + i] = desc.default_pose.get(name, 0.0)
    layout = G1Layout(joint_names=joint_names, coords_per_world=robot.joint_coord_count,
                      dofs_per_world=robot.joint_dof_count, bodies_per_world=robot.body_count,
                      shapes_per_world=robot.shape_count, base_body=body_names.index(desc.base_body),
                      foot_shapes=tuple(foot_shapes),
                      foot_bodies=tuple(body_names.index(f) for f in desc.foot_bodies))
    return robot, layout


def g1_builder(*, foot_mu: float = 0.6, base_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
               ) -> tuple[Any, G1Layout]:
    """``humanoid_builder`` of the G1."""
    return humanoid_builder(G1, foot_mu=foot_mu, base_pose=base_pose)


def build_humanoid_model(desc: HumanoidDescription, num_worlds: int, device: Any, *, foot_mu: float = 0.6,
                         floor_mu: float = 0.3) -> tuple[Any, G1Layout]:
    """One Newton model holding ``num_worlds`` humanoids on a shared ground plane, one world each.

    Returns ``(model, layout)``. Joint targets are in position mode with the description's gains;
    the default pose is the model's initial state.
    """
    import newton

    robot, layout = humanoid_builder(desc, foot_mu=foot_mu)
    scene = newton.ModelBuilder()
    newton.solvers.SolverMuJoCo.register_custom_attributes(scene)
    scene.replicate(robot, num_worlds)
    floor_cfg = newton.ModelBuilder.ShapeConfig(mu=floor_mu)
    scene.add_ground_plane(cfg=floor_cfg)
    model = scene.finalize(device=device)
    return model, layout


def build_g1_model(num_worlds: int, device: Any, *, foot_mu: float = 0.6, floor_mu: float = 0.3
                   ) -> tuple[Any, G1Layout]:
    """``build_humanoid_model`` of the G1."""
    return build_humanoid_model(G1, num_worlds, device, foot_mu=foot_mu, floor_mu=floor_mu)
