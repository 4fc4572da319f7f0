"""Articulated parts of default-catalog assets placed in a scene, and their success predicates.

Public surface (signatures are stable; the task world imports them)::

    frames = package_joint_frames(package_usd)            # {joint name: JointFrame}, asset root frame
    parts = parts_of(record, asset_id="microwave_00", prim_root="/World/Objects/microwave_0",
                     pose=(x, y, z, yaw), joint_frames=frames)             # tuple[ArticulatedPart, ...]
    parts = parts_of_package(record, asset_id=..., prim_root=..., pose=..., package_usd=...)
    part.handle_at(q), part.front_at(q), part.rotation_at(q)   # handle (3,), front normal (3,), (3, 3)
    part_opened(part, state, fraction=0.75) -> (ok, reason); part_closed(part, state, tol=None)

``record`` is one asset's entry of the default catalog's ``generated.json`` (category, joints:
name -> role, handles: link, kind, center, grip_width, clearance, bar_axis in the asset root frame
at the zero configuration). The joint axis, its anchor and limits come from the ingested package's
UsdPhysics joints (``/<id>/joints/<name>``: ``physics:axis`` in the joint frame, ``localRot0`` /
``localPos0`` in body0, limits in degrees for revolute joints), which ingest writes from the URDF.
A package referenced at ``prim_root`` (translate (x, y, z) then yaw about +Z, as
``stages.scene.compose`` places instances) has its joints at ``<prim_root>/joints/<name>`` in the
composed scene; Newton exposes them under those prim paths (``sim.scene.joint_path``,
``read_state(sim).scene_joints``). The experts that open and close them are
:mod:`stages.demos.articulated`.

Conventions (catalog generators): the asset root frame has +X to the front; doors open with
positive angles (towards +X), drawers slide along +X; the closed configuration is joint value 0.
Frame of :class:`ArticulatedPart`: world, Z up, metres, radians.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.types import ItemError

ROLES = ("door", "drawer")
_KINDS = {"PhysicsRevoluteJoint": "revolute", "PhysicsPrismaticJoint": "prismatic"}
_AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}


@dataclass(frozen=True, kw_only=True)
class JointFrame:
    """One joint of a package in its asset root frame. name: joint prim name; link: the moving
    link (body1's prim name); kind: "revolute" | "prismatic"; axis (3,) unit (positive motion
    opens); origin (3,) point on the axis [m]; lower / upper limits [rad or m]."""

    name: str
    link: str
    kind: str
    axis: tuple[float, float, float]
    origin: tuple[float, float, float]
    lower: float
    upper: float


@dataclass(frozen=True, kw_only=True)
class ArticulatedPart:
    """A door or drawer of a placed asset, world frame (metres, radians).

    asset_id; category (catalog category); role: "door" | "drawer"; joint_path: USD prim path of
    the joint in the composed scene; link: moving link name; kind: "revolute" | "prismatic";
    axis (3,) unit: positive joint motion opens; origin (3,): point on the axis; lower / upper:
    joint limits [rad or m]; closed: joint value when closed; handle (3,): grasp centre of the bar
    at the closed configuration; bar_axis (3,) unit: the bar's long axis at closed; grip_width:
    bar diameter [m]; clearance: free space between bar and panel [m]; front (3,): the asset's
    +X (outward normal of the closed front) in the world; handle_kind: "bar" |
    "lever"; back_handle (3,) or None: a second handle on the other face (room doors)."""

    asset_id: str
    category: str
    role: str
    joint_path: str
    link: str
    kind: str
    axis: tuple[float, float, float]
    origin: tuple[float, float, float]
    lower: float
    upper: float
    closed: float
    handle: tuple[float, float, float]
    bar_axis: tuple[float, float, float]
    grip_width: float
    clearance: float
    front: tuple[float, float, float] = (1.0, 0.0, 0.0)
    handle_kind: str = "bar"
    back_handle: tuple[float, float, float] | None = None

    @property
    def travel(self) -> float:
        """Opening range from closed to the upper limit [rad or m]."""
        return self.upper - self.closed

    def rotation_at(self, q: float) -> np.ndarray:
        """(3, 3) rotation of the moving link at joint value ``q`` relative to closed (identity for
        prismatic joints)."""
        if self.kind == "prismatic":
            return np.eye(3)
        return axis_angle(np.asarray(self.axis), q - self.closed)

    def point_at(self, p_closed, q: float) -> np.ndarray:
        """Where a point ``p_closed`` (3,) [m] of the moving link is at joint value ``q``."""
        p = np.asarray(p_closed, float)
        if self.kind == "prismatic":
            return p + (q - self.closed) * np.asarray(self.axis)
        o = np.asarray(self.origin)
        return o + self.rotation_at(q) @ (p - o)

    def handle_at(self, q: float) -> np.ndarray:
        """Handle centre (3,) [m] at joint value ``q``."""
        return self.point_at(self.handle, q)

    def front_at(self, q: float) -> np.ndarray:
        """Outward normal (3,) of the part's front face (the handle side) at joint value ``q``:
        the asset's +X turned with the link (the oven door tilts it down)."""
        return self.rotation_at(q) @ np.asarray(self.front, float)


def axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    a = axis / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * (k @ k)


def _yaw_pose(pose: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """(R (3, 3), t (3,)) of a placement (x, y, z, yaw)."""
    x, y, z, yaw = (float(v) for v in pose)
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), np.array([x, y, z])


def package_joint_frames(package_usd: Path) -> dict[str, JointFrame]:
    """Revolute and prismatic joints of an ingested package, in its asset root frame.

    Reads the UsdPhysics joints: axis = R(body0 in root) R(localRot0) e_axis, origin = body0 in
    root applied to localPos0; revolute limits converted from degrees to radians."""
    from pxr import Gf, Usd, UsdGeom, UsdPhysics

    package_usd = Path(package_usd)
    stage = Usd.Stage.Open(str(package_usd))
    if stage is None:
        raise ItemError(f"{package_usd}: cannot open the package")
    root = stage.GetDefaultPrim()
    if not root:
        raise ItemError(f"{package_usd}: no default prim")
    xc = UsdGeom.XformCache()
    root_inv = xc.GetLocalToWorldTransform(root).GetInverse()
    out: dict[str, JointFrame] = {}
    for prim in stage.Traverse():
        kind = _KINDS.get(prim.GetTypeName())
        if kind is None:
            continue
        j = UsdPhysics.Joint(prim)
        b0, b1 = j.GetBody0Rel().GetTargets(), j.GetBody1Rel().GetTargets()
        if not b1:
            raise ItemError(f"{package_usd}: joint {prim.GetPath()} has no body1")
        m0 = Gf.Matrix4d(1.0)
        if b0:
            m0 = xc.GetLocalToWorldTransform(stage.GetPrimAtPath(b0[0])) * root_inv
        axis_tok = prim.GetAttribute("physics:axis").Get() or "X"
        rot0 = Gf.Rotation(Gf.Quatd(j.GetLocalRot0Attr().Get() or Gf.Quatf(1, 0, 0, 0)))
        ax_body = rot0.TransformDir(Gf.Vec3d(*_AXES[str(axis_tok)]))
        ax = np.asarray(m0.TransformDir(ax_body), float)
        org = np.asarray(m0.Transform(Gf.Vec3d(j.GetLocalPos0Attr().Get() or Gf.Vec3f(0, 0, 0))), float)
        lo = prim.GetAttribute("physics:lowerLimit").Get()
        hi = prim.GetAttribute("physics:upperLimit").Get()
        scale = math.pi / 180.0 if kind == "revolute" else 1.0
        out[prim.GetName()] = JointFrame(
            name=prim.GetName(), link=b1[0].name, kind=kind,
            axis=tuple(float(v) for v in ax / np.linalg.norm(ax)), origin=tuple(float(v) for v in org),
            lower=float(lo if lo is not None else 0.0) * scale,
            upper=float(hi if hi is not None else 0.0) * scale)
    return out


def _world(r: np.ndarray, t: np.ndarray, p) -> tuple[float, float, float]:
    return tuple(float(v) for v in r @ np.asarray(p, float) + t)


def _dir(r: np.ndarray, v) -> tuple[float, float, float]:
    w = r @ np.asarray(v, float)
    return tuple(float(x) for x in w / np.linalg.norm(w))


def parts_of(record: Mapping, *, asset_id: str, prim_root: str, pose: Sequence[float],
             joint_frames: Mapping[str, JointFrame],
             roles: Sequence[str] = ROLES) -> tuple[ArticulatedPart, ...]:
    """The doors and drawers (``roles``) of one placed asset, in the world frame.

    record: the asset's ``generated.json`` entry; prim_root: the referencing prim in the scene
    (e.g. ``/World/Objects/fridge_0``); pose: (x, y, z, yaw) [m, rad] of that prim;
    joint_frames: :func:`package_joint_frames` of its package. Parts come in the record's joint
    order; a part whose link has no handle raises ItemError."""
    r, t = _yaw_pose(pose)
    category = str(record.get("category", ""))
    handles = list(record.get("handles", ()))
    parts = []
    for name, role in dict(record.get("joints", {})).items():
        if role not in roles:
            continue
        jf = joint_frames.get(name)
        if jf is None:
            raise ItemError(f"{asset_id}: joint {name!r} of generated.json is not in the package "
                            f"(has {sorted(joint_frames)})")
        hs = [h for h in handles if h.get("link") == jf.link and h.get("kind") in ("bar", "lever")]
        if not hs:
            raise ItemError(f"{asset_id}: no bar or lever handle on link {jf.link!r} of joint {name!r}")
        hs.sort(key=lambda h: -float(h["center"][0]))  # front face (+X) first
        h = hs[0]
        back = _world(r, t, hs[1]["center"]) if len(hs) > 1 and hs[1]["center"][0] < 0 else None
        parts.append(ArticulatedPart(
            asset_id=asset_id, category=category, role=str(role), joint_path=f"{prim_root}/joints/{name}",
            link=jf.link, kind=jf.kind, axis=_dir(r, jf.axis), origin=_world(r, t, jf.origin),
            lower=jf.lower, upper=jf.upper, closed=0.0, handle=_world(r, t, h["center"]),
            bar_axis=_dir(r, h["bar_axis"]), grip_width=float(h["grip_width"]),
            clearance=float(h["clearance"]), front=_dir(r, (1.0, 0.0, 0.0)), handle_kind=str(h["kind"]),
            back_handle=back))
    return tuple(parts)


def parts_of_package(record: Mapping, *, asset_id: str, prim_root: str, pose: Sequence[float],
                     package_usd: Path, roles: Sequence[str] = ROLES) -> tuple[ArticulatedPart, ...]:
    """:func:`parts_of` with the joint frames read from ``package_usd`` (``<id>/<id>.usda``)."""
    return parts_of(record, asset_id=asset_id, prim_root=prim_root, pose=pose,
                    joint_frames=package_joint_frames(package_usd), roles=roles)


def load_generated_info(path: Path) -> dict[str, dict]:
    """The default catalog's ``generated.json`` (asset id -> record)."""
    import json

    path = Path(path)
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise ItemError(f"{path}: cannot read generated.json ({e})") from None


# --------------------------------------------------------------------------------------------
# Success predicates
# --------------------------------------------------------------------------------------------

def joint_value(part: ArticulatedPart, state) -> float:
    """The part's joint value [rad or m] in a :class:`~stages.simulate.state.StepState`."""
    try:
        return float(state.scene_joints[part.joint_path])
    except KeyError:
        raise ItemError(f"joint {part.joint_path} is not in the simulated scene") from None


def part_opened(part: ArticulatedPart, state, fraction: float = 0.75) -> tuple[bool, str]:
    """Open: the joint is past ``fraction`` of its travel from closed."""
    q = joint_value(part, state)
    ok = q - part.closed >= fraction * part.travel
    return (True, "") if ok else (False, f"{part.role}_not_open")


def part_closed(part: ArticulatedPart, state, tol: float | None = None) -> tuple[bool, str]:
    """Closed: within ``tol`` of closed (default 5 deg for doors, 2 cm for drawers)."""
    if tol is None:
        tol = math.radians(5.0) if part.kind == "revolute" else 0.02
    q = joint_value(part, state)
    return (True, "") if q - part.closed <= tol else (False, f"{part.role}_not_closed")
