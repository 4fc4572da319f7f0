"""AssetBuilder: compose solids per link, add joints, and finish into an ``AssetModel``.

Geometry is given in the asset's root frame (Z up, +X front, origin at the floor/support centre);
the builder moves each link's geometry into its link frame (link frames are translated, never
rotated, from the root frame). Masses come from per-solid densities [kg/m^3], optionally scaled to
a target total mass [kg] (for hollow or upholstered things where density x volume is wrong).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from manifold3d import Manifold

from asset_catalog.annotations import AssetAnnotation, ColliderKind, PlacementKind, RoomType
from asset_catalog.asset_model import (
    AssetModel, Joint, JointType, Link, MassProperties, MaterialSpec, MeshPart, Pose)
import asset_catalog.generators._geom as _geom
from asset_catalog.generators._mesh import box_uvs, corner_normals, manifold_arrays, split_corners
from asset_catalog.materials import MaterialClass


@dataclass(frozen=True)
class HandleInfo:
    """A graspable handle: ``center`` (3,) [m] in the root frame at the zero configuration,
    ``grip_width`` [m] = thickness the gripper fingers close on, ``clearance`` [m] = free gap behind
    the grip (towards the surface it is mounted on), ``bar_axis`` (3,) unit direction of the bar."""

    link: str
    center: tuple[float, float, float]
    grip_width: float
    clearance: float
    bar_axis: tuple[float, float, float]
    kind: str = "bar"


@dataclass(frozen=True)
class SurfaceInfo:
    """A horizontal support surface (table top, shelf, seat, fridge shelf): height ``z`` [m] and the
    rectangle ``lo`` (x, y) .. ``hi`` (x, y) [m] in the root frame at the zero configuration; ``inside``
    when it lies in an enclosure (cabinet shelf, fridge, microwave), where the clear height above is
    ``clear_height`` [m]."""

    link: str
    z: float
    lo: tuple[float, float]
    hi: tuple[float, float]
    inside: bool = False
    clear_height: float = 0.0


@dataclass(frozen=True)
class JointInfo:
    """What a joint is for: role in {door, drawer, button, knob, lid}."""

    name: str
    role: str


@dataclass(frozen=True, eq=False)
class GeneratedAsset:
    """One generated asset: the in-memory model, the source format it is written as, and facts the
    files cannot carry (handles, joint roles, sampled parameters)."""

    model: AssetModel
    source_kind: Literal["obj", "urdf"]
    handles: tuple[HandleInfo, ...]
    joints: tuple[JointInfo, ...]
    params: dict[str, float]
    link_solids: dict[str, Manifold] = field(repr=False)
    surfaces: tuple[SurfaceInfo, ...] = ()

    @property
    def annotation(self) -> AssetAnnotation:
        return self.model.annotation


@dataclass
class _Solid:
    shape: Manifold
    material: str
    collision: list[Manifold] | None
    density: float


@dataclass
class _LinkDraft:
    name: str
    origin: np.ndarray
    solids: list[_Solid] = field(default_factory=list)


@dataclass
class _JointDraft:
    name: str
    type: JointType
    parent: str
    child: str
    axis: tuple[float, float, float]
    lower: float
    upper: float
    effort: float
    velocity: float
    damping: float
    friction: float
    role: str
    counterbalance: tuple[float, float] | None = None
    armature: float = 0.0
    spring: float = 0.0


class AssetBuilder:
    """Collects materials, links, solids, joints and handles of one asset (root link "base")."""

    def __init__(self, rng: np.random.Generator, overrides: dict[str, float] | None = None):
        self.rng = rng
        self.overrides = dict(overrides or {})
        self.materials: dict[str, MaterialSpec] = {}
        self.links: dict[str, _LinkDraft] = {"base": _LinkDraft("base", np.zeros(3))}
        self.joints: list[_JointDraft] = []
        self.handles: list[HandleInfo] = []
        self.surfaces: list[SurfaceInfo] = []
        self.params: dict[str, float] = {}

    # --- declarations -------------------------------------------------------------------------
    def param(self, name: str, lo: float, hi: float) -> float:
        """Sample a parameter uniformly in [lo, hi] and record it; an override by name replaces the sample
        (the generator still draws, so the other parameters do not change)."""
        v = float(self.rng.uniform(lo, hi))
        if name in self.overrides:
            v = float(self.overrides[name])
        self.params[name] = round(v, 6)
        return v

    def choice(self, name: str, options: list):
        i = int(self.rng.integers(len(options)))
        self.params[name] = float(i)   # the index of the option chosen
        return options[i]

    def material(self, name: str, color, roughness: float = 0.5, metallic: float = 0.0) -> str:
        c = tuple(float(np.clip(x, 0.0, 1.0)) for x in color)
        self.materials[name] = MaterialSpec(name=name, base_color=c, roughness=float(roughness),
                                            metallic=float(metallic))
        return name

    def link(self, name: str, *, parent: str, origin, joint: Literal["revolute", "prismatic"], axis,
             lower: float, upper: float, effort: float, velocity: float, damping: float = 0.0,
             friction: float = 0.0, role: str = "", counterbalance: tuple[float, float] | None = None,
             armature: float = 0.0, spring: float = 0.0) -> str:
        """Declare a moving link whose joint frame sits at ``origin`` (3,) [m] (root frame) with
        ``axis`` (3,) in the root frame; limits [rad] or [m]. ``counterbalance`` = (spring, hold)
        for a leaf hinged on a horizontal axis (an oven door): a hinge spring towards zero of
        stiffness ``spring * m g r`` [N m/rad] and joint friction ``hold * m g r`` [N m] (replacing
        ``friction``), m g r being the leaf's largest gravity torque about the axis, computed once
        the link's mass is known. ``armature``: the mechanism's added inertia [kg m^2] or [kg].
        ``spring``: a return spring towards zero [N m/rad] or [N/m] (a push button that gravity
        would otherwise hold pressed)."""
        if name in self.links:
            raise ValueError(f"duplicate link {name!r}")
        self.links[name] = _LinkDraft(name, np.asarray(origin, dtype=np.float64))
        ax = np.asarray(axis, dtype=np.float64)
        ax = ax / np.linalg.norm(ax)
        self.joints.append(_JointDraft(f"{name}_joint", JointType(joint), parent, name,
                                       tuple(float(a) for a in ax), float(lower), float(upper),
                                       float(effort), float(velocity), float(damping), float(friction), role,
                                       counterbalance, float(armature), float(spring)))
        return name

    def add(self, link: str, shape: Manifold, material: str, *, density: float,
            collision: Literal["self", "none"] | list[Manifold] = "self") -> None:
        """Add a watertight solid to ``link`` (root-frame coordinates). ``collision``: "self" (the
        solid is convex: use it), "none" (visual only), or a list of convex pieces."""
        if material not in self.materials:
            raise KeyError(f"unknown material {material!r}")
        if shape.is_empty():
            raise ValueError(f"empty solid added to link {link!r}")
        col = [shape] if collision == "self" else [] if collision == "none" else list(collision)
        self.links[link].solids.append(_Solid(shape, material, col, float(density)))

    def handle(self, link: str, center, grip_width: float, clearance: float, bar_axis,
               kind: str = "bar") -> None:
        """Record a graspable feature (kind: bar, lever, knob, loop, rim)."""
        self.handles.append(HandleInfo(link, tuple(float(c) for c in center), float(grip_width),
                                       float(clearance), tuple(float(a) for a in bar_axis), kind))

    def surface(self, z: float, lo, hi, *, link: str = "base", inside: bool = False,
                clear_height: float = 0.0) -> None:
        """Record a horizontal support surface at height z [m] over the rectangle lo..hi (x, y) [m]."""
        self.surfaces.append(SurfaceInfo(link, float(z), (float(lo[0]), float(lo[1])), (float(hi[0]), float(hi[1])),
                                         inside, float(clear_height)))

    # --- finishing ----------------------------------------------------------------------------
    def build(self, *, asset_id: str, category: str, source: str, room_types: tuple[RoomType, ...],
              placement: PlacementKind, material: MaterialClass, interactable: bool,
              co_occurrence: tuple[str, ...], fixed_base: bool, target_mass: float | None = None,
              rigid_format: Literal["obj", "urdf"] = "urdf") -> GeneratedAsset:
        """Finish the asset. ``rigid_format="obj"`` (single link only) means the asset is near-convex
        and is written as an OBJ whose collider is its convex hull."""
        masses = {name: _mass(lk) for name, lk in self.links.items()}
        scales = _mass_scales({k: m[0] for k, m in masses.items()}, target_mass)
        total = sum(m[0] * scales[k] for k, m in masses.items())
        links, solids_by_link = [], {}
        for name, lk in self.links.items():
            union = _geom.union([s.shape for s in lk.solids])
            solids_by_link[name] = union.translate(tuple(-lk.origin))
            mass, com, inertia = masses[name]
            scale = scales[name]
            links.append(Link(
                name=name, pose=Pose(tuple(float(x) for x in lk.origin)),
                visuals=_visuals(lk, name),
                collision_source=None if rigid_format == "obj" else _collision(lk, name),
                mass=_mass_props(mass * scale, com - lk.origin, inertia * scale),
                mass_from_source=rigid_format == "urdf"))
        joints = tuple(_joint(j, self.links, masses[j.child][0] * scales[j.child], masses[j.child][1])
                       for j in self.joints)
        kind = "obj" if rigid_format == "obj" and not joints else "urdf"
        is_rigid = not joints
        ann = AssetAnnotation(
            id=asset_id, source=source, category=category, room_types=room_types, placement=placement,
            material=material, interactable=interactable, co_occurrence=co_occurrence,
            mass=float(f"{total:.6g}") if is_rigid else None,
            collider=ColliderKind.HULL if kind == "obj" else ColliderKind.AUTO,
            fixed_base=fixed_base if joints else None)
        model = AssetModel(name=asset_id, annotation=ann, links=tuple(links), joints=joints,
                           materials=dict(self.materials), fixed_base=fixed_base)
        return GeneratedAsset(model=model, source_kind=kind, handles=tuple(self.handles), surfaces=tuple(self.surfaces),
                              joints=tuple(JointInfo(j.name, j.role) for j in self.joints),
                              params=dict(self.params), link_solids=solids_by_link)


def _mass_scales(masses: dict[str, float], target: float | None) -> dict[str, float]:
    """Per-link mass factors that bring the total to ``target`` [kg]: links holding at least 5 % of the
    density x volume mass are scaled; small parts (buttons, knobs) keep their density x volume mass."""
    if not target:
        return {k: 1.0 for k in masses}
    total = sum(masses.values())
    big = {k for k, m in masses.items() if m >= 0.05 * total}
    small = total - sum(masses[k] for k in big)
    f = max(target - small, 0.5 * target) / max(total - small, 1e-12)
    return {k: (f if k in big else 1.0) for k in masses}


def _visuals(lk: _LinkDraft, link_name: str) -> tuple[MeshPart, ...]:
    solids = [s.shape.as_original() for s in lk.solids]
    mat_of_id = {s.original_id(): lk.solids[i].material for i, s in enumerate(solids)}
    union = _geom.union(solids).translate(tuple(-lk.origin))
    verts, faces, ids = manifold_arrays(union)
    normals = corner_normals(verts, faces)
    uvs = box_uvs(verts, faces)
    mats = np.array([mat_of_id.get(int(i), lk.solids[0].material) for i in ids], dtype=object)
    parts = []
    for mat in sorted(set(mats.tolist())):
        sel = mats == mat
        v, f, n, uv = split_corners(verts, faces[sel], normals[sel], uvs[sel])
        parts.append(MeshPart(name=f"{link_name}__{mat}", vertices=v, faces=f, normals=n, uvs=uv,
                              material=mat))
    return tuple(parts)


MAX_COLLISION_PIECES = 24     # per link; the collision stage's max_pieces default
_PIECE_SHRINK = 1e-4          # [m] each convex piece shrinks by this per side about its centre


def _collision(lk: _LinkDraft, link_name: str) -> tuple[MeshPart, ...]:
    """The link's convex collision pieces. Each is shrunk by 0.1 mm about its centre so that touching
    pieces share no vertex: a consumer that welds and splits the link's collision meshes into connected
    pieces gets back exactly these convex pieces."""
    parts = []
    for s in lk.solids:
        for piece in s.collision or []:
            h = piece.hull().translate(tuple(-lk.origin))
            lo, hi = np.array(h.bounding_box()[:3]), np.array(h.bounding_box()[3:])
            c = (lo + hi) / 2
            ext = np.maximum(hi - lo, 4 * _PIECE_SHRINK)
            h = h.translate(tuple(-c)).scale(tuple(1 - 2 * _PIECE_SHRINK / ext)).translate(tuple(c))
            v, f, _ = manifold_arrays(h)
            parts.append(MeshPart(name=f"{link_name}__col{len(parts):02d}", vertices=v, faces=f))
    if len(parts) > MAX_COLLISION_PIECES:
        raise ValueError(f"link {link_name!r} has {len(parts)} collision pieces (at most {MAX_COLLISION_PIECES})")
    return tuple(parts)


def _mass(lk: _LinkDraft) -> tuple[float, np.ndarray, np.ndarray]:
    """Mass [kg], centre of mass (3,) [m] (root frame) and inertia tensor (3, 3) [kg m^2] about it."""
    ms, coms, covs = [], [], []
    for s in lk.solids:
        v, f, _ = manifold_arrays(s.shape)
        vol, com, cov = _solid_moments(v, f)
        ms.append(vol * s.density)
        coms.append(com)
        covs.append(cov * s.density)
    m = float(sum(ms))
    com = sum(mi * ci for mi, ci in zip(ms, coms, strict=True)) / m
    cov = sum(covs) - m * np.outer(com, com)         # second moment about the common centre
    inertia = np.trace(cov) * np.eye(3) - cov
    return m, com, inertia


def _solid_moments(v: np.ndarray, f: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Volume [m^3], centroid (3,) [m] and second moment  integral x x^T dV  (3, 3) [m^5] about the
    origin of a closed, outward-oriented triangle mesh (sum of signed tetrahedra to the origin)."""
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    det = np.einsum("ij,ij->i", a, np.cross(b, c))
    vol = float(det.sum() / 6.0)
    s = a + b + c
    com = (det[:, None] * s).sum(0) / (24.0 * vol)
    outer = (np.einsum("i,ij,ik->jk", det, a, a) + np.einsum("i,ij,ik->jk", det, b, b)
             + np.einsum("i,ij,ik->jk", det, c, c) + np.einsum("i,ij,ik->jk", det, s, s))
    return vol, com, outer / 120.0


def _mass_props(mass: float, com: np.ndarray, inertia: np.ndarray) -> MassProperties:
    from scipy.spatial.transform import Rotation

    w, vecs = np.linalg.eigh((inertia + inertia.T) / 2)
    if np.linalg.det(vecs) < 0:
        vecs[:, 2] *= -1
    x, y, z, qw = Rotation.from_matrix(vecs).as_quat()
    w = np.maximum(w, 1e-9)
    return MassProperties(mass=float(mass), center_of_mass=tuple(float(c) for c in com),
                          diagonal_inertia=tuple(float(i) for i in w),
                          principal_axes=(float(qw), float(x), float(y), float(z)))


def _gravity_torque(mass: float, com: np.ndarray, origin: np.ndarray, axis) -> float:
    """m g r [N m]: the largest gravity torque of a link of ``mass`` [kg] with centre of mass ``com``
    (3,) about the unit ``axis`` (3,) through ``origin`` (3,) (r: the centre of mass's distance from
    the axis; horizontal axes only, a vertical one feels none)."""
    a = np.asarray(axis, dtype=np.float64)
    if abs(a[2]) > 0.7:
        return 0.0
    v = np.asarray(com, dtype=np.float64) - origin
    return float(mass * 9.81 * np.linalg.norm(v - np.dot(v, a) * a))


#: the stops of doors and drawers (MuJoCo solreflimit: time constant [s], damping ratio). Newton's
#: default force-space limit gains (ke 1e4, kd 10) give a fridge door's stop a 14 s time constant and
#: a damping ratio of 0.006: a leaf swung shut at 1 rad/s came back open 33 degrees (friction alone
#: stopped it). A limit only pushes, so a damped stop still returns part of the speed while its
#: spring pushes the leaf out faster than the damping would let it go: e^-2 = 13.5 % at ratio 1
#: (fridge door: 4 degrees open again), 4.6 % at 2 (0.2 degrees); the penetration at 1 rad/s is
#: 0.5 degrees. Buttons and knobs keep Newton's force-space stop: MuJoCo's solref is an
#: acceleration: a 10 g slider under a steady 10 N sinks 80 mm past it (20 mm at ratio 1; MuJoCo).
LEAF_STOP_SOLREF = (0.02, 2.0)
LEAF_ROLES = ("door", "drawer")


def _joint(j: _JointDraft, links: dict[str, _LinkDraft], child_mass: float, child_com: np.ndarray) -> Joint:
    """The model joint of a draft; ``child_mass`` [kg] and ``child_com`` (3,) (root frame) of its
    moving link size a counterbalance; a door's or drawer's stops are ``LEAF_STOP_SOLREF``."""
    rel = links[j.child].origin - links[j.parent].origin
    stiffness, friction = j.spring, j.friction
    if j.counterbalance is not None:
        mgr = _gravity_torque(child_mass, child_com, links[j.child].origin, j.axis)
        stiffness = float(f"{j.counterbalance[0] * mgr:.4g}")
        friction = float(f"{j.counterbalance[1] * mgr:.4g}")
    return Joint(name=j.name, type=j.type, parent=j.parent, child=j.child,
                 frame=Pose(tuple(float(x) for x in rel)), axis=j.axis, lower=j.lower, upper=j.upper,
                 max_effort=j.effort, max_velocity=j.velocity, friction=friction, damping=j.damping,
                 stiffness=stiffness, armature=j.armature,
                 limit_solref=LEAF_STOP_SOLREF if j.role in LEAF_ROLES else None)
