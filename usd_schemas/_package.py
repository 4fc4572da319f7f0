"""The asset package writer: ``AssetModel`` -> ``<out_dir>/<id>.usda`` + payload + textures.

Layout (ARCHITECTURE.md, STYLE.md 11)::

    <out_dir>/<id>.usda            small root layer: defaultPrim /<id> (Xform, kind component),
                                   upAxis Z, metersPerUnit 1, kilogramsPerUnit 1,
                                   AgentWorldAssetAPI + SemanticsLabelsAPI:class, payload ->
    <out_dir>/<id>_payload.usdc    geometry, materials, physics (loaded by default by
                                   Usd.Stage.Open, Newton's add_usd, usdview, Isaac, Blender)
    <out_dir>/textures/<stem>_<sha256[:10]><ext>   copied texture files (relative asset paths)

Prims under /<id> (payload)::

    Looks/PhysicsMaterial         Material + PhysicsMaterialAPI (friction, restitution, density)
    Looks/<material>              UsdPreviewSurface (+ UsdUVTexture, UsdPrimvarReader_float2 'st')
    <link>                        Xform + RigidBodyAPI + MassAPI (none for a static fixed base)
    <link>/visuals/<mesh>         Mesh: points, normals and st primvars (vertex), material:binding
    <link>/colliders/<piece>      Mesh, purpose guide, CollisionAPI + MeshCollisionAPI
                                  (approximation convexHull), material:binding:physics
    joints/<joint>                PhysicsRevoluteJoint / PhysicsPrismaticJoint / PhysicsFixedJoint

Each collider piece is already convex (a hull, or one CoACD part), so ``convexHull`` reproduces it
exactly, and every consumer (Newton, PhysX/Isaac, MuJoCo converters) supports it; authoring
``convexDecomposition`` would ask each engine to decompose again, differently. The model's
``collider_approx`` is kept as ``customData["agentworldColliderApprox"]`` on the colliders Xform.

Joint axes: USD joints turn about X, Y or Z of their frame; the writer rotates the joint frame by
the minimal rotation taking X onto the model's unit axis and authors ``physics:axis = "X"``.
Revolute limits are degrees, drive gains per degree (USD); prismatic in meters. A joint with
stiffness, damping or an effort limit gets a DriveAPI (force type, target 0; damping with zero
stiffness is the portable form of passive joint damping); joint friction and velocity limit are
authored as Newton's ``newton:friction`` and ``newton:velocityLimit``; a joint's limit stops, where
the model gives them, as MuJoCo's ``mjc:solreflimit`` (time constant [s], damping ratio).
"""

from __future__ import annotations

import logging
import os
import shutil
from pathlib import Path

from pydantic import BaseModel, ConfigDict

from asset_catalog.asset_model import AssetModel

log = logging.getLogger(__name__)


class AssetPackage(BaseModel):
    """A written asset package. Paths are POSIX, relative to ``out_dir``.

    root_layer: '<id>.usda'; payload_layer: '<id>_payload.usdc'; files: every file written
    (layers and textures), sorted; prim_count: prims in the composed package; mesh_count,
    collider_count, material_count (render materials), body_count (rigid bodies), joint_count;
    bbox_min / bbox_max: axis-aligned bounds [m] of the visual geometry in the asset frame.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    asset_id: str
    out_dir: Path
    root_layer: str
    payload_layer: str
    files: tuple[str, ...]
    prim_count: int
    mesh_count: int
    collider_count: int
    material_count: int
    body_count: int
    joint_count: int
    bbox_min: tuple[float, float, float]
    bbox_max: tuple[float, float, float]

    @property
    def root_path(self) -> Path:
        """Absolute path of the root layer (what scenes reference and tools open)."""
        return self.out_dir / self.root_layer


def write_asset_package(model: AssetModel, out_dir: Path, *, pipeline_version: str) -> AssetPackage:
    """Write ``model`` as an asset package in ``out_dir`` (created if needed) and describe it.

    Deterministic: the same model writes byte-identical files. Each layer is written to a
    temporary name and renamed. Raises ``pipeline.types.ItemError`` with a one-line reason for a
    model that cannot be written (bad mesh arrays, unknown link/material, missing texture, ...).
    """
    from pxr import Sdf

    from pipeline.types import ItemError
    from usd_schemas._author import author_payload_layer, author_root_layer
    from usd_schemas._plan import PlanError, plan_package
    from usd_schemas._registry import register

    register()
    out_dir = Path(out_dir)
    try:
        plan = plan_package(model, pipeline_version)
    except PlanError as e:
        raise ItemError(str(e)) from None
    out_dir.mkdir(parents=True, exist_ok=True)
    aid = plan.asset_id
    root_name, payload_name = f"{aid}.usda", f"{aid}_payload.usdc"

    for src, rel in plan.texture_copies:
        dst = out_dir / rel
        dst.parent.mkdir(parents=True, exist_ok=True)
        tmp = dst.with_name(dst.name + ".tmp")
        try:
            shutil.copyfile(src, tmp)
        except OSError as e:
            raise ItemError(f"{src}: cannot copy texture of asset {aid!r}: {e.strerror or e}") from None
        os.replace(tmp, dst)

    payload = Sdf.Layer.CreateAnonymous(f"{aid}_payload.usdc")
    author_payload_layer(payload, plan)
    _export(payload, out_dir / payload_name)
    root = Sdf.Layer.CreateAnonymous(f"{aid}.usda")
    author_root_layer(root, plan, f"./{payload_name}")
    _export(root, out_dir / root_name)

    n_meshes = sum(len(b.meshes) for b in plan.bodies)
    n_cols = sum(len(b.colliders) for b in plan.bodies)
    files = sorted([root_name, payload_name, *(rel for _, rel in plan.texture_copies)])
    pkg = AssetPackage(
        asset_id=aid, out_dir=out_dir, root_layer=root_name, payload_layer=payload_name, files=tuple(files),
        prim_count=_count_prims(payload), mesh_count=n_meshes, collider_count=n_cols,
        material_count=len(plan.materials), body_count=sum(b.rigid for b in plan.bodies),
        joint_count=len(plan.joints), bbox_min=plan.bbox_min, bbox_max=plan.bbox_max)
    log.debug("wrote asset package %s (%d prims) to %s", aid, pkg.prim_count, out_dir)
    return pkg


def _export(layer, path: Path) -> None:
    """Write ``layer`` to ``path`` atomically (temporary name with the same extension, rename);
    reload a layer of that path already open in this process so readers see the new content."""
    from pxr import Sdf

    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
    if not layer.Export(str(tmp)):
        raise OSError(f"{tmp}: USD could not write the layer")
    os.replace(tmp, path)
    opened = Sdf.Layer.Find(str(path))
    if opened is not None:
        opened.Reload(force=True)


def _count_prims(layer) -> int:
    n = 0

    def visit(path) -> None:
        nonlocal n
        if path.IsPrimPath():
            n += 1

    layer.Traverse(layer.pseudoRoot.path, visit)
    return n
