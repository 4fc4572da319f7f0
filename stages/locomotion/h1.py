"""Unitree H1 (19 DoF: legs 2 x 5, torso 1, arms 2 x 4, no hands) for locomotion training.

The model is newton-assets' MJCF of unitree_ros (shared third-party assets,
``robots/unitree_h1__newton_assets/mjcf/h1.xml``, as in ``stages/embodiment/specs/h1.toml``): its
bodies, joints and inertials; its mesh geoms are dropped and each foot gets 4 sole spheres (the
corners of the sole MuJoCo Menagerie's H1 foot capsules span: x -0.05..0.13 m, lowest point 0.07 m
under the ankle). PD gains, action scale 0.25 and the leg default pose are unitree_rl_gym's
``H1RoughCfg``; armature 0.1 is the MJCF's default class; effort limits its motors' ctrlrange. The
policy drives the 10 leg joints and the torso (``EnvConfig.use_waist``); the arms are held by PD.
"""

from __future__ import annotations

from stages.locomotion.robot import HumanoidDescription, JointGains

LEG_JOINTS: tuple[str, ...] = tuple(
    f"{side}_{j}_joint" for side in ("left", "right")
    for j in ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle"))
WAIST_JOINTS: tuple[str, ...] = ("torso_joint",)
ARM_JOINTS: tuple[str, ...] = tuple(
    f"{side}_{j}_joint" for side in ("left", "right")
    for j in ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow"))

ARMATURE = 0.1
"""the MJCF's default-class armature [kg m^2]"""

# (pattern, kp [N m/rad], kd [N m s/rad], effort [N m]): unitree_rl_gym H1RoughCfg.control, ctrlrange
_DRIVES: tuple[tuple[str, float, float, float], ...] = (
    (r".*_hip_(yaw|roll|pitch)_joint", 150.0, 2.0, 200.0),
    (r".*_knee_joint", 200.0, 4.0, 300.0),
    (r".*_ankle_joint", 40.0, 2.0, 40.0),
    (r"torso_joint", 300.0, 6.0, 200.0),
    (r".*_shoulder_(pitch|roll)_joint", 150.0, 2.0, 40.0),
    (r".*_shoulder_yaw_joint", 150.0, 2.0, 18.0),
    (r".*_elbow_joint", 100.0, 2.0, 18.0),
)

H1 = HumanoidDescription(
    name="h1", label="unitree_h1 (newton-assets MJCF, unitree_ros)", source_origin="shared",
    source_file="robots/unitree_h1__newton_assets/mjcf/h1.xml", num_joints=19, base_body="pelvis",
    foot_bodies=("left_ankle_link", "right_ankle_link"),
    foot_spheres=tuple((x, y, -0.06) for x in (-0.04, 0.12) for y in (-0.02, 0.02)),
    foot_sphere_radius=0.01, sole_below_ankle=0.07,
    leg_joints=LEG_JOINTS, waist_joints=WAIST_JOINTS, arm_joints=ARM_JOINTS,
    # legs: unitree_rl_gym H1RoughCfg.init_state; elbows bent as in the embodiment spec
    default_pose={"left_hip_pitch_joint": -0.1, "right_hip_pitch_joint": -0.1, "left_knee_joint": 0.3,
                  "right_knee_joint": 0.3, "left_ankle_joint": -0.2, "right_ankle_joint": -0.2,
                  "left_elbow_joint": 0.5, "right_elbow_joint": 0.5},
    base_height=1.035,  # the ankles 0.0358 m under the base at 1.0 m (FK), the soles 0.07 m under them
    drives=tuple((pattern, JointGains(ARMATURE, kp, kd, effort)) for pattern, kp, kd, effort in _DRIVES),
    action_scale=0.25,
    posture_std=((r".*hip_pitch.*", 0.3), (r".*hip_roll.*", 0.15), (r".*hip_yaw.*", 0.15),
                 (r".*knee.*", 0.35),
                 (r".*ankle.*", 0.25), (r"torso_joint", 0.15), (r".*shoulder_pitch.*", 0.35),
                 (r".*shoulder_roll.*", 0.15), (r".*shoulder_yaw.*", 0.1), (r".*elbow.*", 0.25)),
    # the G1's wide draw without wrists (not re-derived by FK for the H1's longer arms)
    reach_ranges={"shoulder_pitch": (-2.0, 0.8), "shoulder_roll": (-0.2, 1.2), "shoulder_yaw": (-1.0, 1.0),
                  "elbow": (-0.6, 1.8)},
    fall_height=0.4,
)
"""the H1 as the locomotion stack trains it"""
