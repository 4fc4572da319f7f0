"""AssetModels built in code for the usd_schemas and physics-check tests.

Colliders are trimesh convex hulls (the collision stage is not used here); mass properties are
computed from the collider pieces at the material's density.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from asset_catalog.annotations import AssetAnnotation
from asset_catalog.asset_model import (
    AssetModel,
    ColliderApprox,
    Joint,
    JointType,
    Link,
    MassProperties,
    MaterialSpec,
    MeshPart,
    PhysicsMaterialSpec,
    Pose,
)

WOOD = PhysicsMaterialSpec(static_friction=0.44, dynamic_friction=0.4, restitution=0.3, density=700.0)
CERAMIC = PhysicsMaterialSpec(static_friction=0.55, dynamic_friction=0.5, restitution=0.25, density=2400.0)


def part(name: str, mesh: trimesh.Trimesh, material: str | None = None, uvs: np.ndarray | None = None) -> MeshPart:
    return MeshPart(name=name, vertices=np.asarray(mesh.vertices, dtype=np.float64),
                    faces=np.asarray(mesh.faces, dtype=np.int64),
                    normals=np.asarray(mesh.vertex_normals, dtype=np.float64), uvs=uvs, material=material)


def hulls(pieces: list[trimesh.Trimesh]) -> tuple[MeshPart, ...]:
    return tuple(part(f"hull_{i}", p.convex_hull) for i, p in enumerate(pieces))


def mass_properties(pieces: list[trimesh.Trimesh], density: float) -> MassProperties:
    """Mass [kg], center of mass, principal inertia and axes of disjoint closed pieces."""
    mesh = trimesh.util.concatenate([p.convex_hull for p in pieces])
    mesh.density = density
    com = mesh.center_mass
    inertia = mesh.moment_inertia  # about the center of mass, mesh frame axes
    vals, vecs = np.linalg.eigh(inertia)
    if np.linalg.det(vecs) < 0:
        vecs[:, 2] *= -1
    x, y, z, w = Rotation.from_matrix(vecs).as_quat()
    return MassProperties(mass=float(mesh.mass), center_of_mass=tuple(float(c) for c in com),
                          diagonal_inertia=tuple(float(v) for v in vals),
                          principal_axes=(float(w), float(x), float(y), float(z)))


def annotation(asset_id: str, category: str, **kw) -> AssetAnnotation:
    return AssetAnnotation(id=asset_id, source=f"{asset_id}.obj", category=category, **kw)


def box_model(asset_id: str = "box_01", size=(0.2, 0.1, 0.3)) -> AssetModel:
    box = trimesh.creation.box(size)
    link = Link(name="body", visuals=(part("box", box),), colliders=hulls([box]),
                collider_approx=ColliderApprox.HULL, mass=mass_properties([box], WOOD.density))
    return AssetModel(name=asset_id, annotation=annotation(asset_id, "box", room_types=("kitchen",)),
                      links=(link,), physics_material=WOOD, source_sha256="ab" * 32)


def bowl_model(asset_id: str = "bowl_01", radius: float = 0.08, height: float = 0.06, wall: float = 0.008,
               segments: int = 8) -> AssetModel:
    """An open bowl: a bottom disc and ``segments`` wall blocks around it (each its own hull)."""
    bottom = trimesh.creation.cylinder(radius=radius, height=wall, sections=24)
    bottom.apply_translation((0, 0, wall / 2))
    pieces = [bottom]
    seg_len = 2 * np.pi * radius / segments * 1.02
    for k in range(segments):
        blk = trimesh.creation.box((wall, seg_len, height - wall))
        ang = 2 * np.pi * k / segments
        tf = trimesh.transformations.rotation_matrix(ang, (0, 0, 1))
        tf[:3, 3] = ((radius - wall / 2) * np.cos(ang), (radius - wall / 2) * np.sin(ang), wall + (height - wall) / 2)
        blk.apply_transform(tf)
        pieces.append(blk)
    visual = trimesh.util.concatenate(pieces)
    link = Link(name="bowl", visuals=(part("bowl", visual),), colliders=hulls(pieces),
                collider_approx=ColliderApprox.DECOMPOSITION, mass=mass_properties(pieces, CERAMIC.density))
    return AssetModel(name=asset_id, annotation=annotation(asset_id, "bowl", placement="on_surface",
                                                            material="ceramic", interactable=True,
                                                            co_occurrence=("table", "counter")),
                      links=(link,), physics_material=CERAMIC)


def cabinet_model(asset_id: str = "cabinet_01", fixed_base: bool = False) -> AssetModel:
    """A cabinet (front +X) with a door on a vertical hinge (axis +Z, not X) and a drawer sliding
    along +X. Links: body (root), door, drawer; link frames at their geometry centers."""
    depth, width, h = 0.4, 0.5, 0.7
    body_mesh = trimesh.creation.box((depth, width, h))
    body_mesh.apply_translation((0, 0, h / 2))
    door_mesh = trimesh.creation.box((0.02, width - 0.02, 0.38))
    drawer_mesh = trimesh.creation.box((0.3, width - 0.1, 0.2))
    door_pose = Pose((depth / 2 + 0.011, 0.0, 0.48))
    drawer_pose = Pose((depth / 2 - 0.14, 0.0, 0.14))
    links = (
        Link(name="body", visuals=(part("carcass", body_mesh),), colliders=hulls([body_mesh]),
             collider_approx=ColliderApprox.HULL, mass=mass_properties([body_mesh], WOOD.density)),
        Link(name="door", pose=door_pose, visuals=(part("panel", door_mesh),), colliders=hulls([door_mesh]),
             collider_approx=ColliderApprox.HULL, mass=mass_properties([door_mesh], WOOD.density)),
        Link(name="drawer", pose=drawer_pose, visuals=(part("box", drawer_mesh),), colliders=hulls([drawer_mesh]),
             collider_approx=ColliderApprox.HULL, mass=mass_properties([drawer_mesh], WOOD.density)),
    )
    # hinge on the door's -Y edge, in the body frame; a door turning outward about +Z
    hinge = Pose((depth / 2 + 0.011, -(width - 0.02) / 2, 0.48))
    joints = (
        Joint(name="door_hinge", type=JointType.REVOLUTE, parent="body", child="door", frame=hinge,
              axis=(0.0, 0.0, 1.0), lower=0.0, upper=1.4, friction=0.05, damping=0.5, max_velocity=3.0,
              limit_solref=(0.02, 2.0)),
        Joint(name="drawer_slide", type=JointType.PRISMATIC, parent="body", child="drawer",
              frame=Pose((depth / 2 - 0.14, 0.0, 0.14)), axis=(1.0, 0.0, 0.0), lower=0.0, upper=0.25,
              damping=2.0, max_effort=50.0),
    )
    return AssetModel(name=asset_id, annotation=annotation(asset_id, "cabinet", placement="against_wall",
                                                            interactable=True, fixed_base=fixed_base),
                      links=links, joints=joints, physics_material=WOOD, fixed_base=fixed_base)


def tilted_hinge_model(asset_id: str = "flap_01") -> AssetModel:
    """A base plate and a flap on a hinge whose axis is oblique, (0, 1, 1)/sqrt(2), with a frame
    rotated away from the parent's axes: exercises the axis-to-X frame rotation."""
    base = trimesh.creation.box((0.3, 0.3, 0.05))
    base.apply_translation((0, 0, 0.025))
    flap = trimesh.creation.box((0.1, 0.02, 0.1))
    frame_rot = Rotation.from_euler("z", 30, degrees=True).as_quat()
    frame = Pose((0.0, 0.0, 0.2), (float(frame_rot[3]), *map(float, frame_rot[:3])))
    links = (
        Link(name="base", visuals=(part("plate", base),), colliders=hulls([base]),
             mass=mass_properties([base], WOOD.density)),
        Link(name="flap", pose=frame, visuals=(part("flap", flap),), colliders=hulls([flap]),
             mass=mass_properties([flap], WOOD.density)),
    )
    axis = tuple(float(a) for a in np.array([0.0, 1.0, 1.0]) / np.sqrt(2.0))
    joints = (Joint(name="hinge", type=JointType.REVOLUTE, parent="base", child="flap", frame=frame, axis=axis,
                    lower=-0.8, upper=0.6),)
    return AssetModel(name=asset_id, annotation=annotation(asset_id, "flap", fixed_base=True), links=links,
                      joints=joints, physics_material=WOOD, fixed_base=True)


def _textured_box(size: float) -> tuple[trimesh.Trimesh, np.ndarray]:
    """A cube with 4 vertices per face (24) and per-face UVs covering [0, 1]^2."""
    verts, faces, uvs = [], [], []
    h = size / 2
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            u = np.zeros(3)
            u[(axis + 1) % 3] = 1.0
            v = np.cross(n, u)
            base = len(verts)
            for cu, cv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                verts.append(n * h + u * cu * h + v * cv * h)
                uvs.append(((cu + 1) / 2, (cv + 1) / 2))
            faces += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    mesh = trimesh.Trimesh(np.array(verts), np.array(faces), process=False)
    return mesh, np.array(uvs)


def write_png(path: Path, rgb: tuple[int, int, int], size: int = 32, checker: bool = True) -> Path:
    from PIL import Image

    img = np.zeros((size, size, 3), dtype=np.uint8)
    img[:] = rgb
    if checker:
        yy, xx = np.mgrid[0:size, 0:size]
        img[((xx // 8 + yy // 8) % 2).astype(bool)] //= 2
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(img).save(path)
    return path


def textured_model(tex_dir: Path, asset_id: str = "crate_01") -> AssetModel:
    """A textured cube: base color (checker PNG), normal map, packed roughness/metallic (glTF-style
    ARM in one file) and occlusion."""
    mesh, uvs = _textured_box(0.15)
    color = write_png(tex_dir / "crate_albedo.png", (200, 120, 40))
    normal = write_png(tex_dir / "crate normal.png", (128, 128, 255), checker=False)
    arm = write_png(tex_dir / "crate_arm.png", (255, 180, 0), checker=False)
    mat = MaterialSpec(name="crate", base_color=(1.0, 1.0, 1.0), roughness=0.7, base_color_texture=color,
                       normal_texture=normal, roughness_texture=arm, metallic_texture=arm, occlusion_texture=arm)
    link = Link(name="crate", visuals=(part("crate", mesh, material="crate", uvs=uvs),), colliders=hulls([mesh]),
                collider_approx=ColliderApprox.HULL, mass=mass_properties([mesh], WOOD.density))
    return AssetModel(name=asset_id, annotation=annotation(asset_id, "crate"), links=(link,),
                      materials={"crate": mat}, physics_material=WOOD)


def loaded_hinge_model(asset_id: str = "lid_01", friction: float = 2.0) -> AssetModel:
    """A box with a lid on a horizontal hinge (axis -Y along the back edge): the check's drive must
    lift the lid's weight and beat ``friction`` [N m] of joint friction."""
    base = trimesh.creation.box((0.3, 0.4, 0.2))
    base.apply_translation((0, 0, 0.1))
    lid = trimesh.creation.box((0.3, 0.4, 0.02))
    lid_pose = Pose((0.0, 0.0, 0.211))
    links = (
        Link(name="base", visuals=(part("box", base),), colliders=hulls([base]),
             mass=mass_properties([base], WOOD.density)),
        Link(name="lid", pose=lid_pose, visuals=(part("lid", lid),), colliders=hulls([lid]),
             mass=mass_properties([lid], WOOD.density)),
    )
    joints = (Joint(name="lid_hinge", type=JointType.REVOLUTE, parent="base", child="lid",
                    frame=Pose((-0.15, 0.0, 0.211)), axis=(0.0, -1.0, 0.0), lower=0.0, upper=1.9,
                    friction=friction),)
    return AssetModel(name=asset_id, annotation=annotation(asset_id, "chest"), links=links, joints=joints,
                      physics_material=WOOD)
