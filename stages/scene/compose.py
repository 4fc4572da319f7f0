"""Composition of a scene USD: the layout layer plus references to asset packages (never copies),
per-instance transforms and overrides, a physics scene, one sublayer per stage::

    scene.usda          defaultPrim /World (kind assembly); subLayers lighting, materials, placement;
                        /World/Layout references the layout layer; /World/PhysicsScene
    placement.usda      /World/Objects/<instance> references ../<assets>/<id>/<id>.usda, translate + orient
    materials.usdc      /World/Looks/* UsdPreviewSurface materials; primvars:st on the layout meshes;
                        variant set "look" on /World: each variant binds floors, walls and assets
    lighting.usda       /World/Lights/* UsdLux lights (chosen values in customData)
    textures/*.png      the material library's maps

Every path to another file is relative to the layer that names it. Layers are authored with the
Sdf API inside one ``Sdf.ChangeBlock`` each (values computed first).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stages.scene.lighting import LightSpec, sun_orientation
from stages.scene.materials import Look, MaterialChoice, TextureSet, planar_st

SCENE_NAME = "scene.usda"
LAYER_NAMES = {"lighting": "lighting.usda", "materials": "materials.usdc", "placement": "placement.usda"}
ROOT = "/World"
LAYOUT = f"{ROOT}/Layout"
OBJECTS = f"{ROOT}/Objects"
LOOKS = f"{ROOT}/Looks"
LIGHTS = f"{ROOT}/Lights"


@dataclass(frozen=True)
class InstanceSpec:
    """One referenced asset: instance name, package root layer (absolute), position [m] (3,), yaw
    [rad], catalog material class, room id, support instance (or ""), category."""

    name: str
    usd: Path
    position: tuple[float, float, float]
    yaw: float
    material: str
    room: str
    support: str
    category: str


def _rel(target: Path, layer_dir: Path) -> str:
    r = os.path.relpath(Path(target).resolve(), Path(layer_dir).resolve()).replace(os.sep, "/")
    return r if r.startswith(".") else f"./{r}"


def _layer_meta(layer, *, default_prim: str | None = None) -> None:
    root = layer.pseudoRoot
    root.SetInfo("upAxis", "Z")
    root.SetInfo("metersPerUnit", 1.0)
    root.SetInfo("kilogramsPerUnit", 1.0)
    if default_prim:
        layer.defaultPrim = default_prim


def _attr(spec, name: str, tn: str, value, *, uniform: bool = False, custom: bool = False):
    from pxr import Sdf

    a = Sdf.AttributeSpec(spec, name, getattr(Sdf.ValueTypeNames, tn),
                          Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying, declaresCustom=custom)
    if value is not None:
        a.default = value
    return a


def _prim(parent, name: str, type_name: str = "", *, over: bool = False, kind: str | None = None,
          apis: Sequence[str] = ()):
    from pxr import Sdf

    spec = Sdf.PrimSpec(parent, name, Sdf.SpecifierOver if over else Sdf.SpecifierDef, type_name)
    if kind:
        spec.kind = kind
    if apis:
        spec.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=list(apis)))
    return spec


def _export(layer, path: Path, reload: bool = True) -> None:
    """Write ``layer`` to ``path`` (temporary name, then rename). A layer of that path still open in
    this process (a stage of an earlier settle check not yet collected) is reloaded, else the next
    stage opened on the scene would reuse its stale content; ``reload`` False leaves it as it was
    (the final rewrite for the folder the scene moves to: no stage opens it here again, and a stage
    still alive would recompose with paths that resolve only from there)."""
    from pxr import Sdf

    tmp = path.with_name(f".{path.name}.tmp{path.suffix}")
    if not layer.Export(str(tmp)):
        raise OSError(f"{path}: could not write the layer")
    os.replace(tmp, path)
    stale = Sdf.Layer.Find(str(path)) if reload else None
    if stale is not None:
        stale.Reload(force=True)


# ---------------------------------------------------------------------------------------------


def write_root(scene_dir: Path, layout_usd: Path, layout_dir_final: Path, scene_dir_final: Path,
               meta: dict[str, str], *, reload: bool = True) -> Path:
    """scene.usda: /World, the layout reference, the physics scene and the sublayers (``reload``:
    see ``_export``)."""
    from pxr import Gf, Sdf

    layer = Sdf.Layer.CreateAnonymous(".usda")
    layout_ref = _rel(layout_dir_final / Path(layout_usd).name, scene_dir_final)
    with Sdf.ChangeBlock():
        _layer_meta(layer, default_prim="World")
        layer.subLayerPaths = [f"./{LAYER_NAMES[k]}" for k in ("lighting", "materials", "placement")]
        layer.customLayerData = {f"agentworld:{k}": v for k, v in meta.items()}
        world = _prim(layer.pseudoRoot, "World", "Xform", kind="assembly")
        lay = _prim(world, "Layout", "Xform", kind="assembly")
        lay.referenceList.Prepend(Sdf.Reference(layout_ref))
        ps = _prim(world, "PhysicsScene", "PhysicsScene")
        _attr(ps, "physics:gravityDirection", "Vector3f", Gf.Vec3f(0.0, 0.0, -1.0))
        _attr(ps, "physics:gravityMagnitude", "Float", 9.81)
    path = scene_dir / SCENE_NAME
    _export(layer, path, reload)
    return path


def write_placement(scene_dir: Path, scene_dir_final: Path, instances: Sequence[InstanceSpec], *,
                    reload: bool = True) -> Path:
    """placement.usda: one referencing Xform per instance with its transform and annotations
    (``reload``: see ``_export``)."""
    from pxr import Gf, Sdf, Vt

    layer = Sdf.Layer.CreateAnonymous(".usda")
    refs = [(i, _rel(i.usd, scene_dir_final)) for i in instances]
    with Sdf.ChangeBlock():
        _layer_meta(layer)
        world = _prim(layer.pseudoRoot, "World", over=True)
        objs = _prim(world, "Objects", "Xform", kind="group")
        for inst, ref in refs:
            s = _prim(objs, inst.name, "Xform")
            s.referenceList.Prepend(Sdf.Reference(ref))
            half = inst.yaw / 2
            _attr(s, "xformOp:translate", "Double3", Gf.Vec3d(*inst.position))
            _attr(s, "xformOp:orient", "Quatd", Gf.Quatd(math.cos(half), 0.0, 0.0, math.sin(half)))
            _attr(s, "xformOpOrder", "TokenArray", Vt.TokenArray(["xformOp:translate", "xformOp:orient"]),
                  uniform=True)
            s.customData = {"agentworld": {"room": inst.room, "support": inst.support, "category": inst.category}}
    path = scene_dir / LAYER_NAMES["placement"]
    _export(layer, path, reload)
    return path


def _material(looks_spec, m: MaterialChoice, tex: TextureSet, layer_dir_rel: str) -> None:
    from pxr import Gf, Sdf

    mat = _prim(looks_spec, m.name, "Material")
    base = f"{LOOKS}/{m.name}"
    out = _attr(mat, "outputs:surface", "Token", None)
    out.connectionPathList.Prepend(Sdf.Path(f"{base}/PreviewSurface.outputs:surface"))
    sh = _prim(mat, "PreviewSurface", "Shader")
    _attr(sh, "info:id", "Token", "UsdPreviewSurface", uniform=True)
    _attr(sh, "outputs:surface", "Token", None)

    def connect(inp: str, tn: str, src: str):
        a = _attr(sh, inp, tn, None)
        a.connectionPathList.Prepend(Sdf.Path(f"{base}/{src}"))

    st = _prim(mat, "ST", "Shader")
    _attr(st, "info:id", "Token", "UsdPrimvarReader_float2", uniform=True)
    _attr(st, "inputs:varname", "String", "st")
    _attr(st, "outputs:result", "Float2", None)

    def texture(name: str, file: str, color_space: str, outputs: Sequence[tuple[str, str]],
                scale=(1.0, 1.0, 1.0, 1.0), bias=(0.0, 0.0, 0.0, 0.0)):
        t = _prim(mat, name, "Shader")
        _attr(t, "info:id", "Token", "UsdUVTexture", uniform=True)
        _attr(t, "inputs:file", "Asset", Sdf.AssetPath(f"{layer_dir_rel}{file}"))
        a = _attr(t, "inputs:st", "Float2", None)
        a.connectionPathList.Prepend(Sdf.Path(f"{base}/ST.outputs:result"))
        _attr(t, "inputs:wrapS", "Token", "repeat")
        _attr(t, "inputs:wrapT", "Token", "repeat")
        _attr(t, "inputs:sourceColorSpace", "Token", color_space)
        _attr(t, "inputs:scale", "Float4", Gf.Vec4f(*scale))
        _attr(t, "inputs:bias", "Float4", Gf.Vec4f(*bias))
        for o, tn in outputs:
            _attr(t, f"outputs:{o}", tn, None)

    texture("BaseColor", tex.base_color, "sRGB", [("rgb", "Float3")], scale=(*m.tint, 1.0))
    connect("inputs:diffuseColor", "Color3f", "BaseColor.outputs:rgb")
    texture("Roughness", tex.roughness, "raw", [("r", "Float")])
    connect("inputs:roughness", "Float", "Roughness.outputs:r")
    texture("Normal", tex.normal, "raw", [("rgb", "Float3")], scale=(2.0, 2.0, 2.0, 1.0), bias=(-1.0, -1.0, -1.0, 0.0))
    connect("inputs:normal", "Normal3f", "Normal.outputs:rgb")
    if tex.metallic:
        texture("Metallic", tex.metallic, "raw", [("r", "Float")])
        connect("inputs:metallic", "Float", "Metallic.outputs:r")
    else:
        _attr(sh, "inputs:metallic", "Float", 0.0)
    if m.opacity < 1.0:
        _attr(sh, "inputs:opacity", "Float", float(m.opacity))


def _bind(parent, rel_path: str, material: str) -> None:
    """An over at ``rel_path`` (below parent) binding ``material`` stronger than descendants."""
    from pxr import Sdf

    spec = parent
    for part in rel_path.split("/"):
        child = spec.nameChildren.get(part) if hasattr(spec.nameChildren, "get") else None
        spec = child if child is not None else _prim(spec, part, over=True)
    spec.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["MaterialBindingAPI"]))
    rel = Sdf.RelationshipSpec(spec, "material:binding", custom=False)
    rel.targetPathList.Prepend(Sdf.Path(f"{LOOKS}/{material}"))
    rel.SetInfo("bindMaterialAs", "strongerThanDescendants")


def layout_surfaces(layout_usd: Path) -> tuple[dict[str, str], dict[str, tuple[np.ndarray, np.ndarray]]]:
    """From the layout layer: room floor element paths below the layout root ({room id: path}) and
    the Visual meshes of floors and walls ({path below the root: (points (N, 3), indices (3M,))})."""
    from pxr import Sdf

    layer = Sdf.Layer.FindOrOpen(str(layout_usd))
    root = layer.GetPrimAtPath(f"/{layer.defaultPrim}")
    floors, meshes = {}, {}
    for fl in root.nameChildren:
        rooms = fl.nameChildren.get("Rooms") if "Rooms" in fl.nameChildren else None
        walls = fl.nameChildren.get("Walls") if "Walls" in fl.nameChildren else None
        for grp, key in ((rooms, "Floor"), (walls, None)):
            if grp is None:
                continue
            for el in grp.nameChildren:
                target = el.nameChildren.get(key) if key else el
                if target is None or "Visual" not in target.nameChildren:
                    continue
                vis = target.nameChildren["Visual"]
                rel = str(vis.path.MakeRelativePath(root.path))
                pts = np.asarray(vis.attributes["points"].default, dtype=np.float64)
                idx = np.asarray(vis.attributes["faceVertexIndices"].default, dtype=np.int64)
                meshes[rel] = (pts, idx)
                if key:
                    floors[el.name] = str(target.path.MakeRelativePath(root.path))
    return floors, meshes


def write_materials(scene_dir: Path, looks: Sequence[Look], textures: dict[str, TextureSet],
                    instances: Sequence[InstanceSpec], layout_usd: Path, wall_room: dict[str, str]) -> Path:
    """materials.usdc (binary: it holds the st arrays): the materials of every look, st primvars on the layout's floor and wall meshes,
    and the ``look`` variant set with the bindings of each look (first look selected)."""
    from pxr import Sdf, Vt

    floors, meshes = layout_surfaces(layout_usd)
    sts = {rel: planar_st(pts, idx) for rel, (pts, idx) in meshes.items()}
    layer = Sdf.Layer.CreateAnonymous(".usdc")
    with Sdf.ChangeBlock():
        _layer_meta(layer)
        world = _prim(layer.pseudoRoot, "World", over=True)
        looks_spec = _prim(world, "Looks", "Scope")
        for look in looks:
            for m in look.materials():
                _material(looks_spec, m, textures[m.kind], "./")
        layout = _prim(world, "Layout", over=True)
        for rel, st in sts.items():
            spec = layout
            for part in rel.split("/"):
                spec = spec.nameChildren[part] if part in spec.nameChildren else _prim(spec, part, over=True)
            a = _attr(spec, "primvars:st", "TexCoord2fArray", Vt.Vec2fArray.FromNumpy(st))
            a.SetInfo("interpolation", "faceVarying")
        vset = Sdf.VariantSetSpec(world, "look")
        for look in looks:
            var = Sdf.VariantSpec(vset, look.name)
            vp = var.primSpec
            lay = _prim(vp, "Layout", over=True)
            for rid, path in floors.items():
                if rid in look.floors:
                    _bind(lay, path, look.floors[rid].name)
            for wall_rel in (r for r in meshes if "/Walls/" in f"/{r}"):
                wall = wall_rel.split("/")[-2]
                rid = wall_room.get(wall)
                if rid in look.walls:
                    _bind(lay, wall_rel.rsplit("/", 1)[0], look.walls[rid].name)
            objs = _prim(vp, "Objects", over=True)
            for inst in instances:
                if inst.material in look.assets:
                    _bind(objs, inst.name, look.assets[inst.material].name)
        world.SetInfo("variantSetNames", Sdf.StringListOp.Create(prependedItems=["look"]))
        world.variantSelections["look"] = looks[0].name
    path = scene_dir / LAYER_NAMES["materials"]
    _export(layer, path)
    return path


def write_lighting(scene_dir: Path, lights: Sequence[LightSpec]) -> Path:
    """lighting.usda: /World/Lights with one UsdLux light per spec."""
    from pxr import Gf, Sdf, Vt

    layer = Sdf.Layer.CreateAnonymous(".usda")
    with Sdf.ChangeBlock():
        _layer_meta(layer)
        world = _prim(layer.pseudoRoot, "World", over=True)
        group = _prim(world, "Lights", "Scope")
        for lt in lights:
            s = _prim(group, lt.name, lt.type)
            _attr(s, "inputs:intensity", "Float", float(lt.intensity))
            _attr(s, "inputs:exposure", "Float", float(lt.exposure))
            _attr(s, "inputs:enableColorTemperature", "Bool", True)
            _attr(s, "inputs:colorTemperature", "Float", float(lt.color_temperature))
            ops = []
            if lt.type == "SphereLight":
                _attr(s, "inputs:radius", "Float", float(lt.radius))
                _attr(s, "treatAsPoint", "Bool", False)
                _attr(s, "xformOp:translate", "Double3", Gf.Vec3d(*lt.position))
                ops.append("xformOp:translate")
            if lt.type == "DistantLight":
                _attr(s, "inputs:angle", "Float", 0.53)
                _attr(s, "xformOp:orient", "Quatd", Gf.Quatd(*sun_orientation(lt.elevation, lt.azimuth)))
                ops.append("xformOp:orient")
            if ops:
                _attr(s, "xformOpOrder", "TokenArray", Vt.TokenArray(ops), uniform=True)
            s.customData = {"agentworld": {"targetLux": float(lt.target_lux),
                                           "colorTemperature": float(lt.color_temperature),
                                           "exposure": float(lt.exposure)}}
    path = scene_dir / LAYER_NAMES["lighting"]
    _export(layer, path)
    return path
