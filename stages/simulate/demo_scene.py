"""A small furnished room authored as a USD scene, for tests and benchmarks of the simulate stage.

Composed scenes (layout + placed asset packages) come from other stages; until they exist, and
as a fixed reference afterwards, this module authors a real USD scene with the same ingredients:
a floor and four walls (static colliders), a table, a rigid mug (a real mesh with its convex
collision pieces), a cabinet with a sliding drawer and a hinged door (UsdPhysics joints), UsdLux
lights and UsdSemantics labels on every object. It is loaded with ``ModelBuilder.add_usd`` exactly
like a composed scene.

Frame: Z up, metres; the room spans [0, size_x] x [0, size_y]; +X is "east".
Authoring follows the project rule: compute everything first, then write with the Sdf API inside
one ``Sdf.ChangeBlock``.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pipeline.types import ItemError

log = logging.getLogger(__name__)

MUG_REL = Path("objects_rigid/daily_objects__vikashplus_object_sim/object_sim/mug")


@dataclass(frozen=True, kw_only=True)
class BoxSpec:
    """A box [m]: centre (3,), size (3,), yaw about Z [rad]; rgb linear in [0, 1]."""

    name: str
    center: tuple[float, float, float]
    size: tuple[float, float, float]
    rgb: tuple[float, float, float] = (0.7, 0.7, 0.7)
    yaw: float = 0.0


@dataclass(frozen=True, kw_only=True)
class CabinetSpec:
    """A cabinet with a drawer and a door, front facing -X (see ``cabinet_parts``).

    origin: centre of the carcass footprint on the floor [m]; size: carcass (depth x, width y,
    height z) [m]; drawer_travel [m]; door_range [rad]; the front faces ``-X`` (towards the room)."""

    origin: tuple[float, float] = (4.2, 2.5)
    size: tuple[float, float, float] = (0.45, 0.8, 0.75)
    drawer_travel: float = 0.30
    door_range: float = float(np.pi / 2)


@dataclass(frozen=True, kw_only=True)
class DemoRoom:
    """What a test needs to know about the authored room (all in the world frame, metres).

    usd: the scene file; size: room interior (x, y); wall_thickness; table: the table top box;
    mug_position: the mug's initial origin; cabinet: the cabinet spec; drawer_handle /
    door_handle: handle bar centres at the closed configuration; door_hinge: hinge axis point;
    labels: semantic label of every top-level object.
    """

    usd: Path
    size: tuple[float, float]
    wall_thickness: float
    wall_height: float
    table: BoxSpec
    mug_position: tuple[float, float, float] | None
    cabinet: CabinetSpec | None
    drawer_handle: tuple[float, float, float] | None = None
    door_handle: tuple[float, float, float] | None = None
    door_hinge: tuple[float, float, float] | None = None
    labels: dict[str, str] = field(default_factory=dict)


# --------------------------------------------------------------------------------------------
# Sdf authoring helpers
# --------------------------------------------------------------------------------------------


def _quat_z(yaw: float):
    from pxr import Gf

    return Gf.Quatf(float(np.cos(yaw / 2)), 0.0, 0.0, float(np.sin(yaw / 2)))


class _Writer:
    """Collects prims as plain values, then writes them in one Sdf change block."""

    def __init__(self) -> None:
        self.prims: list[tuple[str, str, list[str], dict, dict, dict]] = []

    def prim(self, path: str, type_name: str, *, apis=(), attrs=None, rels=None, meta=None) -> None:
        self.prims.append((path, type_name, list(apis), attrs or {}, rels or {}, meta or {}))

    def write(self, path: Path, default_prim: str) -> None:
        from pxr import Sdf

        layer = Sdf.Layer.CreateAnonymous(".usda")
        with Sdf.ChangeBlock():
            layer.defaultPrim = default_prim
            layer.pseudoRoot.SetInfo("metersPerUnit", 1.0)
            layer.pseudoRoot.SetInfo("upAxis", "Z")
            layer.pseudoRoot.SetInfo("kilogramsPerUnit", 1.0)
            for ppath, type_name, apis, attrs, rels, meta in self.prims:
                spec = Sdf.CreatePrimInLayer(layer, ppath)
                spec.specifier = Sdf.SpecifierDef
                spec.typeName = type_name
                if apis:
                    spec.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=apis))
                for k, v in meta.items():
                    spec.SetInfo(k, v)
                order = []
                for name, (vtype, value) in attrs.items():
                    a = Sdf.AttributeSpec(spec, name, vtype)
                    a.default = value
                    if name.startswith("xformOp:"):
                        order.append(name)
                if order:
                    a = Sdf.AttributeSpec(
                        spec, "xformOpOrder", Sdf.ValueTypeNames.TokenArray, Sdf.VariabilityUniform
                    )
                    a.default = order
                for name, targets in rels.items():
                    r = Sdf.RelationshipSpec(spec, name)
                    for t in targets:
                        r.targetPathList.Append(Sdf.Path(t))
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.stem + ".tmp" + path.suffix)
        layer.Export(str(tmp))
        tmp.replace(path)


def _labels(label: str) -> tuple[list[str], dict]:
    from pxr import Sdf

    return ["SemanticsLabelsAPI:class"], {"semantics:labels:class": (Sdf.ValueTypeNames.TokenArray, [label])}


def _xform_attrs(pos, yaw=0.0, scale=None) -> dict:
    from pxr import Gf, Sdf

    attrs = {"xformOp:translate": (Sdf.ValueTypeNames.Double3, Gf.Vec3d(*map(float, pos)))}
    if yaw:
        attrs["xformOp:orient"] = (Sdf.ValueTypeNames.Quatf, _quat_z(yaw))
    if scale is not None:
        attrs["xformOp:scale"] = (Sdf.ValueTypeNames.Float3, Gf.Vec3f(*map(float, scale)))
    return attrs


def _box(w: _Writer, path: str, center, size, rgb, *, collide=True, label=None, yaw=0.0) -> None:
    """A unit cube scaled to ``size`` (Newton reads size x scale)."""
    from pxr import Gf, Sdf

    apis = ["PhysicsCollisionAPI"] if collide else []
    attrs = {
        "size": (Sdf.ValueTypeNames.Double, 1.0),
        "primvars:displayColor": (Sdf.ValueTypeNames.Color3fArray, [Gf.Vec3f(*rgb)]),
        **_xform_attrs(center, yaw, size),
    }
    if label:
        la, lv = _labels(label)
        apis += la
        attrs.update(lv)
    w.prim(path, "Cube", apis=apis, attrs=attrs)


def _mesh(
    w: _Writer,
    path: str,
    vertices: np.ndarray,
    faces: np.ndarray,
    rgb,
    *,
    collide: bool,
    visible: bool = True,
) -> None:
    from pxr import Gf, Sdf, Vt

    apis = ["PhysicsCollisionAPI", "PhysicsMeshCollisionAPI"] if collide else []
    attrs = {
        "points": (Sdf.ValueTypeNames.Point3fArray, Vt.Vec3fArray.FromNumpy(vertices.astype(np.float32))),
        "faceVertexCounts": (
            Sdf.ValueTypeNames.IntArray,
            Vt.IntArray.FromNumpy(np.full(len(faces), 3, np.int32)),
        ),
        "faceVertexIndices": (
            Sdf.ValueTypeNames.IntArray,
            Vt.IntArray.FromNumpy(faces.astype(np.int32).ravel()),
        ),
        "primvars:displayColor": (Sdf.ValueTypeNames.Color3fArray, [Gf.Vec3f(*rgb)]),
        "subdivisionScheme": (Sdf.ValueTypeNames.Token, "none"),
    }
    if collide:
        attrs["physics:approximation"] = (Sdf.ValueTypeNames.Token, "convexHull")
    if not visible:
        attrs["visibility"] = (Sdf.ValueTypeNames.Token, "invisible")
        attrs["purpose"] = (Sdf.ValueTypeNames.Token, "guide")
    w.prim(path, "Mesh", apis=apis, attrs=attrs)


# --------------------------------------------------------------------------------------------
# The room
# --------------------------------------------------------------------------------------------


def _walls(size: tuple[float, float], t: float, h: float) -> list[BoxSpec]:
    sx, sy = size
    c = (0.85, 0.83, 0.78)
    return [
        BoxSpec(name="WallSouth", center=(sx / 2, -t / 2, h / 2), size=(sx + 2 * t, t, h), rgb=c),
        BoxSpec(name="WallNorth", center=(sx / 2, sy + t / 2, h / 2), size=(sx + 2 * t, t, h), rgb=c),
        BoxSpec(name="WallWest", center=(-t / 2, sy / 2, h / 2), size=(t, sy, h), rgb=c),
        BoxSpec(name="WallEast", center=(sx + t / 2, sy / 2, h / 2), size=(t, sy, h), rgb=c),
    ]


def _table_parts(center_xy, top_size=(0.6, 0.9), height=0.55) -> list[BoxSpec]:
    x, y = center_xy
    tz = 0.04
    wood = (0.55, 0.38, 0.22)
    parts = [BoxSpec(name="Top", center=(x, y, height - tz / 2), size=(*top_size, tz), rgb=wood)]
    lx, ly = top_size[0] / 2 - 0.05, top_size[1] / 2 - 0.05
    for i, (dx, dy) in enumerate(((lx, ly), (lx, -ly), (-lx, ly), (-lx, -ly))):
        parts.append(
            BoxSpec(
                name=f"Leg{i}",
                center=(x + dx, y + dy, (height - tz) / 2),
                size=(0.05, 0.05, height - tz),
                rgb=wood,
            )
        )
    return parts


def _add_mug(w: _Writer, mug_dir: Path, pos, scale: float = 1.0) -> None:
    import trimesh
    from pxr import Sdf

    visual = trimesh.load(mug_dir / "mug.stl", force="mesh")
    visual.apply_scale(scale)
    # the mug's origin is its centre; put the origin at the base so the position is "on the table"
    lift = -float(visual.bounds[0, 2])
    la, lv = _labels("mug")
    attrs = {**_xform_attrs(pos), **lv, "physics:mass": (Sdf.ValueTypeNames.Float, 0.30 * scale**3)}
    w.prim("/World/Mug", "Xform", apis=["PhysicsRigidBodyAPI", "PhysicsMassAPI", *la], attrs=attrs)
    _mesh(
        w, "/World/Mug/Visual", visual.vertices + [0, 0, lift], visual.faces, (0.1, 0.2, 0.75), collide=False
    )
    pieces = sorted(mug_dir.glob("contact*.stl"), key=lambda p: int(p.stem[7:]))
    if not pieces:
        raise ItemError(f"{mug_dir}: no contact*.stl collision pieces")
    for i, p in enumerate(pieces):
        m = trimesh.load(p, force="mesh")
        m.apply_scale(scale)
        _mesh(
            w,
            f"/World/Mug/Collision{i}",
            m.vertices + [0, 0, lift],
            m.faces,
            (0.1, 0.2, 0.75),
            collide=True,
            visible=False,
        )


def cabinet_parts(c: CabinetSpec) -> dict[str, list[BoxSpec]]:
    """Carcass (static), drawer and door boxes at the closed configuration, in world frame.

    The carcass is open towards -X. The upper third holds a drawer (slides along -X); the lower
    two thirds a fixed panel (-Y half) and a door (+Y half) hinged on its +Y edge, which opens
    towards -X by a negative rotation about +Z.
    """
    d, wdt, h = c.size
    x0, y0 = c.origin
    t = 0.02
    xf = x0 - d / 2  # front plane
    white = (0.9, 0.9, 0.88)
    carcass = [
        BoxSpec(name="Back", center=(x0 + d / 2 - t / 2, y0, h / 2), size=(t, wdt, h), rgb=white),
        BoxSpec(name="SideL", center=(x0, y0 - wdt / 2 + t / 2, h / 2), size=(d, t, h), rgb=white),
        BoxSpec(name="SideR", center=(x0, y0 + wdt / 2 - t / 2, h / 2), size=(d, t, h), rgb=white),
        BoxSpec(name="Top", center=(x0, y0, h - t / 2), size=(d, wdt, t), rgb=white),
        BoxSpec(name="Bottom", center=(x0, y0, 0.05 + t / 2), size=(d, wdt, t), rgb=white),
        BoxSpec(name="Shelf", center=(x0, y0, 0.52), size=(d, wdt, t), rgb=white),
        BoxSpec(name="Plinth", center=(x0, y0, 0.025), size=(d, wdt, 0.05), rgb=white),
    ]
    zd0, zd1 = 0.53 + 0.005, h - t - 0.005  # drawer opening
    dz = zd1 - zd0
    iw = wdt - 2 * t - 0.01
    dd = d - t - 0.03
    grey = (0.35, 0.35, 0.38)
    front = (0.72, 0.5, 0.3)
    drawer = [
        BoxSpec(name="Front", center=(xf - t / 2, y0, zd0 + dz / 2), size=(t, wdt - 0.01, dz), rgb=front),
        BoxSpec(name="Floor", center=(xf + dd / 2, y0, zd0 + 0.01), size=(dd, iw, t), rgb=white),
        BoxSpec(
            name="SideL",
            center=(xf + dd / 2, y0 - iw / 2 + 0.005, zd0 + dz / 2),
            size=(dd, 0.01, dz - 0.02),
            rgb=white,
        ),
        BoxSpec(
            name="SideR",
            center=(xf + dd / 2, y0 + iw / 2 - 0.005, zd0 + dz / 2),
            size=(dd, 0.01, dz - 0.02),
            rgb=white,
        ),
        BoxSpec(
            name="HandleBar", center=(xf - t - 0.035, y0, zd0 + dz / 2), size=(0.02, 0.16, 0.02), rgb=grey
        ),
        BoxSpec(
            name="HandleL",
            center=(xf - t - 0.0125, y0 - 0.07, zd0 + dz / 2),
            size=(0.025, 0.02, 0.02),
            rgb=grey,
        ),
        BoxSpec(
            name="HandleR",
            center=(xf - t - 0.0125, y0 + 0.07, zd0 + dz / 2),
            size=(0.025, 0.02, 0.02),
            rgb=grey,
        ),
    ]
    zo0, zo1 = 0.055 + t, 0.52 - 0.01
    zm = (zo0 + zo1) / 2
    half = wdt / 2 - 0.005
    # the -Y half of the lower compartment is a fixed panel; the +Y half a door hinged on its +Y edge
    carcass.append(
        BoxSpec(
            name="FixedPanel", center=(xf - t / 2, y0 - wdt / 4, zm), size=(t, half, zo1 - zo0), rgb=front
        )
    )
    door = [
        # the panel stops short of the hinge line so that its back corner never swings into the side
        BoxSpec(
            name="Panel",
            center=(xf - t / 2, y0 + 0.0025 + (wdt / 2 - t - 0.0045) / 2, zm),
            size=(t, wdt / 2 - t - 0.0045, zo1 - zo0),
            rgb=front,
        ),
        BoxSpec(name="HandleBar", center=(xf - t - 0.035, y0 + 0.06, zm), size=(0.02, 0.02, 0.16), rgb=grey),
        BoxSpec(
            name="HandleB", center=(xf - t - 0.0125, y0 + 0.06, zm - 0.07), size=(0.025, 0.02, 0.02), rgb=grey
        ),
        BoxSpec(
            name="HandleT", center=(xf - t - 0.0125, y0 + 0.06, zm + 0.07), size=(0.025, 0.02, 0.02), rgb=grey
        ),
    ]
    return {"carcass": carcass, "drawer": drawer, "door": door}


def _add_cabinet(w: _Writer, c: CabinetSpec) -> dict[str, tuple[float, float, float]]:
    from pxr import Gf, Sdf

    parts = cabinet_parts(c)
    la, lv = _labels("cabinet")
    w.prim("/World/Cabinet", "Xform", apis=["PhysicsArticulationRootAPI", *la], attrs=lv)
    w.prim("/World/Cabinet/Carcass", "Xform", attrs={})
    for b in parts["carcass"]:
        _box(w, f"/World/Cabinet/Carcass/{b.name}", b.center, b.size, b.rgb)
    d, wdt, h = c.size
    xf = c.origin[0] - d / 2
    # moving parts: bodies whose origin is the world origin, so part boxes keep world coordinates
    for part, mass in (("drawer", 2.0), ("door", 3.0)):
        body = f"/World/Cabinet/{part.capitalize()}"
        w.prim(
            body,
            "Xform",
            apis=["PhysicsRigidBodyAPI", "PhysicsMassAPI"],
            attrs={"physics:mass": (Sdf.ValueTypeNames.Float, mass)},
        )
        for b in parts[part]:
            _box(w, f"{body}/{b.name}", b.center, b.size, b.rgb)
    hinge = (xf - 0.02, c.origin[1] + wdt / 2 - 0.02, 0.0)
    joint_common = {
        "physics:localRot0": (Sdf.ValueTypeNames.Quatf, Gf.Quatf(1, 0, 0, 0)),
        "physics:localRot1": (Sdf.ValueTypeNames.Quatf, Gf.Quatf(1, 0, 0, 0)),
    }
    w.prim(
        "/World/Cabinet/DrawerJoint",
        "PhysicsPrismaticJoint",
        attrs={
            **joint_common,
            "physics:axis": (Sdf.ValueTypeNames.Token, "X"),
            "physics:lowerLimit": (Sdf.ValueTypeNames.Float, float(-c.drawer_travel)),
            "physics:upperLimit": (Sdf.ValueTypeNames.Float, 0.0),
            "physics:localPos0": (Sdf.ValueTypeNames.Point3f, Gf.Vec3f(0, 0, 0)),
            "physics:localPos1": (Sdf.ValueTypeNames.Point3f, Gf.Vec3f(0, 0, 0)),
        },
        rels={"physics:body1": ["/World/Cabinet/Drawer"]},
    )
    # the door swings towards -X (into the room) about its +Y edge: a negative rotation about +Z
    # opens it, so the limit is [-range, 0] [deg].
    w.prim(
        "/World/Cabinet/DoorJoint",
        "PhysicsRevoluteJoint",
        attrs={
            **joint_common,
            "physics:axis": (Sdf.ValueTypeNames.Token, "Z"),
            "physics:lowerLimit": (Sdf.ValueTypeNames.Float, float(-np.rad2deg(c.door_range))),
            "physics:upperLimit": (Sdf.ValueTypeNames.Float, 0.0),
            "physics:localPos0": (Sdf.ValueTypeNames.Point3f, Gf.Vec3f(*hinge)),
            "physics:localPos1": (Sdf.ValueTypeNames.Point3f, Gf.Vec3f(*hinge)),
        },
        rels={"physics:body1": ["/World/Cabinet/Door"]},
    )
    drawer_handle = next(b.center for b in parts["drawer"] if b.name == "HandleBar")
    door_handle = next(b.center for b in parts["door"] if b.name == "HandleBar")
    return {"drawer_handle": drawer_handle, "door_handle": door_handle, "door_hinge": hinge}


def _add_lights(
    w: _Writer,
    size,
    height: float = 2.3,
    *,
    ceiling_lux: float = 300.0,
    ceiling_kelvin: float = 4000.0,
    ceiling_xy: tuple[float, float] | None = None,
    sun_lux: float = 400.0,
    sun_tilt: tuple[float, float] = (25.0, -20.0),
    dome_lux: float = 200.0,
) -> None:
    """Photometric lights as the scene stage authors them: a ceiling SphereLight of colour
    temperature ``ceiling_kelvin`` [K] at ``ceiling_xy`` (default: the room centre) [m], ``height``
    [m] above the floor, giving ``ceiling_lux`` on the floor below it, a weak sun of ``sun_lux``
    [lux] whose -Z axis is turned by ``sun_tilt`` (about world X, then Y) [deg], and a sky dome
    giving ``dome_lux`` [lux] on a horizontal surface. Intensities are physical with the scene
    exposure on each light, the dome's folded into its intensity (``stages.scene.lighting``)."""
    from pxr import Gf, Sdf
    from scipy.spatial.transform import Rotation

    from stages.scene.lighting import SCENE_EXPOSURE

    exposure = (Sdf.ValueTypeNames.Float, SCENE_EXPOSURE)

    radius, lux = 0.08, float(ceiling_lux)
    cx, cy = (size[0] / 2, size[1] / 2) if ceiling_xy is None else ceiling_xy
    q = Rotation.from_euler("xy", list(sun_tilt), degrees=True).as_quat()  # x, y, z, w; shines along -Z
    w.prim("/World/Lights", "Xform")
    w.prim(
        "/World/Lights/Sun",
        "DistantLight",
        attrs={
            "inputs:intensity": (Sdf.ValueTypeNames.Float, float(sun_lux)),
            "inputs:exposure": exposure,
            "inputs:color": (Sdf.ValueTypeNames.Color3f, Gf.Vec3f(1.0, 0.97, 0.92)),
            "xformOp:orient": (
                Sdf.ValueTypeNames.Quatf,
                Gf.Quatf(float(q[3]), float(q[0]), float(q[1]), float(q[2])),
            ),
        },
    )
    w.prim(
        "/World/Lights/Ceiling",
        "SphereLight",
        attrs={
            "inputs:intensity": (Sdf.ValueTypeNames.Float, lux * height**2 / (np.pi * radius**2)),
            "inputs:exposure": exposure,
            "inputs:radius": (Sdf.ValueTypeNames.Float, radius),
            "inputs:enableColorTemperature": (Sdf.ValueTypeNames.Bool, True),
            "inputs:colorTemperature": (Sdf.ValueTypeNames.Float, float(ceiling_kelvin)),
            **_xform_attrs((cx, cy, height)),
        },
    )
    w.prim(
        "/World/Lights/Sky",
        "DomeLight",
        attrs={
            # exposure folded in: Blender's importer ignores a dome light's exposure
            "inputs:intensity": (Sdf.ValueTypeNames.Float, float(dome_lux) / np.pi * 2.0**SCENE_EXPOSURE),
            "inputs:color": (Sdf.ValueTypeNames.Color3f, Gf.Vec3f(0.8, 0.88, 1.0)),
        },
    )


def write_demo_room(
    path: Path,
    *,
    shared_assets: Path | None = None,
    size=(6.0, 5.0),
    table_xy=(3.0, 3.6),
    mug_xy: tuple[float, float] | None = None,
    cabinet: CabinetSpec | None = CabinetSpec(),
    clutter: int = 0,
    mug_scale: float = 1.0,
    rng: np.random.Generator | None = None,
) -> DemoRoom:
    """Author the room at ``path`` (.usda). The mug needs ``shared_assets`` (the third-party
    assets folder); without it there is no mug. ``mug_scale`` scales the mug mesh (the real one
    is 82 mm across, wider than the Franka hand's 80 mm stroke). ``clutter`` adds that many loose
    boxes (rigid, 0.1-0.2 m) on the floor at positions from ``rng``.
    """
    from pxr import Gf, Sdf

    w = _Writer()
    t, h = 0.1, 2.5
    w.prim("/World", "Xform", meta={"kind": "assembly"})
    w.prim(
        "/World/PhysicsScene",
        "PhysicsScene",
        attrs={
            "physics:gravityDirection": (Sdf.ValueTypeNames.Vector3f, Gf.Vec3f(0, 0, -1)),
            "physics:gravityMagnitude": (Sdf.ValueTypeNames.Float, 9.81),
        },
    )
    labels = {"Floor": "floor"}
    _box(
        w,
        "/World/Floor",
        (size[0] / 2, size[1] / 2, -0.05),
        (size[0] + 2 * t, size[1] + 2 * t, 0.1),
        (0.6, 0.6, 0.58),
        label="floor",
    )
    for b in _walls(size, t, h):
        _box(w, f"/World/{b.name}", b.center, b.size, b.rgb, label="wall")
        labels[b.name] = "wall"
    la, lv = _labels("table")
    w.prim("/World/Table", "Xform", apis=la, attrs=lv)
    parts = _table_parts(table_xy)
    for b in parts:
        _box(w, f"/World/Table/{b.name}", b.center, b.size, b.rgb)
    labels["Table"] = "table"
    top = parts[0]
    mug_pos = None
    if shared_assets is not None:
        mxy = mug_xy or (table_xy[0] - 0.12, table_xy[1] - 0.2)
        mug_pos = (mxy[0], mxy[1], top.center[2] + top.size[2] / 2 + 0.001)
        _add_mug(w, Path(shared_assets) / MUG_REL, mug_pos, mug_scale)
        labels["Mug"] = "mug"
    handles: dict = {}
    if cabinet is not None:
        handles = _add_cabinet(w, cabinet)
        labels["Cabinet"] = "cabinet"
    if clutter:
        rng = rng if rng is not None else np.random.default_rng(0)
        for i in range(clutter):
            s = rng.uniform(0.1, 0.2, 3)
            p = (rng.uniform(0.5, size[0] - 0.5), rng.uniform(0.4, 1.6), s[2] / 2 + 0.002)
            la, lv = _labels("box")
            w.prim(
                f"/World/Box{i}",
                "Xform",
                apis=["PhysicsRigidBodyAPI", "PhysicsMassAPI", *la],
                attrs={**_xform_attrs(p), **lv, "physics:mass": (Sdf.ValueTypeNames.Float, 0.5)},
            )
            _box(w, f"/World/Box{i}/Geom", (0, 0, 0), s, tuple(rng.uniform(0.2, 0.9, 3)))
            labels[f"Box{i}"] = "box"
    _add_lights(w, size)
    w.write(Path(path), "World")
    log.info("wrote demo room %s", path)
    return DemoRoom(
        usd=Path(path),
        size=tuple(size),
        wall_thickness=t,
        wall_height=h,
        table=top,
        mug_position=mug_pos,
        cabinet=cabinet,
        labels=labels,
        **handles,
    )
