"""The layout USD layer, authored with the Sdf API inside one ``Sdf.ChangeBlock``.

Structure (Z up, meters, defaultPrim ``/House``, kind assembly)::

    /House                                   Xform, kind=assembly
      /Floor_<i>                             Xform, kind=group
        /Rooms/<room id>                     Xform, label = room type
          /Floor, /Ceiling                   element Xforms (below)
        /Walls/<wall id>, /Windows/<id>, /Stairs/<id>, /Railings/<id>
      /Roof

Each element Xform carries a ``UsdSemantics.LabelsAPI`` (instance ``class``) label and holds a
``Mesh "Visual"`` (displayColor) and ``Cube "Collider_<k>"`` prims: static colliders
(``UsdPhysics.CollisionAPI``, no rigid body), purpose ``guide``, unit cubes placed by translate and
scale; their union equals the visual solid.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from stages.layout.geometry import Element

LABEL_INSTANCE = "class"


def _attr(spec, name: str, type_name: str, value, *, uniform: bool = False):
    from pxr import Sdf

    tn = getattr(Sdf.ValueTypeNames, type_name)
    a = Sdf.AttributeSpec(spec, name, tn, Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying)
    a.default = value
    return a


def _prim(parent, name: str, type_name: str, *, kind: str | None = None, apis: Sequence[str] = ()):
    from pxr import Sdf

    spec = Sdf.PrimSpec(parent, name, Sdf.SpecifierDef, type_name)
    if kind:
        spec.kind = kind
    if apis:
        spec.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=list(apis)))
    return spec


def _label(spec, labels: Sequence[str]) -> None:
    from pxr import Sdf, Vt

    spec.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=[f"SemanticsLabelsAPI:{LABEL_INSTANCE}"]))
    _attr(spec, f"semantics:labels:{LABEL_INSTANCE}", "TokenArray", Vt.TokenArray(list(labels)))


def _mesh(parent, e: Element) -> None:
    from pxr import Gf, Vt

    m = _prim(parent, "Visual", "Mesh")
    pts = e.vertices.astype(np.float32)
    _attr(m, "points", "Point3fArray", Vt.Vec3fArray.FromNumpy(pts))
    _attr(m, "faceVertexCounts", "IntArray", Vt.IntArray.FromNumpy(np.full(len(e.faces), 3, dtype=np.int32)))
    _attr(m, "faceVertexIndices", "IntArray", Vt.IntArray.FromNumpy(e.faces.reshape(-1).astype(np.int32)))
    tri = e.vertices[e.faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    normals = np.repeat(n.astype(np.float32), 3, axis=0)
    na = _attr(m, "normals", "Normal3fArray", Vt.Vec3fArray.FromNumpy(normals))
    na.SetInfo("interpolation", "faceVarying")
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    _attr(m, "extent", "Float3Array", Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]))
    _attr(m, "subdivisionScheme", "Token", "none", uniform=True)
    c = _attr(m, "primvars:displayColor", "Color3fArray", Vt.Vec3fArray([Gf.Vec3f(*e.color)]))
    c.SetInfo("interpolation", "constant")
    if e.opacity < 1.0:
        o = _attr(m, "primvars:displayOpacity", "FloatArray", Vt.FloatArray([e.opacity]))
        o.SetInfo("interpolation", "constant")


def _colliders(parent, e: Element) -> None:
    from pxr import Gf, Vt

    for k, b in enumerate(e.colliders):
        c = _prim(parent, f"Collider_{k:03d}", "Cube", apis=["PhysicsCollisionAPI"])
        lo, hi = np.asarray(b.lo), np.asarray(b.hi)
        _attr(c, "size", "Double", 1.0)
        _attr(c, "extent", "Float3Array", Vt.Vec3fArray([Gf.Vec3f(-0.5, -0.5, -0.5), Gf.Vec3f(0.5, 0.5, 0.5)]))
        _attr(c, "purpose", "Token", "guide", uniform=True)
        _attr(c, "xformOp:translate", "Double3", Gf.Vec3d(*map(float, (lo + hi) / 2)))
        _attr(c, "xformOp:scale", "Float3", Gf.Vec3f(*map(float, hi - lo)))
        _attr(c, "xformOpOrder", "TokenArray", Vt.TokenArray(["xformOp:translate", "xformOp:scale"]), uniform=True)


def write_layout_usd(elements: Sequence[Element], room_types: dict[str, str], n_floors: int, path: Path,
                     *, seed: int) -> Path:
    """Write the layout layer to ``path`` (.usda or .usdc).

    room_types: room id -> room type (the label of the room's Xform). Deterministic: the same
    elements give the same bytes.
    """
    from pxr import Sdf

    layer = Sdf.Layer.CreateAnonymous(Path(path).suffix)
    with Sdf.ChangeBlock():
        root = layer.pseudoRoot
        root.SetInfo("upAxis", "Z")
        root.SetInfo("metersPerUnit", 1.0)
        root.SetInfo("kilogramsPerUnit", 1.0)
        layer.defaultPrim = "House"
        layer.customLayerData = {"agentworld:generator": "stages.layout", "agentworld:seed": str(seed)}
        house = _prim(root, "House", "Xform", kind="assembly")
        _label(house, ["house"])
        specs: dict[str, object] = {}
        for f in range(n_floors):
            fl = _prim(house, f"Floor_{f}", "Xform", kind="group")
            _label(fl, ["storey"])
            specs[f"Floor_{f}"] = fl
        for e in elements:
            parent = house if e.floor is None else specs[f"Floor_{e.floor}"]
            key = "" if e.floor is None else f"Floor_{e.floor}"
            for part in (p for p in e.group.split("/") if p):
                key = f"{key}/{part}"
                if key not in specs:
                    is_room = part in room_types
                    specs[key] = _prim(parent, part, "Xform")
                    if is_room:
                        _label(specs[key], [room_types[part]])
                parent = specs[key]
            el = _prim(parent, e.name, "Xform")
            _label(el, [e.label])
            _mesh(el, e)
            _colliders(el, e)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not layer.Export(str(path)):
        raise OSError(f"{path}: could not write the layout layer")
    return path


def composition_errors(path: Path) -> list[str]:
    """Composition errors of a stage opened on ``path`` (empty when it composes cleanly)."""
    from pxr import Usd

    stage = Usd.Stage.Open(str(path))
    return [str(e) for e in stage.GetCompositionErrors()]
