"""Typed per-step state of a simulation, read from a :class:`~stages.simulate.world.Sim`.

All poses are in the world frame (metres; quaternions (w, x, y, z), as ``asset_model.Pose``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from asset_catalog.asset_model import Pose


@dataclass(frozen=True, kw_only=True)
class BasePose:
    """The mobile base in the world: x, y [m], theta (yaw) [rad]."""

    x: float
    y: float
    theta: float


@dataclass(frozen=True, kw_only=True)
class Contact:
    """A contact between two shapes: model shape indices, their semantic labels, the world
    contact normal (3,) from shape a to shape b."""

    shape_a: int
    shape_b: int
    label_a: str
    label_b: str
    normal: tuple[float, float, float]


@dataclass(frozen=True, kw_only=True)
class RobotState:
    """joint_names (J,) in control order (base, arm, fingers); q (J,) [m or rad]; qd (J,)
    [m/s or rad/s]; ee_pose: end-effector frame; base: base pose in the world; gripper_opening:
    distance between the fingers [m]."""

    joint_names: tuple[str, ...]
    q: np.ndarray
    qd: np.ndarray
    ee_pose: Pose
    base: BasePose
    gripper_opening: float


@dataclass(frozen=True, kw_only=True)
class StepState:
    """One world at one step: time [s], step count, the robot, object poses by scene prim path
    (every free or articulated scene body), scene joint positions by prim path [m or rad], and
    contacts (empty unless requested)."""

    time: float
    step: int
    world: int
    robot: RobotState
    objects: dict[str, Pose]
    scene_joints: dict[str, float]
    contacts: tuple[Contact, ...] = ()


def _pose_from_transform(t: np.ndarray) -> Pose:
    x, y, z, qx, qy, qz, qw = (float(v) for v in t[:7])
    return Pose((x, y, z), (qw, qx, qy, qz))


def read_state(sim, world: int = 0, *, contacts: bool = False) -> StepState:
    """The typed state of ``world`` (see :class:`StepState`)."""
    desc = sim.desc
    jq = sim.state_0.joint_q.numpy()
    jqd = sim.state_0.joint_qd.numpy()
    bq = sim.state_0.body_q.numpy()
    names = desc.joints
    q = np.array([jq[sim.world_coord(n, world)] for n in names])
    qd = np.array([jqd[sim.world_dof(n, world)] for n in names])
    ee = _pose_from_transform(bq[sim.world_body(desc.ee_frame, world)])
    base_t = bq[sim.world_body("base_link", world)]
    from scipy.spatial.transform import Rotation

    theta = float(Rotation.from_quat(base_t[3:7]).as_euler("xyz")[2])
    fingers = [bq[sim.world_body(_finger_link(sim, n), world)][:3] for n in desc.gripper.finger_joints]
    robot = RobotState(
        joint_names=names,
        q=q,
        qd=qd,
        ee_pose=ee,
        base=BasePose(x=float(base_t[0]), y=float(base_t[1]), theta=theta),
        gripper_opening=float(np.linalg.norm(fingers[0] - fingers[1])),
    )
    objects = {
        p: _pose_from_transform(bq[b + world * sim.bodies_per_world]) for b, p in sim.scene.body_path.items()
    }
    qs = sim.model.joint_q_start.numpy()
    scene_joints = {
        p: float(jq[qs[j] + world * sim.coords_per_world]) for j, p in sim.scene.joint_path.items()
    }
    return StepState(
        time=sim.time,
        step=sim.steps,
        world=world,
        robot=robot,
        objects=objects,
        scene_joints=scene_joints,
        contacts=read_contacts(sim, world) if contacts else (),
    )


def _finger_link(sim, joint_name: str) -> str:
    j = sim.model.joint_label if hasattr(sim.model, "joint_label") else None
    # the child link of a finger joint: look it up once through the model's joint labels
    cache = sim.__dict__.setdefault("_finger_links", {})
    if joint_name not in cache:
        child = sim.model.joint_child.numpy()
        labels = list(j)
        k = next(i for i, lab in enumerate(labels) if lab.rsplit("/", 1)[-1] == joint_name)
        body = int(child[k])
        cache[joint_name] = next(n for n, b in sim.robot.body.items() if b == body)
    return cache[joint_name]


def read_contacts(sim, world: int = 0) -> tuple[Contact, ...]:
    """Current rigid contacts of ``world`` (shape pairs with labels and normals)."""
    import newton

    if sim.pipeline is None:
        if sim.contacts is None:
            sim.contacts = newton.Contacts(sim.solver.get_max_contact_count(), 0, device=sim.model.device)
        sim.solver.update_contacts(sim.contacts, sim.state_0)
    c = sim.contacts
    n = int(c.rigid_contact_count.numpy()[0])
    s0 = c.rigid_contact_shape0.numpy()[:n]
    s1 = c.rigid_contact_shape1.numpy()[:n]
    nrm = c.rigid_contact_normal.numpy()[:n]
    lo, hi = world * sim.shapes_per_world, (world + 1) * sim.shapes_per_world
    out = []
    for a, b, v in zip(s0, s1, nrm, strict=True):
        if not (lo <= a < hi or lo <= b < hi) or a < 0 or b < 0:
            continue
        out.append(
            Contact(
                shape_a=int(a),
                shape_b=int(b),
                label_a=str(sim.shape_label[a]),
                label_b=str(sim.shape_label[b]),
                normal=tuple(float(x) for x in v),
            )
        )
    return tuple(out)
