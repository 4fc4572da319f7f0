"""The robot of :mod:`stages.simulate.robot` loaded into Newton (:func:`add_robot`: drives, finger
contacts, gravity compensation) and into Pinocchio (:func:`build_pinocchio_model`), both from the one
URDF that :func:`stages.simulate.robot.write_robot_urdf` writes.
"""

from __future__ import annotations

from dataclasses import dataclass

from pipeline.types import ItemError
from stages.simulate.robot import RobotDescription


@dataclass(frozen=True, kw_only=True)
class DriveGains:
    """Joint drive gains. base: velocity gain kd of the base joints [N s/m] (velocity control);
    arm_ke [N m/rad] / arm_kd [N m s/rad] per arm joint; finger_ke [N/m], finger_kd [N s/m];
    arm_armature [kg m^2]; finger_armature [kg]: reflected inertia of the finger drives. MuJoCo's
    soft contacts yield in proportion to force over effective mass, so a 15 g finger squeezing
    with 70 N sinks centimetres into what it grasps; 1 kg (a geared drive's reflected inertia is
    of that order) keeps it to about 2 mm."""

    base_kd: float = 4000.0
    arm_ke: tuple[float, ...] = (4500.0, 4500.0, 3500.0, 3500.0, 2000.0, 2000.0, 2000.0)
    arm_kd: tuple[float, ...] = (450.0, 450.0, 350.0, 350.0, 200.0, 200.0, 200.0)
    arm_armature: float = 0.1
    finger_ke: float = 2000.0
    finger_kd: float = 100.0
    finger_armature: float = 1.0
    gravity_compensation: bool = True


@dataclass(frozen=True)
class RobotIndices:
    """Indices of one robot inside a Newton builder (world-local; add the world offsets for
    replicated models). dof: joint name -> dof index; body: link name -> body index;
    shape_start/shape_end: the robot's shapes."""

    dof: dict[str, int]
    coord: dict[str, int]
    body: dict[str, int]
    shape_start: int
    shape_end: int


def _short(label: str) -> str:
    return label.rsplit("/", 1)[-1]


def add_robot(
    builder,
    desc: RobotDescription,
    *,
    spawn_xy_yaw: tuple[float, float, float] = (0.0, 0.0, 0.0),
    gains: DriveGains | None = None,
    arm_q: tuple[float, ...] | None = None,
) -> RobotIndices:
    """Add the robot to a Newton ``ModelBuilder`` with its root at the spawn pose (x, y [m],
    yaw [rad]) and set drives: base joints velocity-controlled, arm and fingers position-controlled.

    The base joints start at 0 (the spawn frame); the arm starts at ``arm_q`` (default home)
    with the gripper open. Returns the robot's indices in ``builder``.
    """
    import warp as wp

    gains = gains or DriveGains()
    x, y, yaw = spawn_xy_yaw
    body0, shape0, joint0 = builder.body_count, builder.shape_count, builder.joint_count
    xform = wp.transform(wp.vec3(x, y, 0.0), wp.quat_from_axis_angle(wp.vec3(0.0, 0.0, 1.0), float(yaw)))
    builder.add_urdf(
        str(desc.urdf),
        xform=xform,
        floating=False,
        enable_self_collisions=False,
        joint_ordering="dfs",
        collapse_fixed_joints=False,
    )
    dof, coord, body = {}, {}, {}
    for j in range(joint0, builder.joint_count):
        name = _short(builder.joint_label[j])
        if builder.joint_dof_dim[j][0] + builder.joint_dof_dim[j][1] == 1:
            dof[name] = builder.joint_qd_start[j]
            coord[name] = builder.joint_q_start[j]
    for b in range(body0, builder.body_count):
        body[_short(builder.body_label[b])] = b
    missing = [n for n in desc.joints if n not in dof]
    if missing:
        raise ItemError(f"{desc.urdf}: joints {missing} not found after loading into Newton")
    _set_drives(builder, desc, gains, dof, coord, arm_q or desc.arm_home)
    _set_finger_contacts(builder, desc, body, shape0)
    if gains.gravity_compensation:
        _set_gravity_compensation(builder, desc, body)
    return RobotIndices(dof=dof, coord=coord, body=body, shape_start=shape0, shape_end=builder.shape_count)


def _set_drives(builder, desc: RobotDescription, gains: DriveGains, dof, coord, arm_q) -> None:
    import newton

    for name in desc.base_joints:
        d = dof[name]
        builder.joint_target_ke[d] = 0.0
        builder.joint_target_kd[d] = gains.base_kd
        builder.joint_target_mode[d] = int(newton.JointTargetMode.VELOCITY)
        builder.joint_armature[d] = 1.0
        builder.joint_target_qd[d] = 0.0
    for i, name in enumerate(desc.arm_joints):
        d = dof[name]
        builder.joint_target_ke[d] = gains.arm_ke[i]
        builder.joint_target_kd[d] = gains.arm_kd[i]
        builder.joint_target_mode[d] = int(newton.JointTargetMode.POSITION)
        builder.joint_armature[d] = gains.arm_armature
        builder.joint_q[coord[name]] = arm_q[i]
        builder.joint_target_q[coord[name]] = arm_q[i]
    g = desc.gripper
    hand = g.hand.drive if g.hand is not None else None    # a dexterous hand's own drives
    for i, (name, q0) in enumerate(zip(g.finger_joints, g.finger_targets(0.0), strict=True)):
        d = dof[name]
        builder.joint_target_ke[d] = gains.finger_ke if hand is None else hand.kp
        builder.joint_target_kd[d] = gains.finger_kd if hand is None else hand.kd
        builder.joint_target_mode[d] = int(newton.JointTargetMode.POSITION)
        builder.joint_effort_limit[d] = g.max_force if hand is None else hand.effort[i]
        builder.joint_armature[d] = gains.finger_armature if hand is None else hand.armature
        builder.joint_q[coord[name]] = q0
        builder.joint_target_q[coord[name]] = q0


def mujoco_attribute(builder, key: str):
    """The builder's MuJoCo custom attribute ``key`` (e.g. ``"mujoco:gravcomp"``), registering
    SolverMuJoCo's attributes first if needed; its ``values`` dict (entity index -> value) exists."""
    from newton.solvers import SolverMuJoCo

    if key not in builder.custom_attributes:
        SolverMuJoCo.register_custom_attributes(builder)
    attr = builder.custom_attributes[key]
    if attr.values is None:
        attr.values = {}
    return attr


def _set_finger_contacts(builder, desc: RobotDescription, body: dict[str, int], shape0: int) -> None:
    """Finger pads get torsional friction (MuJoCo ``condim`` 4, Newton's ``mu_torsional``): with
    point contacts only, an object pinched off its centre of mass (a mug by its handle) spins
    freely about the line between the pads."""
    attr = mujoco_attribute(builder, "mujoco:condim")
    fingers = set()
    for j in desc.gripper.finger_joints:
        k = next(i for i in range(builder.joint_count) if _short(builder.joint_label[i]) == j)
        fingers.add(builder.joint_child[k])
    if desc.gripper.hand is not None:   # a hand grasps with its palm too
        fingers.add(body[desc.gripper.hand_link])
    for s in range(shape0, builder.shape_count):
        if builder.shape_body[s] in fingers:
            attr.values[s] = 4
            builder.shape_material_mu_torsional[s] = 0.01


def _set_gravity_compensation(builder, desc: RobotDescription, body: dict[str, int]) -> None:
    """Mark the arm and gripper bodies as gravity-compensated (MuJoCo ``gravcomp``), like the
    Panda's own controller does; other solvers ignore it."""
    attr = mujoco_attribute(builder, "mujoco:gravcomp")
    arm_root = body.get("panda_link1")
    for b in body.values():
        if arm_root is not None and b >= arm_root:
            attr.values[b] = 1.0


def build_pinocchio_model(desc: RobotDescription):
    """The Pinocchio model of the same URDF (kinematics; root fixed to the spawn frame)."""
    import pinocchio as pin

    return pin.buildModelFromUrdf(str(desc.urdf))
