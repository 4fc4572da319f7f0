"""Unitree G1 (29 DoF, rubber hands fixed) for locomotion training: joints, gains, default pose, model.

The URDF comes from example-robot-data (a dependency, so CI and fresh clones have it). For speed
the URDF's meshes are dropped: the only collision shapes are one box per foot (the sole spanned by
mjlab's seven foot capsules) and the ground plane; links keep the URDF's inertials, so the
dynamics are the robot's. Gains follow mjlab's ``g1_constants.py``: armature is the reflected
inertia of each actuator's two-stage planetary gearbox, stiffness = armature * (2*pi*10 Hz)^2,
damping = 2 * 2.0 * armature * 2*pi*10 Hz; ankles and waist roll/pitch are two 5020 actuators.
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


def g1_urdf_path() -> Path:
    """The G1 URDF inside the installed example-robot-data package."""
    import sys
    for root in map(Path, sys.path):
        candidate = root / "cmeel.prefix/share/example-robot-data/robots/g1_description/urdf" / URDF_NAME
        if candidate.is_file():
            return candidate
    raise FileNotFoundError(f"{URDF_NAME} not found: is example-robot-data installed?")


def _urdf_without_geometry(path: Path) -> str:
    text = path.read_text()
    text = re.sub(r"<collision>.*?</collision>", "", text, flags=re.S)
    return re.sub(r"<visual>.*?</visual>", "", text, flags=re.S)


@dataclass(frozen=True)
class G1Layout:
    """Where the G1's joints sit in one world's coordinate and DoF vectors.

    ``joint_names`` are the 29 actuated joints in model order; coordinate ``7 + i`` and DoF ``6 + i``
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
    """body indices in a world of the feet (``FOOT_BODIES``: left, right)"""

    def index(self, names: tuple[str, ...]) -> list[int]:
        """joint indices (0..28) of the named joints"""
        return [self.joint_names.index(n) for n in names]


def g1_builder(*, foot_mu: float = 0.6, base_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
               ) -> tuple[Any, G1Layout]:
    """A Newton builder holding one G1 as trained: inertials of the URDF, sole spheres as the only
    collision shapes, position drives with mjlab's gains, the default pose standing with its base
    at ``base_pose`` = (x [m], y [m], yaw [rad]), ``DEFAULT_BASE_HEIGHT`` above z = 0. Returns
    ``(builder, layout)``; add it to a scene with ``ModelBuilder.add_builder`` or ``replicate``."""
    import newton
    import warp as wp

    x, y, yaw = base_pose
    robot = newton.ModelBuilder()
    newton.solvers.SolverMuJoCo.register_custom_attributes(robot)
    robot.default_shape_cfg.mu = foot_mu
    rot = wp.quat(0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))
    robot.add_urdf(_urdf_without_geometry(g1_urdf_path()), floating=True, collapse_fixed_joints=True,
                   enable_self_collisions=False, xform=wp.transform((x, y, DEFAULT_BASE_HEIGHT), rot))
    body_names = [label.rsplit("/", 1)[-1] for label in robot.body_label]
    joint_names = tuple(label.rsplit("/", 1)[-1] for label in robot.joint_label[1:])
    if len(joint_names) != 29 or robot.joint_coord_count != 36:
        raise RuntimeError(f"unexpected G1 layout: {len(joint_names)} joints, {robot.joint_coord_count} coords")
    foot_shapes = []
    for foot in FOOT_BODIES:
        for center in FOOT_SPHERES:
            foot_shapes.append(robot.shape_count)
            robot.add_shape_sphere(body_names.index(foot), xform=wp.transform(center, wp.quat_identity()),
                                   radius=FOOT_SPHERE_RADIUS)
    for i, name in enumerate(joint_names):
        gains = joint_gains(name)
        dof = 6 + i
        robot.joint_armature[dof] = gains.armature
        robot.joint_target_ke[dof] = gains.stiffness
        robot.joint_target_kd[dof] = gains.damping
        robot.joint_effort_limit[dof] = gains.effort_limit
        robot.joint_target_mode[dof] = int(newton.JointTargetMode.POSITION)
        robot.joint_q[7 + i] = DEFAULT_POSE.get(name, 0.0)
        robot.joint_target_q[7 + i] = DEFAULT_POSE.get(name, 0.0)
    layout = G1Layout(joint_names=joint_names, coords_per_world=robot.joint_coord_count,
                      dofs_per_world=robot.joint_dof_count, bodies_per_world=robot.body_count,
                      shapes_per_world=robot.shape_count, base_body=body_names.index(BASE_BODY),
                      foot_shapes=tuple(foot_shapes), foot_bodies=tuple(body_names.index(f) for f in FOOT_BODIES))
    return robot, layout


def build_g1_model(num_worlds: int, device: Any, *, foot_mu: float = 0.6, floor_mu: float = 0.3
                   ) -> tuple[Any, G1Layout]:
    """One Newton model holding ``num_worlds`` G1s on a shared ground plane, one world each.

    Returns ``(model, layout)``. Joint targets are in position mode with mjlab's gains; the default
    pose is the model's initial state.
    """
    import newton

    robot, layout = g1_builder(foot_mu=foot_mu)
    scene = newton.ModelBuilder()
    newton.solvers.SolverMuJoCo.register_custom_attributes(scene)
    scene.replicate(robot, num_worlds)
    floor_cfg = newton.ModelBuilder.ShapeConfig(mu=floor_mu)
    scene.add_ground_plane(cfg=floor_cfg)
    model = scene.finalize(device=device)
    return model, layout
