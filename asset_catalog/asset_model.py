"""The in-memory model of one asset between loading and USD authoring.

Every loader (OBJ, glTF/GLB, STL, PLY, URDF, MJCF) and every built-in generator produces an
``AssetModel``; the collision and annotate stages fill in colliders and mass properties; the USD
writer (``usd_schemas``) turns it into an asset package. Conventions, fixed for every producer:

- units are meters, kilograms, seconds, radians; Z is up; +X is the asset's front where it has one;
- poses are ``Pose(position (3,), orientation quaternion (w, x, y, z))``;
- link poses are in the asset's root frame at the zero joint configuration;
- mesh vertices are in their link's frame; faces are triangles with counter-clockwise winding
  seen from outside;
- ``links[0]`` is the root link; a rigid asset has one link and no joints.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import StrEnum
from pathlib import Path

import numpy as np

from asset_catalog.annotations import AssetAnnotation


@dataclass(frozen=True)
class Pose:
    """position [m] (3,), orientation unit quaternion (w, x, y, z)."""

    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    orientation: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)

    def matrix(self) -> np.ndarray:
        """4x4 homogeneous transform (column vectors: p_parent = M @ p_child)."""
        w, x, y, z = self.orientation
        r = np.array([
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ])
        m = np.eye(4)
        m[:3, :3] = r
        m[:3, 3] = self.position
        return m

    @staticmethod
    def from_matrix(m: np.ndarray) -> "Pose":
        from scipy.spatial.transform import Rotation

        x, y, z, w = Rotation.from_matrix(np.asarray(m)[:3, :3]).as_quat()
        return Pose(tuple(float(v) for v in np.asarray(m)[:3, 3]), (float(w), float(x), float(y), float(z)))


@dataclass(frozen=True, kw_only=True)
class MaterialSpec:
    """A UsdPreviewSurface material. Colors are linear RGB in [0, 1]; texture paths are absolute
    paths of the source files (the writer copies them beside the asset)."""

    name: str
    base_color: tuple[float, float, float] = (0.8, 0.8, 0.8)
    opacity: float = 1.0
    roughness: float = 0.5
    metallic: float = 0.0
    base_color_texture: Path | None = None
    normal_texture: Path | None = None
    roughness_texture: Path | None = None
    metallic_texture: Path | None = None
    occlusion_texture: Path | None = None


@dataclass(frozen=True, kw_only=True, eq=False)
class MeshPart:
    """A triangle mesh in its link's frame.

    vertices: (N, 3) float64 [m]; faces: (M, 3) int64 indices into vertices;
    normals: (N, 3) unit per-vertex normals or None; uvs: (N, 2) texture coordinates or None;
    material: key into ``AssetModel.materials`` or None.
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None = None
    uvs: np.ndarray | None = None
    material: str | None = None


@dataclass(frozen=True, kw_only=True)
class MassProperties:
    """mass [kg]; center_of_mass [m] (3,) in the link frame; diagonal inertia [kg m^2] (3,) about
    the principal axes, whose orientation in the link frame is principal_axes (w, x, y, z)."""

    mass: float
    center_of_mass: tuple[float, float, float]
    diagonal_inertia: tuple[float, float, float]
    principal_axes: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)


class ColliderApprox(StrEnum):
    HULL = "convexHull"
    DECOMPOSITION = "convexDecomposition"


@dataclass(frozen=True, kw_only=True, eq=False)
class Link:
    """A rigid body.

    visuals: render meshes; collision_source: the source's own collision meshes if it has any
    (URDF/MJCF), else None (colliders are then computed from visuals);
    colliders: convex pieces (each a closed convex MeshPart) filled in by the collision stage;
    collider_approx: how they were made; mass: filled in by the annotate stage unless the source
    gives it (``mass_from_source``); contact: contact properties the source declares for this
    link (URDF ``<contact>``), which override the asset's physics material on its colliders.
    """

    name: str
    pose: Pose = Pose()
    visuals: tuple[MeshPart, ...] = ()
    collision_source: tuple[MeshPart, ...] | None = None
    colliders: tuple[MeshPart, ...] = ()
    collider_approx: ColliderApprox | None = None
    mass: MassProperties | None = None
    mass_from_source: bool = False
    contact: ContactSpec | None = None


class JointType(StrEnum):
    REVOLUTE = "revolute"
    PRISMATIC = "prismatic"
    FIXED = "fixed"


@dataclass(frozen=True, kw_only=True)
class Joint:
    """A joint between two links.

    frame: the joint frame in the parent link's frame (the child's frame coincides with it at zero);
    axis: unit axis (3,) in the joint frame; lower/upper: limits [rad] or [m], None if unlimited;
    max_effort [N m] or [N]; max_velocity [rad/s] or [m/s]; friction: joint friction [N m] or [N];
    damping [N m s/rad] or [N s/m]; stiffness: drive stiffness [N m/rad] or [N/m] (0: no drive);
    armature: added inertia of the joint's mechanism [kg m^2] or [kg] (hinge springs, linkages).
    limit_solref: the limit stops as MuJoCo's solref (time constant [s], damping ratio), None: the
    simulator's default (Newton's force-space limit ke/kd, which leave a heavy leaf's stop nearly
    elastic); authored as ``mjc:solreflimit``.
    """

    name: str
    type: JointType
    parent: str
    child: str
    frame: Pose = Pose()
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    lower: float | None = None
    upper: float | None = None
    max_effort: float | None = None
    max_velocity: float | None = None
    friction: float = 0.0
    damping: float = 0.0
    stiffness: float = 0.0
    armature: float = 0.0
    limit_solref: tuple[float, float] | None = None


@dataclass(frozen=True, kw_only=True)
class PhysicsMaterialSpec:
    """static/dynamic friction [-], restitution [-], density [kg/m^3]; torsional and rolling
    friction [m] (torque per normal force; see ``asset_catalog.materials``; the defaults are MuJoCo's
    and Newton's)."""

    static_friction: float
    dynamic_friction: float
    restitution: float
    density: float
    torsional_friction: float = 0.005
    rolling_friction: float = 0.0001


@dataclass(frozen=True, kw_only=True)
class ContactSpec:
    """Contact properties a source declares for one link, None where it says nothing: friction
    (static and dynamic) [-], torsional_friction [m], rolling_friction [m], restitution [-]."""

    friction: float | None = None
    torsional_friction: float | None = None
    rolling_friction: float | None = None
    restitution: float | None = None

    def apply(self, pm: PhysicsMaterialSpec) -> PhysicsMaterialSpec:
        """``pm`` with the values this spec declares."""
        out = pm
        if self.friction is not None:
            out = replace(out, static_friction=self.friction, dynamic_friction=self.friction)
        for name in ("torsional_friction", "rolling_friction", "restitution"):
            if getattr(self, name) is not None:
                out = replace(out, **{name: getattr(self, name)})
        return out


@dataclass(frozen=True, kw_only=True, eq=False)
class AssetModel:
    name: str
    annotation: AssetAnnotation
    links: tuple[Link, ...]
    joints: tuple[Joint, ...] = ()
    materials: dict[str, MaterialSpec] = field(default_factory=dict)
    fixed_base: bool = False
    physics_material: PhysicsMaterialSpec | None = None
    source_sha256: str = ""

    @property
    def is_articulated(self) -> bool:
        return len(self.joints) > 0

    def link(self, name: str) -> Link:
        for lk in self.links:
            if lk.name == name:
                return lk
        raise KeyError(name)

    def replace_links(self, links: tuple[Link, ...]) -> "AssetModel":
        return replace(self, links=links)
