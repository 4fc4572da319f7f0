"""A spec's drives applied to its robot inside a Newton ``ModelBuilder``.

:func:`apply_drives` sets, for every 1-DoF joint of the robot whose name a drive entry matches:
the target mode (position / velocity / none), ``kp`` and ``kd``, the armature and effort limit
where the entry gives them (an end-effector joint: its ``max_force``; else the description's stay), the start position and position target
from the spec's default pose (end effectors open), and MuJoCo's ``gravcomp`` on the bodies those
joints move where the entry asks for gravity compensation (as stages/simulate/robot.py does for
the Panda; other solvers ignore it). Newton is imported lazily.
"""

from __future__ import annotations

from dataclasses import dataclass

from stages.embodiment.spec import DriveMode, EmbodimentError, EmbodimentSpec


@dataclass(frozen=True)
class RobotJoints:
    """Where the robot's joints are in the builder: name -> dof index and coordinate index."""

    dof: dict[str, int]
    coord: dict[str, int]


def _short(label: str) -> str:
    return label.rsplit("/", 1)[-1]


def default_positions(spec: EmbodimentSpec) -> dict[str, float]:
    """Joint name -> start position: the default pose, end effectors open."""
    out = dict(spec.default_pose)
    for arm in spec.arms:
        if arm.end_effector:
            ee = spec.end_effectors[arm.end_effector]
            out.update(zip(ee.joints, ee.open, strict=True))
    return out


def apply_drives(builder, spec: EmbodimentSpec, *, joint_start: int = 0, joint_end: int | None = None) -> RobotJoints:
    """Apply ``spec``'s drives to the joints ``joint_start:joint_end`` of ``builder`` (the robot,
    just added). Raises EmbodimentError if a 1-DoF joint there has no drive entry."""
    import newton

    end = builder.joint_count if joint_end is None else joint_end
    dof, coord, undriven = {}, {}, []
    start_q = default_positions(spec)
    ee_force = {j: ee.max_force for a in spec.arms if a.end_effector
                for ee in (spec.end_effectors[a.end_effector],) for j in ee.joints if ee.max_force is not None}
    gravcomp_bodies = []
    for j in range(joint_start, end):
        if builder.joint_type[j] not in (newton.JointType.REVOLUTE, newton.JointType.PRISMATIC):
            continue
        name = _short(builder.joint_label[j])
        d, c = builder.joint_qd_start[j], builder.joint_q_start[j]
        dof[name], coord[name] = d, c
        drive = spec.drive_for(name)
        if drive is None:
            undriven.append(name)
            continue
        mode = {DriveMode.POSITION: newton.JointTargetMode.POSITION,
                DriveMode.VELOCITY: newton.JointTargetMode.VELOCITY,
                DriveMode.NONE: newton.JointTargetMode.NONE}[drive.mode]
        builder.joint_target_mode[d] = int(mode)
        builder.joint_target_ke[d] = drive.kp
        builder.joint_target_kd[d] = drive.kd
        if drive.armature is not None:
            builder.joint_armature[d] = drive.armature
        if drive.effort_limit is not None or name in ee_force:
            builder.joint_effort_limit[d] = drive.effort_limit or ee_force[name]
        if name in start_q:
            builder.joint_q[c] = start_q[name]
            builder.joint_target_q[c] = start_q[name]
        if drive.gravity_compensation:
            gravcomp_bodies.append(builder.joint_child[j])
    if undriven:
        raise EmbodimentError(f"{spec.name}: no drive matches joints {undriven}")
    if gravcomp_bodies:
        _gravity_compensation(builder, gravcomp_bodies)
    return RobotJoints(dof=dof, coord=coord)


def _gravity_compensation(builder, bodies: list[int]) -> None:
    """MuJoCo ``gravcomp`` 1 on ``bodies`` and every body rigidly welded below them."""
    import newton

    from stages.simulate.robot_load import mujoco_attribute

    attr = mujoco_attribute(builder, "mujoco:gravcomp")
    fixed: dict[int, list[int]] = {}
    for j in range(builder.joint_count):
        if builder.joint_type[j] == newton.JointType.FIXED:
            fixed.setdefault(builder.joint_parent[j], []).append(builder.joint_child[j])
    stack = list(bodies)
    while stack:
        b = stack.pop()
        attr.values[b] = 1.0
        stack.extend(fixed.get(b, []))
