"""URDF -> AssetModel.

Parsed with ``xml.etree`` after rejecting any DOCTYPE/ENTITY (no entity expansion). Supported: links with
visual and collision geometry (mesh: STL/OBJ/PLY/glTF via trimesh, DAE by a built-in reader, ``scale``;
box, cylinder, sphere and the common ``capsule`` extension), origins, materials (``color rgba``,
``texture filename``; named robot-level materials), inertials, and revolute / continuous / prismatic /
fixed joints with axis, limits (lower, upper, effort, velocity) and dynamics (damping, friction, and
the extensions ``spring_stiffness``: a hinge spring towards joint value 0 [N m/rad or N/m], as
Gazebo's ``spring_stiffness`` with ``spring_reference`` 0, and ``armature``: the mechanism's added
inertia [kg m^2 or kg], as MuJoCo's joint armature), and on ``<limit>`` the extension ``solreflimit``
("time_constant damping_ratio", both > 0): the limit stops as MuJoCo's joint ``solreflimit``.
``mimic`` is ignored (logged); floating and planar joints are rejected. A link's ``<contact>`` (the
common URDF extension of PyBullet and others) gives it its own contact properties (``Link.contact``):
``lateral_friction`` [-], ``spinning_friction`` (torsional) [m], ``rolling_friction`` [m] and
``restitution`` [-], each ``value="..."``, finite and >= 0; its other children are ignored (logged).

Mesh filenames: ``package://<pkg>/<rest>`` is looked up in the URDF's folder and each ancestor (as
``<ancestor>/<pkg>/<rest>``, or ``<ancestor>/<rest>`` where the ancestor is itself named ``<pkg>``),
never above ``catalog_dir``; ``file://`` and plain paths are taken relative to the URDF's folder. With a
``catalog_dir`` every resolved file must lie inside it (after following symbolic links).

Collision: each ``<collision>`` becomes a part of the link's ``collision_source``; when the URDF has
collision elements, links without one get ``collision_source = ()`` (they do not collide); a URDF
without any keeps ``None`` (colliders are then computed from the visuals).

Frames: a link's frame is its parent joint's frame at zero; link poses are composed into the root
link's frame. A fixed joint from a link named ``world`` fixes the base, a floating one leaves it movable
(either way that link is dropped); the annotation's ``fixed_base`` overrides both.
"""

from __future__ import annotations

import hashlib
import logging
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from asset_catalog.annotations import AssetAnnotation
from asset_catalog.asset_model import AssetModel, ContactSpec, Joint, JointType, Link, MaterialSpec, MeshPart
from pipeline.types import ItemError
from stages.loaders import _geom as g
from stages.loaders._inertia import judge_masses, mass_properties
from stages.loaders._meshfiles import load_mesh_file

log = logging.getLogger(__name__)

_JOINT_TYPES = {"revolute": JointType.REVOLUTE, "continuous": JointType.REVOLUTE,
                "prismatic": JointType.PRISMATIC, "fixed": JointType.FIXED}
WORLD = "world"


@dataclass
class _Ctx:
    file: Path
    catalog_dir: Path | None
    materials: dict[str, MaterialSpec] = field(default_factory=dict)   # by output name
    named: dict[str, MaterialSpec] = field(default_factory=dict)       # robot-level, by source name
    mat_names: g.NameTable = field(default_factory=g.NameTable)
    mesh_cache: dict[Path, list[g.RawMesh]] = field(default_factory=dict)


def load_urdf(path: Path, annotation: AssetAnnotation, *, catalog_dir: Path | None = None) -> AssetModel:
    """Load a URDF file into an AssetModel (links[0] is the root; joints in tree order).

    ``catalog_dir``: the catalog folder; mesh and texture paths may not leave it (None: no check).
    Raises ItemError with a one-line reason naming the file for malformed XML, a DOCTYPE, missing or
    duplicate names, cycles, several roots, non-finite numbers, zero axes, lower > upper, unsupported
    joint types, missing or escaping mesh files.
    """
    path = Path(path)
    root = g.read_xml(path)
    if root.tag != "robot":
        raise ItemError(f"{path}: root element is <{root.tag}>, expected <robot>")
    ctx = _Ctx(file=path, catalog_dir=catalog_dir)
    for m in root.findall("material"):
        spec = _material(m, ctx)
        if spec is not None and m.get("name"):
            ctx.named[m.get("name")] = spec
    link_els = _unique(root.findall("link"), "link", path)
    joint_els = _unique(root.findall("joint"), "joint", path)
    joints = [_joint(j, path) for j in joint_els.values()]
    for j in joints:
        for end in ("parent", "child"):
            if getattr(j, end) not in link_els:
                raise ItemError(f"{path}: joint {j.name!r} names {end} link {getattr(j, end)!r}, "
                                "which does not exist")
    order, parent_joint = _tree(link_els, joints, path)
    fixed_base = annotation.fixed_base
    if order[0] == WORLD and not _has_geometry(link_els[WORLD]):
        world_joints = [j for j in joints if j.parent == WORLD]
        if len(world_joints) == 1 and world_joints[0].type == JointType.FIXED:
            order = order[1:]
            del parent_joint[world_joints[0].child]
            joints = [j for j in joints if j is not world_joints[0]]
            fixed_base = (not world_joints[0].floating) if fixed_base is None else fixed_base
    floating = [j.name for j in joints if j.floating]
    if floating:
        raise ItemError(f"{path}: floating joint {floating[0]!r} is only supported from the 'world' link "
                        "to the root (a movable base)")
    if fixed_base is None:
        fixed_base = WORLD in link_els
    names = g.NameTable()
    out_name = {src: names.add(src, "link") for src in order}
    jnames = g.NameTable()
    links, out_joints, world_of = [], [], {}
    for src in order:
        pj = parent_joint.get(src)
        world_of[src] = np.eye(4) if pj is None else world_of[pj.parent] @ pj.frame_matrix
        links.append(_link(link_els[src], out_name[src], world_of[src], ctx))
        if pj is not None:
            out_joints.append(pj.to_joint(jnames.add(pj.name, "joint"), out_name[pj.parent], out_name[src]))
    model = AssetModel(name=annotation.id, annotation=annotation, links=tuple(links),
                       joints=tuple(out_joints),
                       materials=dict(ctx.materials), fixed_base=bool(fixed_base),
                       source_sha256=hashlib.sha256(path.read_bytes()).hexdigest())
    return judge_masses(g.source_defines_collision(
        g.scale_and_up(model, annotation.meters_per_unit, annotation.up_axis)))


# ------------------------------------------------------------------------------------------ structure


def _unique(elements: list[ET.Element], kind: str, path: Path) -> dict[str, ET.Element]:
    out: dict[str, ET.Element] = {}
    for el in elements:
        name = el.get("name")
        if not name:
            raise ItemError(f"{path}: a <{kind}> has no name")
        if name in out:
            raise ItemError(f"{path}: duplicate {kind} name {name!r}")
        out[name] = el
    if kind == "link" and not out:
        raise ItemError(f"{path}: no <link> elements")
    return out


@dataclass(frozen=True)
class _SrcJoint:
    name: str
    type: JointType
    parent: str
    child: str
    frame_matrix: np.ndarray
    axis: tuple[float, float, float]
    lower: float | None
    upper: float | None
    effort: float | None
    velocity: float | None
    damping: float
    friction: float
    stiffness: float = 0.0
    armature: float = 0.0
    limit_solref: tuple[float, float] | None = None
    floating: bool = False     # a 'floating' joint, kept only as world -> root (a movable base)

    def to_joint(self, name: str, parent: str, child: str) -> Joint:
        return Joint(name=name, type=self.type, parent=parent, child=child,
                     frame=g.pose_of(self.frame_matrix),
                     axis=self.axis, lower=self.lower, upper=self.upper, max_effort=self.effort,
                     max_velocity=self.velocity, friction=self.friction, damping=self.damping,
                     stiffness=self.stiffness, armature=self.armature, limit_solref=self.limit_solref)


def _origin(el: ET.Element | None, path: Path, what: str) -> np.ndarray:
    if el is None:
        return np.eye(4)
    xyz = g.parse_floats(el.get("xyz"), 3, file=path, what=f"{what} origin xyz", default=(0.0, 0.0, 0.0))
    rpy = g.parse_floats(el.get("rpy"), 3, file=path, what=f"{what} origin rpy", default=(0.0, 0.0, 0.0))
    return g.transform(xyz, g.rpy_matrix(rpy))


def _opt_float(el: ET.Element | None, attr: str, path: Path, what: str) -> float | None:
    if el is None or el.get(attr) is None:
        return None
    return g.parse_floats(el.get(attr), 1, file=path, what=f"{what} {attr}")[0]


def _joint(el: ET.Element, path: Path) -> _SrcJoint:
    name = el.get("name")
    what = f"joint {name!r}"
    kind = el.get("type", "")
    floating = kind == "floating"
    kind = "fixed" if floating else kind
    if kind not in _JOINT_TYPES:
        raise ItemError(f"{path}: {what} has unsupported type {kind!r} "
                        "(revolute, continuous, prismatic, fixed)")
    parent, child = el.find("parent"), el.find("child")
    if parent is None or child is None or not parent.get("link") or not child.get("link"):
        raise ItemError(f"{path}: {what} lacks a parent or child link")
    axis = np.array(g.parse_floats((el.find("axis").get("xyz") if el.find("axis") is not None else None), 3,
                                   file=path, what=f"{what} axis", default=(1.0, 0.0, 0.0)))
    jt = _JOINT_TYPES[kind]
    if jt != JointType.FIXED:
        n = float(np.linalg.norm(axis))
        if n < 1e-9:
            raise ItemError(f"{path}: {what} has a zero axis")
        axis = axis / n
    limit = el.find("limit")
    lower = upper = None
    if kind in ("revolute", "prismatic"):
        if limit is None:
            raise ItemError(f"{path}: {what} ({kind}) has no <limit>")
        lower = _opt_float(limit, "lower", path, what) or 0.0
        upper = _opt_float(limit, "upper", path, what) or 0.0
        if lower > upper:
            raise ItemError(f"{path}: {what} has lower limit {lower} > upper limit {upper}")
    dyn = el.find("dynamics")
    solref = None
    if limit is not None and limit.get("solreflimit") is not None and jt != JointType.FIXED:
        tc, dr = g.parse_floats(limit.get("solreflimit"), 2, file=path, what=f"{what} solreflimit")
        if not (tc > 0 and dr > 0):
            raise ItemError(f"{path}: {what} solreflimit must be two positive numbers (got {tc}, {dr})")
        solref = (float(tc), float(dr))
    if el.find("mimic") is not None:
        log.info("%s: %s: <mimic> ignored (the joint is kept as an independent joint)", path, what)
    effort = _opt_float(limit, "effort", path, what) if jt != JointType.FIXED else None
    velocity = _opt_float(limit, "velocity", path, what) if jt != JointType.FIXED else None
    return _SrcJoint(name=name, type=jt, parent=parent.get("link"), child=child.get("link"),
                     frame_matrix=_origin(el.find("origin"), path, what),
                     axis=tuple(float(a) for a in axis), lower=lower, upper=upper,
                     effort=effort if effort and effort > 0 else None,
                     velocity=velocity if velocity and velocity > 0 else None,
                     damping=max(_opt_float(dyn, "damping", path, what) or 0.0, 0.0),
                     friction=max(_opt_float(dyn, "friction", path, what) or 0.0, 0.0),
                     stiffness=max(_opt_float(dyn, "spring_stiffness", path, what) or 0.0, 0.0),
                     armature=max(_opt_float(dyn, "armature", path, what) or 0.0, 0.0), limit_solref=solref,
                     floating=floating)


def _tree(links: dict[str, ET.Element], joints: list[_SrcJoint], path: Path
          ) -> tuple[list[str], dict[str, _SrcJoint]]:
    """Links in depth-first order from the single root, and each non-root link's parent joint."""
    parent_joint: dict[str, _SrcJoint] = {}
    for j in joints:
        if j.child in parent_joint:
            raise ItemError(f"{path}: link {j.child!r} is the child of two joints "
                            f"({parent_joint[j.child].name!r}, {j.name!r})")
        parent_joint[j.child] = j
    for start in links:   # a cycle: following parents returns to a link already seen
        seen, cur = [start], start
        while cur in parent_joint:
            cur = parent_joint[cur].parent
            if cur in seen:
                cyc = seen[seen.index(cur):] + [cur]
                raise ItemError(f"{path}: kinematic cycle: {' -> '.join(reversed(cyc))}")
            seen.append(cur)
    roots = [name for name in links if name not in parent_joint]
    if len(roots) != 1:
        raise ItemError(f"{path}: expected exactly one root link, found {len(roots)}: {', '.join(roots[:8])}")
    children: dict[str, list[str]] = {}
    for j in joints:
        children.setdefault(j.parent, []).append(j.child)
    order, stack = [], [roots[0]]
    while stack:
        cur = stack.pop()
        order.append(cur)
        stack.extend(reversed(children.get(cur, [])))
    return order, parent_joint


def _has_geometry(el: ET.Element) -> bool:
    return el.find("visual") is not None or el.find("collision") is not None


# ------------------------------------------------------------------------------------------- links


def _link(el: ET.Element, name: str, pose: np.ndarray, ctx: _Ctx) -> Link:
    """One link; ``pose``: its 4x4 frame in the root link's frame."""
    visuals, collisions = [], []
    for k, v in enumerate(el.findall("visual")):
        visuals += _geometry_parts(v, f"{name}_visual{k}", ctx, visual=True)
    for k, c in enumerate(el.findall("collision")):
        collisions += _geometry_parts(c, f"{name}_collision{k}", ctx, visual=False)
    mass, from_source = _inertial(el.find("inertial"), name, ctx.file)
    return Link(name=name, pose=g.pose_of(pose), visuals=tuple(visuals),
                collision_source=tuple(collisions) if collisions else None, mass=mass,
                mass_from_source=from_source, contact=_contact(el.find("contact"), name, ctx.file))


_CONTACT_TAGS = {"lateral_friction": "friction", "spinning_friction": "torsional_friction",
                 "rolling_friction": "rolling_friction", "restitution": "restitution"}


def _contact(el: ET.Element | None, link: str, path: Path) -> ContactSpec | None:
    """A link's ``<contact>`` (see the module docstring), or None if it has none we use."""
    if el is None:
        return None
    what = f"link {link!r} contact"
    values = {}
    for child in el:
        field_name = _CONTACT_TAGS.get(child.tag)
        if field_name is None:
            log.info("%s: %s: <%s> ignored", path, what, child.tag)
            continue
        v = _opt_float(child, "value", path, f"{what} {child.tag}")
        if v is None:
            raise ItemError(f"{path}: {what}: <{child.tag}> has no value")
        if not (np.isfinite(v) and v >= 0):
            raise ItemError(f"{path}: {what}: <{child.tag}> must be finite and >= 0, got {v}")
        values[field_name] = v
    return ContactSpec(**values) if values else None


def _inertial(el: ET.Element | None, link: str, path: Path):
    if el is None:
        return None, False
    what = f"link {link!r} inertial"
    t = _origin(el.find("origin"), path, what)
    mass_el = el.find("mass")
    mass = _opt_float(mass_el, "value", path, what)
    ie = el.find("inertia")
    if mass is None or ie is None:
        log.warning("%s: %s without mass or inertia; mass will be computed", path, what)
        return None, False
    vals = {k: _opt_float(ie, k, path, what) or 0.0 for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
    tensor = np.array([[vals["ixx"], vals["ixy"], vals["ixz"]],
                       [vals["ixy"], vals["iyy"], vals["iyz"]],
                       [vals["ixz"], vals["iyz"], vals["izz"]]])
    r = t[:3, :3]
    try:
        mp = mass_properties(mass, t[:3, 3], r @ tensor @ r.T)
    except np.linalg.LinAlgError:
        raise ItemError(f"{path}: {what}: inertia tensor cannot be decomposed") from None
    return mp, True   # judged against the geometry by _geom.judge_masses once units are final


def _geometry_parts(el: ET.Element, base: str, ctx: _Ctx, *, visual: bool) -> list[MeshPart]:
    geo = el.find("geometry")
    if geo is None or len(geo) == 0:
        raise ItemError(f"{ctx.file}: {base}: <geometry> missing or empty")
    shape = geo[0]
    what = f"{base} {shape.tag}"
    t = _origin(el.find("origin"), ctx.file, base)
    if shape.tag == "mesh":
        meshes = _mesh(shape, ctx, what)
    elif shape.tag == "box":
        meshes = [g.box(np.array(g.parse_floats(shape.get("size"), 3, file=ctx.file, what=what)) / 2.0)]
    elif shape.tag == "cylinder":
        r, length = _pos_floats(shape, ("radius", "length"), ctx.file, what)
        meshes = [g.cylinder(r, length / 2.0)]
    elif shape.tag == "capsule":
        r, length = _pos_floats(shape, ("radius", "length"), ctx.file, what)
        meshes = [g.capsule(r, length / 2.0)]
    elif shape.tag == "sphere":
        (r,) = _pos_floats(shape, ("radius",), ctx.file, what)
        meshes = [g.ellipsoid((r, r, r))]
    else:
        raise ItemError(f"{ctx.file}: {base}: unsupported geometry <{shape.tag}>")
    spec = None
    if visual:
        mat_el = el.find("material")
        spec = _material(mat_el, ctx) if mat_el is not None else None
        if spec is None and mat_el is not None and mat_el.get("name") in ctx.named:
            spec = ctx.named[mat_el.get("name")]
    parts = []
    for k, m in enumerate(meshes):
        m = m.transformed(t)
        name = base if len(meshes) == 1 else f"{base}_{k}"
        mat = None
        if visual:   # a mesh file's own material wins over a URDF colour; a URDF texture wins over both
            use_file = m.material is not None and (spec is None or spec.base_color_texture is None)
            chosen = m.material if use_file else spec
            mat = _register(chosen, ctx) if chosen is not None else None
            if mat is not None and m.uvs is None and ctx.materials[mat].base_color_texture is not None:
                m = g.box_uvs(m)
        parts.append(m.part(name, mat))
    return parts


def _pos_floats(el: ET.Element, attrs: tuple[str, ...], path: Path, what: str) -> tuple[float, ...]:
    out = []
    for a in attrs:
        v = g.parse_floats(el.get(a), 1, file=path, what=f"{what} {a}")[0]
        if v <= 0:
            raise ItemError(f"{path}: {what} {a} must be > 0, got {v}")
        out.append(v)
    return tuple(out)


def _mesh(el: ET.Element, ctx: _Ctx, what: str) -> list[g.RawMesh]:
    uri = el.get("filename")
    if not uri:
        raise ItemError(f"{ctx.file}: {what} has no filename")
    scale = g.parse_floats(el.get("scale"), None, file=ctx.file, what=f"{what} scale",
                           default=(1.0, 1.0, 1.0))
    if len(scale) == 1:
        scale = scale * 3
    if len(scale) != 3 or min(abs(s) for s in scale) <= 0:
        raise ItemError(f"{ctx.file}: {what} scale must be 1 or 3 non-zero numbers, got {el.get('scale')!r}")
    file = resolve_uri(uri, ctx.file, ctx.catalog_dir)
    if file not in ctx.mesh_cache:
        ctx.mesh_cache[file] = load_mesh_file(file, source=ctx.file, catalog_dir=ctx.catalog_dir)
    return [m.scaled(scale) for m in ctx.mesh_cache[file]]


def resolve_uri(uri: str, urdf: Path, catalog_dir: Path | None) -> Path:
    """The file a URDF filename names (see the module docstring); ItemError if not found or escaping."""
    urdf_dir = urdf.parent.resolve()
    if uri.startswith("package://"):
        rest = uri[len("package://"):]
        pkg, _, sub = rest.partition("/")
        stop = Path(catalog_dir).resolve() if catalog_dir is not None else None
        cur = urdf_dir
        while True:
            for cand in (cur / pkg / sub, cur / sub if cur.name == pkg else None):
                if cand is None:
                    continue
                cand = g.inside_catalog(Path(os.path.normpath(cand)), catalog_dir, source=urdf,
                                        what="mesh path")
                if cand.exists():
                    return cand
            if cur == stop or cur.parent == cur:
                break
            cur = cur.parent
        raise ItemError(f"{urdf}: cannot resolve {uri!r} in the URDF's folder or its ancestors"
                        + (" within the catalog" if catalog_dir is not None else ""))
    raw = uri[len("file://"):] if uri.startswith("file://") else uri
    p = Path(raw)
    p = p if p.is_absolute() else urdf_dir / p
    resolved = g.inside_catalog(p, catalog_dir, source=urdf, what="mesh path")
    if not resolved.exists():
        raise ItemError(f"{urdf}: mesh file not found: {uri!r}")
    return resolved


def _material(el: ET.Element | None, ctx: _Ctx) -> MaterialSpec | None:
    if el is None:
        return None
    color, tex = el.find("color"), el.find("texture")
    if color is None and tex is None:
        return None
    rgba = g.parse_floats(color.get("rgba") if color is not None else None, 4, file=ctx.file,
                          what=f"material {el.get('name')!r} rgba", default=(1.0, 1.0, 1.0, 1.0))
    texture = None
    if tex is not None and tex.get("filename"):
        try:
            texture = resolve_uri(tex.get("filename"), ctx.file, ctx.catalog_dir)
        except ItemError as e:
            if "escapes" in str(e):
                raise
            log.warning("%s; colour only", e)
    return MaterialSpec(name=el.get("name") or "material",
                        base_color=tuple(float(np.clip(c, 0, 1)) for c in rgba[:3]),
                        opacity=float(np.clip(rgba[3], 0, 1)), base_color_texture=texture)


def _register(spec: MaterialSpec, ctx: _Ctx) -> str:
    """Add a material (deduplicated by content) and return its key in AssetModel.materials."""
    for key, existing in ctx.materials.items():
        if _same(existing, spec):
            return key
    key = ctx.mat_names.add(spec.name, "material")
    from dataclasses import replace

    ctx.materials[key] = replace(spec, name=key)
    return key


def _same(a: MaterialSpec, b: MaterialSpec) -> bool:
    from dataclasses import replace

    return replace(a, name="") == replace(b, name="")
