"""Hands and objects of the humanoid engine (``stages.engine.humanoid``): the collision boxes of a
hand's links (a spec whose end effectors are hands, e.g. the G1's Dex3), the free objects' poses
and the task predicates' view of a world (objects, the hand that grasps, scene joints).

Hand colliders: the humanoid as trained has no collision shapes but its soles; a hand end effector
gets one box per link of the hand (its mount link and every link a hand joint moves): the URDF's
collision box, or the axis-aligned bounds of its collision mesh in the link frame. The boxes are
massless (the links keep the description's inertials, which the arms' gravity feed-forward
assumes), have friction ``mu``, and do not collide with each other. Frame: world, Z up, metres.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from asset_catalog.asset_model import Pose


def _rpy(rpy: list[float]) -> np.ndarray:
    r, p, y = rpy
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    return rz @ ry @ rx


def _origin(el: ET.Element | None) -> np.ndarray:
    m = np.eye(4)
    if el is not None:
        m[:3, 3] = [float(v) for v in el.get("xyz", "0 0 0").split()]
        m[:3, :3] = _rpy([float(v) for v in el.get("rpy", "0 0 0").split()])
    return m


def hand_link_boxes(urdf: Path, root: Path, links: list[str]
                    ) -> dict[str, list[tuple[np.ndarray, np.ndarray]]]:
    """Per link of ``links``: its collision boxes as (centre (3,), half extents (3,)) [m] in the
    link frame, from the URDF ``urdf`` (mesh paths ``package://<pkg>/...`` resolve under ``root``,
    the description's data root). ValueError naming the file for a link without collision
    geometry or with a shape other than a box or a mesh."""
    import trimesh

    doc = ET.parse(urdf).getroot()
    by_name = {link.get("name"): link for link in doc.iter("link")}
    out: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
    for name in links:
        link = by_name.get(name)
        cols = link.findall("collision") if link is not None else []
        if not cols:
            raise ValueError(f"{urdf}: link {name!r} has no collision geometry")
        boxes = []
        for col in cols:
            org, geom = _origin(col.find("origin")), col.find("geometry")
            box, mesh = geom.find("box"), geom.find("mesh")
            if box is not None:
                h = np.array([float(v) for v in box.get("size").split()]) / 2
                pts = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
            elif mesh is not None:
                rel = mesh.get("filename").split("://", 1)[-1].split("/", 1)[-1]
                pts = np.asarray(trimesh.load(root / rel, force="mesh").vertices) * [
                    float(v) for v in mesh.get("scale", "1 1 1").split()]
            else:
                raise ValueError(f"{urdf}: link {name!r}: collision shape is neither a box nor a mesh")
            p = pts @ org[:3, :3].T + org[:3, 3]
            lo, hi = p.min(axis=0), p.max(axis=0)
            boxes.append(((lo + hi) / 2, (hi - lo) / 2))
        out[name] = boxes
    return out


def _fixed_parents(urdf: Path) -> dict[str, tuple[str, np.ndarray]]:
    """child link -> (parent link, child frame in the parent (4, 4)) of the URDF's fixed joints."""
    doc = ET.parse(urdf).getroot()
    return {j.find("child").get("link"): (j.find("parent").get("link"), _origin(j.find("origin")))
            for j in doc.iter("joint") if j.get("type") == "fixed"}


def add_hand_colliders(robot: Any, spec: Any, *, mu: float = 1.0) -> list[int]:
    """The collision boxes of every hand end effector of ``spec`` on ``robot`` (a Newton builder
    holding one humanoid; links merged into their parents by collapsed fixed joints are found
    through those joints); returns the shape indices. See the module docstring."""
    import dataclasses

    import warp as wp

    from stages.embodiment.sources import resolve_description
    from stages.embodiment.spec import EndEffectorKind

    desc = resolve_description(spec.description)
    fixed = _fixed_parents(desc.path)
    bodies = [label.rsplit("/", 1)[-1] for label in robot.body_label]
    doc = ET.parse(desc.path).getroot()
    joint_child = {j.get("name"): j.find("child").get("link") for j in doc.iter("joint")}
    cfg = dataclasses.replace(robot.default_shape_cfg, density=0.0, mu=mu)
    out: list[int] = []
    for ee in spec.end_effectors.values():
        if ee.kind != EndEffectorKind.HAND:
            continue
        links = [ee.mount_link] + [joint_child[j] for j in ee.joints]
        shapes = []
        for link, boxes in hand_link_boxes(desc.path, desc.root, links).items():
            body, off = link, np.eye(4)
            while body not in bodies:
                if body not in fixed:
                    raise ValueError(f"{desc.path}: hand link {link!r} is not a body of the simulated robot")
                body, m = fixed[body]
                off = m @ off
            for centre, half in boxes:
                c = off[:3, :3] @ centre + off[:3, 3]
                q = _quat_xyzw(off[:3, :3])
                xf = wp.transform(tuple(c), wp.quat(*q))
                shapes.append(robot.add_shape_box(bodies.index(body), xform=xf,
                                                  hx=float(half[0]), hy=float(half[1]), hz=float(half[2]),
                                                  cfg=cfg))
        for i, a in enumerate(shapes):
            for b in shapes[i + 1:]:
                robot.add_shape_collision_filter_pair(a, b)
        out += shapes
    return out


def _quat_xyzw(r: np.ndarray) -> tuple[float, float, float, float]:
    from scipy.spatial.transform import Rotation

    return tuple(float(v) for v in Rotation.from_matrix(r).as_quat())


@dataclass(frozen=True)
class HandRobot:
    """The predicates' view of the robot: the pose of the hand that grasps (world frame) and its
    opening [m]: 0.08 open, 0 closed (``_released`` asks > 0.06: the hand's command below 0.25)."""

    ee_pose: Pose
    gripper_opening: float


@dataclass(frozen=True)
class HumanoidPredicateState:
    """What a task predicate reads of one world: ``objects`` (free body prim path -> Pose),
    ``robot`` (:class:`HandRobot`), ``scene_joints`` (prim path -> value [m or rad])."""

    objects: Any
    robot: HandRobot | None
    scene_joints: Any


def pose_of(body_q: np.ndarray) -> Pose:
    """A Newton body transform (7,) (position, quaternion x, y, z, w) as a Pose (w, x, y, z)."""
    p, q = body_q[:3], body_q[3:7]
    return Pose(position=tuple(float(v) for v in p),
                orientation=(float(q[3]), float(q[0]), float(q[1]), float(q[2])))
