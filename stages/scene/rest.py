"""Rest of a populated scene without simulating it, where statics proves it; the rest is simulated.

Every asset stands on a horizontal support: the floor or a support surface of the asset below it,
``REST_GAP`` (1 mm) above it (``stages.scene.solver``), touching nothing else (the placement keeps
``PLACE_GAP`` to every other collider). A rigid body on a horizontal plane with no other contact is
in static equilibrium exactly when the vertical through its center of mass passes inside the convex
hull of its contact points (friction carries no load); a support also carries what rests on it, so
for each instance the center of mass of the instance and everything resting on it (recursively)
must lie inside its contact region. ``analytic_rest`` proves that per instance:

- instances fixed to the world cannot move; their joints only move on their own when gravity works
  on them (``AssetGeometry.neutral_joints``), which the package rest check decides;
- contact region (``stages.scene.support.contact_region``): per collider piece of the fixed part,
  its base patch (points within ``BASE_TOL`` of the lowest point; a moving part at the bottom, e.g.
  a door touching the floor, is not proven) clipped to the support surface's polygons (the floor:
  unbounded), and the hull of those patches: a foot past the support's edge carries nothing; it
  must sit ``REST_GAP`` above the support;
- the combined center of mass must lie ``margin`` inside that region (5 mm by default); it is known
  only when every dynamic instance in the stack has authored mass properties (``MassAPI`` mass and
  center of mass on each body): otherwise the simulator derives them from collider volumes, which
  the pieces' centroid does not stand for, so such a stack is simulated;
- a dynamic package with several bodies or with joints gravity works on (an oven's door) must also
  pass ``package_rest``: the package alone on a flat floor, simulated once in Newton + MuJoCo as the
  scene settle check does, result kept per package content (``CheckCache`` kind ``rest``);
- the support itself must be proven (or fixed).

Instances that are not proven are simulated (``stages.scene.settle.settle_check`` on the scene
restricted to them and the instances they rest on or that rest on them).
"""

from __future__ import annotations

import logging
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stages.scene.checkcache import CheckCache, content_hash
from stages.scene.support import (  # noqa: F401  (clip_convex, signed_inside: this module's surface before)
    BASE_TOL, GAP_TOL, REST_GAP, REST_MARGIN, clip_convex, contact_region, signed_inside, world_com,
)

log = logging.getLogger(__name__)

@dataclass(frozen=True)
class RestProof:
    """proven: instances shown to stay at rest (or fixed); unproven: instance -> why not;
    margin: instance -> distance of its combined center of mass inside its contact region [m]."""

    proven: tuple[str, ...]
    unproven: dict[str, str]
    margin: dict[str, float]


def analytic_rest(pop, needs_package_check, *, margin: float = REST_MARGIN) -> RestProof:
    """See the module docstring. ``pop``: a populated ``stages.scene.solver.Populator``;
    ``needs_package_check(inst) -> str | None``: why the instance's package is not known to rest
    on a flat floor (None: it is)."""
    insts = {i.p.inst: i for i in pop.insts}
    children: dict[str, list[str]] = {}
    for i in pop.insts:
        if i.p.support:
            children.setdefault(i.p.support, []).append(i.p.inst)

    def load(name: str) -> tuple[float, np.ndarray]:
        """(mass [kg], center of mass (3,)) of the instance and all that rests on it."""
        i = insts[name]
        m, c = max(i.geo.mass, 1e-9), world_com(i) * max(i.geo.mass, 1e-9)
        for k in children.get(name, ()):
            mk, ck = load(k)
            m, c = m + mk, c + ck * mk
        return m, c / m

    def unknown_mass(name: str) -> bool:
        """Whether a dynamic instance in the stack rooted at ``name`` has no authored mass."""
        i = insts[name]
        return (i.geo.dynamic and not i.geo.mass > 0) or any(unknown_mass(k) for k in children.get(name, ()))

    unproven: dict[str, str] = {}
    margins: dict[str, float] = {}
    for name, i in insts.items():
        why = needs_package_check(i)
        if why:
            unproven[name] = why
            continue
        if not i.geo.dynamic:
            continue
        floor_top = pop.room_ctx[i.p.room].elevation if i.p.room in pop.room_ctx else None
        region, why = contact_region(i, insts.get(i.p.support) if i.p.support else None, floor_top)
        if region is None:
            unproven[name] = why
            continue
        if unknown_mass(name):
            unproven[name] = "mass properties not authored on every body of the stack (center of mass unknown)"
            continue
        _, com = load(name)
        d = signed_inside(com[:2], region)
        margins[name] = d
        if d < margin:
            unproven[name] = f"center of mass {d * 1000:.1f} mm inside its contact region (< {margin * 1000:.0f} mm)"
    # a support that is not proven takes what rests on it along
    changed = True
    while changed:
        changed = False
        for name, i in insts.items():
            if name not in unproven and i.p.support in unproven:
                unproven[name] = f"its support {i.p.support} is not proven"
                changed = True
    proven = tuple(sorted(n for n in insts if n not in unproven))
    return RestProof(proven=proven, unproven=unproven, margin=margins)


def to_simulate(pop, unproven: Sequence[str]) -> list[str]:
    """The unproven instances with everything in their support trees (what they rest on, down to
    the floor, and what rests on those), sorted."""
    sup = {i.p.inst: i.p.support for i in pop.insts}
    roots = set()
    for n in unproven:
        while sup.get(n):
            n = sup[n]
        roots.add(n)
    out = set()
    for i in pop.insts:
        n = i.p.inst
        while sup.get(n):
            n = sup[n]
        if n in roots:
            out.add(i.p.inst)
    return sorted(out)


def package_rest(usd_path: Path, geo, cache: CheckCache, *, tolerance: float = 0.01) -> dict:
    """The package alone on a flat floor, ``REST_GAP`` above it, settled as the scene settle check
    does (``stages.scene.settle.settle_check``): {"passed": bool, "moved": largest displacement
    [m]}. Computed once per package content (``cache`` kind ``rest``)."""
    key = content_hash(Path(usd_path).parent)
    got = cache.get("rest", key)
    if got is not None:
        return got
    from stages.scene.settle import settle_check

    with tempfile.TemporaryDirectory(prefix="aw_rest_") as d:
        scene = write_floor_scene(Path(d), Path(usd_path), geo)
        rep = settle_check(scene, tolerance=tolerance)
    val = {"passed": bool(rep.passed), "moved": max(rep.moved.values(), default=0.0)}
    cache.put("rest", key, val)
    log.debug("package rest %s: %s", usd_path, val)
    return val


def write_floor_scene(folder: Path, usd_path: Path, geo) -> Path:
    """A scene USD in ``folder``: a 10 m floor box (top at z = 0) and the package referenced as
    /World/Objects/asset, its lowest point ``REST_GAP`` above the floor."""
    from pxr import Gf, Sdf

    from stages.scene.compose import _attr, _layer_meta, _prim, _rel

    layer = Sdf.Layer.CreateAnonymous(".usda")
    with Sdf.ChangeBlock():
        _layer_meta(layer, default_prim="World")
        world = _prim(layer.pseudoRoot, "World", "Xform")
        ps = _prim(world, "PhysicsScene", "PhysicsScene")
        _attr(ps, "physics:gravityDirection", "Vector3f", Gf.Vec3f(0.0, 0.0, -1.0))
        _attr(ps, "physics:gravityMagnitude", "Float", 9.81)
        lay = _prim(world, "Layout", "Xform")
        floor = _prim(lay, "Floor", "Cube", apis=["PhysicsCollisionAPI"])
        _attr(floor, "size", "Double", 1.0)
        _attr(floor, "xformOp:translate", "Double3", Gf.Vec3d(0.0, 0.0, -0.05))
        _attr(floor, "xformOp:scale", "Float3", Gf.Vec3f(10.0, 10.0, 0.1))
        from pxr import Vt

        _attr(floor, "xformOpOrder", "TokenArray", Vt.TokenArray(["xformOp:translate", "xformOp:scale"]), uniform=True)
        objs = _prim(world, "Objects", "Xform")
        a = _prim(objs, "asset", "Xform")
        a.referenceList.Prepend(Sdf.Reference(_rel(usd_path, folder)))
        _attr(a, "xformOp:translate", "Double3", Gf.Vec3d(0.0, 0.0, REST_GAP - float(geo.lo[2])))
        _attr(a, "xformOpOrder", "TokenArray", Vt.TokenArray(["xformOp:translate"]), uniform=True)
    path = folder / "scene.usda"
    layer.Export(str(path))
    return path
