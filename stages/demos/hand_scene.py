"""A table scene for grasping with a hand: floor, a table (static boxes) and one catalog package
(an ingested USD asset package, referenced, never copied) standing on it, as a USD scene that
:func:`stages.simulate.world.build_sim` loads like a composed scene.

Frame: world, Z up, metres; the table top's centre is at ``table_xy``, its surface at
``table_height``; the object's origin (its package's bottom centre) stands on it at ``object_xy``
turned ``object_yaw`` about +Z.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

OBJECT_PRIM = "/World/Object"


@dataclass(frozen=True, kw_only=True)
class TableScene:
    """usd: the scene file; body: the object's rigid body prim path; position: the object's origin
    (3,) [m]; yaw [rad]; table_height [m]; category."""

    usd: Path
    body: str
    position: tuple[float, float, float]
    yaw: float
    table_height: float
    category: str


def table_world(table_xy=(1.0, 0.0), table_size=(0.6, 0.9), table_height=0.55):
    """A scene writer holding the world, gravity, a 6 m floor and a table: its top ``table_size`` [m]
    centred at ``table_xy`` [m], ``table_height`` [m] high. The caller adds its objects and writes."""
    from pxr import Gf, Sdf

    from stages.simulate.demo_scene import _box, _labels, _Writer

    w = _Writer()
    w.prim("/World", "Xform", meta={"kind": "assembly"})
    w.prim("/World/PhysicsScene", "PhysicsScene", attrs={
        "physics:gravityDirection": (Sdf.ValueTypeNames.Vector3f, Gf.Vec3f(0, 0, -1)),
        "physics:gravityMagnitude": (Sdf.ValueTypeNames.Float, 9.81)})
    _box(w, "/World/Floor", (0.0, 0.0, -0.05), (6.0, 6.0, 0.1), (0.6, 0.6, 0.58), label="floor")
    la, lv = _labels("table")
    w.prim("/World/Table", "Xform", apis=la, attrs=lv)
    t = 0.04
    _box(w, "/World/Table/Top", (*table_xy, table_height - t / 2), (*table_size, t), (0.55, 0.4, 0.3))
    _box(w, "/World/Table/Base", (*table_xy, (table_height - t) / 2),
         (table_size[0] * 0.5, table_size[1] * 0.5, table_height - t), (0.4, 0.3, 0.25))
    return w


def write_object_world(path: Path, w, asset, pos, yaw: float) -> None:
    """Reference ``asset`` (a :class:`stages.demos.packages.CatalogAsset`) into the world ``w`` (from
    :func:`table_world`) at OBJECT_PRIM, at ``pos`` [m] turned by ``yaw`` [rad], and write it to ``path``."""
    import os

    from pxr import Sdf

    from stages.simulate.demo_scene import _labels, _xform_attrs

    la, lv = _labels(asset.category)
    rel = os.path.relpath(Path(asset.usd).resolve(), Path(path).parent.resolve()).replace(os.sep, "/")
    ref = Sdf.Reference(rel if rel.startswith(".") else f"./{rel}")
    w.prim(OBJECT_PRIM, "Xform", apis=la, attrs={**_xform_attrs(pos, yaw), **lv},
           meta={"references": Sdf.ReferenceListOp.Create(prependedItems=[ref])})
    w.write(path, "World")


def write_table_scene(path: Path, asset, *, table_xy=(1.0, 0.0), table_size=(0.6, 0.9), table_height=0.55,
                      object_xy=(0.85, 0.0), object_yaw: float = 0.0) -> TableScene:
    """Author the scene at ``path`` (.usda) with ``asset`` (a :class:`stages.demos.packages.CatalogAsset`)
    on the table; returns where things are."""
    path = Path(path)
    w = table_world(table_xy, table_size, table_height)
    pos = (float(object_xy[0]), float(object_xy[1]), float(table_height) + 0.001)
    write_object_world(path, w, asset, pos, object_yaw)
    return TableScene(usd=path, body=f"{OBJECT_PRIM}/{asset.root_link}", position=pos, yaw=float(object_yaw),
                      table_height=float(table_height), category=asset.category)
