"""Annotate stage: mass properties and the physics material of an AssetModel, plus the catalog
record figures (bounding box, dimensions, volume, mass, friction, restitution).

Mass of a link (unless the source gave it, ``mass_from_source``):

- where every welded piece of the link's visual mesh is watertight, the mesh models the object's
  real walls and its volume is the *mass volume* (a mug is its ceramic, not its cavity);
- otherwise the volume is that of the union of the link's convex colliders (else of the hull of its
  visuals), which fills cavities and the inside of thin-shelled objects (a cabinet, a sofa, a
  cardboard box): such objects are hollow and density x hull volume would make a cabinet weigh
  several hundred kg. The mass volume is then capped by a shell estimate,
  ``min(hull volume, surface area / 2 x wall thickness)`` (every wall is modelled with its two
  faces, hence the half), with a per-material wall thickness ``SHELL_THICKNESS_M`` (wood 20 mm,
  fabric/upholstery 20 mm, plastic 4 mm, metal 3 mm, glass 5 mm, ceramic 8 mm, paper 3 mm, rubber
  10 mm; stone and food are taken solid);
- mass = ``annotation.mass`` if given (split over links by mass volume), else material density x
  mass volume;
- center of mass and inertia are those of the solid (visual mesh if watertight, else the collider
  union) of uniform density, scaled to the mass; the inertia tensor is diagonalised into principal
  moments and the rotation of the principal axes.

Friction and restitution are sampled per asset from the material rules
(``asset_catalog.materials.sample_physical_properties``) with the stage's generator; torsional and
rolling friction are the material class's. A link whose source declares contact properties (URDF
``<contact>``, ``Link.contact``) keeps them: the writer gives its colliders their own material.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace

import numpy as np

from asset_catalog.asset_model import AssetModel, Link, MassProperties, MeshPart, PhysicsMaterialSpec, Pose
from asset_catalog.materials import MaterialClass, sample_physical_properties
from pipeline.types import ItemError

log = logging.getLogger(__name__)

SHELL_THICKNESS_M: dict[MaterialClass, float] = {
    MaterialClass.WOOD: 0.02, MaterialClass.METAL: 0.003, MaterialClass.CERAMIC: 0.008,
    MaterialClass.GLASS: 0.005, MaterialClass.PLASTIC: 0.004, MaterialClass.FABRIC: 0.02,
    MaterialClass.RUBBER: 0.01, MaterialClass.STONE: float("inf"), MaterialClass.PAPER: 0.003,
    MaterialClass.FOOD: float("inf"),
}
"""Largest plausible wall thickness per material [m] (see the module docstring)."""

MIN_LINK_MASS_KG = 1e-3
"""Mass given to a link without any geometry [kg] (physics engines need a positive mass)."""


@dataclass(frozen=True, kw_only=True)
class AssetStats:
    """Catalog record figures of an annotated asset (root frame, Z-up, meters).

    bbox_min / bbox_max: axis-aligned bounds of all visuals at the zero configuration (3,) [m];
    dimensions: bbox_max - bbox_min (3,) [m]; volume: sum of link mass volumes [m^3];
    mass: total mass [kg]; static/dynamic friction and restitution [-]; density [kg/m^3].
    """

    bbox_min: tuple[float, float, float]
    bbox_max: tuple[float, float, float]
    dimensions: tuple[float, float, float]
    volume: float
    mass: float
    static_friction: float
    dynamic_friction: float
    restitution: float
    density: float


@dataclass(frozen=True)
class _Solid:
    """What a link's mass comes from: mass volume [m^3], solid volume [m^3], unit-density center of
    mass (3,) [m] and inertia tensor per unit mass (3, 3) [m^2] of the solid, in the link frame."""

    mass_volume: float
    solid_volume: float
    com: np.ndarray
    inertia_per_kg: np.ndarray


def annotate_physics(model: AssetModel, rng: np.random.Generator) -> AssetModel:
    """The model with every link's MassProperties (unless ``mass_from_source``) and the asset's
    PhysicsMaterialSpec filled in (see the module docstring)."""
    return annotate_with_stats(model, rng)[0]


def annotate_with_stats(model: AssetModel, rng: np.random.Generator) -> tuple[AssetModel, AssetStats]:
    """:func:`annotate_physics` plus the catalog record figures of the result."""
    ann = model.annotation
    material = MaterialClass(ann.material)
    props = sample_physical_properties(material, rng)
    solids = [_link_solid(lk, material) for lk in model.links]
    own = [s for lk, s in zip(model.links, solids, strict=True) if not lk.mass_from_source]
    own_vol = sum(s.mass_volume for s in own)
    if ann.mass is not None and own and own_vol <= 0.0:
        raise ItemError(f"{ann.source}: cannot split the annotated mass: no link has volume")
    source_mass = sum(lk.mass.mass for lk in model.links if lk.mass_from_source and lk.mass is not None)
    links: list[Link] = []
    for lk, s in zip(model.links, solids, strict=True):
        if lk.mass_from_source:
            links.append(lk)
            continue
        if ann.mass is not None:
            mass = max(ann.mass - source_mass, 0.0) * s.mass_volume / own_vol
        else:
            mass = props.density * s.mass_volume
        links.append(replace(lk, mass=_mass_properties(max(mass, MIN_LINK_MASS_KG), s)))
    pm = PhysicsMaterialSpec(static_friction=props.static_friction, dynamic_friction=props.dynamic_friction,
                             restitution=props.restitution, density=props.density,
                             torsional_friction=props.torsional_friction, rolling_friction=props.rolling_friction)
    out = replace(model, links=tuple(links), physics_material=pm)
    lo, hi = model_bounds(out)
    stats = AssetStats(
        bbox_min=tuple(float(x) for x in lo), bbox_max=tuple(float(x) for x in hi),
        dimensions=tuple(float(x) for x in hi - lo), volume=float(sum(s.mass_volume for s in solids)),
        mass=float(sum(lk.mass.mass for lk in links if lk.mass is not None)),
        static_friction=pm.static_friction, dynamic_friction=pm.dynamic_friction, restitution=pm.restitution,
        density=pm.density)
    return out, stats


def model_bounds(model: AssetModel) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds (lo (3,), hi (3,)) [m] of all visuals (else colliders) in the root frame at
    the zero joint configuration (link poses applied)."""
    pts = []
    for lk in model.links:
        meshes = lk.visuals or lk.colliders
        if not meshes:
            continue
        m = lk.pose.matrix()
        for p in meshes:
            pts.append(np.asarray(p.vertices) @ m[:3, :3].T + m[:3, 3])
    if not pts:
        z = np.zeros(3)
        return z, z
    allp = np.concatenate(pts)
    return allp.min(0).astype(float), allp.max(0).astype(float)


# ------------------------------------------------------------------------------------------ solids


def _link_solid(link: Link, material: MaterialClass) -> _Solid:
    import trimesh

    solid = _watertight_visual(link.visuals) if link.visuals else None
    watertight = solid is not None
    if solid is None:
        solid = _hull_union(link.colliders) if link.colliders else None
    if solid is None and link.visuals:
        verts = np.concatenate([p.vertices for p in link.visuals])
        solid = trimesh.convex.convex_hull(verts)
    if solid is None or solid.volume <= 0.0:
        return _Solid(0.0, 0.0, np.zeros(3), np.eye(3) * 1e-6)
    vol = float(solid.volume)
    if watertight:
        mass_vol = vol
    else:
        area = _surface_area(link.visuals) if link.visuals else float(solid.area)
        mass_vol = min(vol, 0.5 * area * SHELL_THICKNESS_M[material])
    mp = solid.mass_properties  # density 1: mass == volume
    return _Solid(mass_volume=mass_vol, solid_volume=vol, com=np.asarray(mp["center_mass"], dtype=float),
                  inertia_per_kg=np.asarray(mp["inertia"], dtype=float) / vol)


def _watertight_visual(visuals: tuple[MeshPart, ...]):
    """The welded visual mesh if every connected piece of it is watertight with positive volume."""
    import trimesh

    vs, fs, off = [], [], 0
    for p in visuals:
        vs.append(p.vertices)
        fs.append(p.faces + off)
        off += len(p.vertices)
    mesh = trimesh.Trimesh(np.concatenate(vs), np.concatenate(fs), process=True)
    mesh.merge_vertices(digits_vertex=6)
    if not mesh.is_watertight or not mesh.is_winding_consistent:
        return None
    if mesh.volume < 0:
        mesh.invert()
    return mesh if mesh.volume > 0 else None


def _hull_union(colliders: tuple[MeshPart, ...]):
    """The union of the convex colliders as one closed mesh (manifold3d boolean union)."""
    import trimesh

    hulls = [trimesh.Trimesh(c.vertices, c.faces, process=True) for c in colliders]
    hulls = [h for h in hulls if h.volume > 0]
    if not hulls:
        return None
    if len(hulls) == 1:
        return hulls[0]
    return trimesh.boolean.union(hulls, engine="manifold")


def _surface_area(parts: tuple[MeshPart, ...]) -> float:
    total = 0.0
    for p in parts:
        v, f = p.vertices, p.faces
        cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
        total += 0.5 * float(np.linalg.norm(cross, axis=1).sum())
    return total


def _mass_properties(mass: float, s: _Solid) -> MassProperties:
    """MassProperties of ``mass`` distributed like the solid: principal moments + axes rotation."""
    from scipy.spatial.transform import Rotation

    tensor = s.inertia_per_kg * mass
    tensor = 0.5 * (tensor + tensor.T)
    evals, evecs = np.linalg.eigh(tensor)
    if np.linalg.det(evecs) < 0:
        evecs[:, 2] = -evecs[:, 2]
    evals = np.maximum(evals, 1e-12)
    x, y, z, w = Rotation.from_matrix(evecs).as_quat()
    q = Pose(orientation=(float(w), float(x), float(y), float(z))).orientation
    return MassProperties(mass=float(mass), center_of_mass=tuple(float(c) for c in s.com),
                          diagonal_inertia=tuple(float(e) for e in evals), principal_axes=q)
