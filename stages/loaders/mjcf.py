"""MJCF (MuJoCo XML) -> AssetModel.

The file is compiled by MuJoCo itself (``mujoco.MjModel.from_xml_path``), so includes, default classes,
``<compiler angle/meshdir/texturedir/eulerseq>``, ``fromto`` and inertia-from-geometry behave exactly as in
MuJoCo; the compiled model is read at its reference configuration ``qpos0``.

One MJCF file is one asset. Its root link is the world body's one child body, unless that body is
hinged or slid to the world, or the world body has several child bodies (both common in public
packages): then the world is wrapped in a fixed parent link named ``world`` at the world origin (like
a URDF's world link), which holds the world body's own geoms (planes still skipped); jointless
top-level bodies merge into it and jointed ones hang from it by their joint. Such an asset has a fixed
base unless the annotation's ``fixed_base`` says otherwise; a free joint on a top-level body beside
others raises ItemError (several loose objects are not one asset). For one asset per top-level body,
give each entry the annotation's ``mjcf_body``: the asset is then that body and its children only (the
world body's geoms are left out), with the rules above for one top-level body.

Bodies and joints:
- a body with one hinge or slide joint becomes a link with a revolute / prismatic joint whose frame is
  the body frame moved to the joint's anchor (``pos``); limits are ``range`` relative to ``qpos0``
  (None where not ``limited``); ``damping``, ``frictionloss`` and ``stiffness`` (a passive spring towards
  the reference position, kept as drive stiffness with target 0) and ``armature`` carry over;
  the joint's ``actuatorfrcrange``, else the ``forcerange`` x gear of the actuators on it, gives the
  effort limit (actuator gains are not carried);
- a body without joints is welded to its parent: its geoms and inertia merge into the parent's link;
- a free joint on the root body means a movable base; without one the base is fixed (the annotation's
  ``fixed_base`` overrides both); a free joint elsewhere, a ball joint, or several joints in one body
  raise ItemError (not representable as one revolute/prismatic joint per link);
- sites, tendons, equality constraints (e.g. the coupled knobs of the oven), actuators and sensors are
  ignored with a log line.

Geoms -> MeshParts in their link's frame (a colliding mesh geom's collision part is its convex hull,
which is what MuJoCo collides; its visual part is the full mesh). MuJoCo stores mesh vertices re-centred in the geom frame, so
the geom's compiled pose is applied. Primitives (box, sphere, capsule, cylinder, ellipsoid) are
tessellated; planes, height fields and SDFs are skipped with a log line. A geom collides when its
``contype`` or ``conaffinity`` is non-zero; it becomes a collision source. It is a visual when it does
not collide, lies in group 0-2 and is not fully transparent, or when it collides and its link has no
visual-only geoms (sources whose geoms serve both roles, such as robosuite's door). Colours come from
the geom's material (``rgba``, and the image file of its RGB texture) or the geom's ``rgba``; meshes
without texture coordinates under a textured material get box-projected UVs. When some geom collides,
links without colliding geoms get ``collision_source = ()`` (they do not collide, as in MuJoCo); a source
without colliding geoms keeps ``None`` (colliders are then computed from the visuals).

Body-chain fragments: a source whose root element is ``<mujocoinclude>`` holding bodies (e.g. furniture_sim's
``kettle/kettle_body0.xml``) is compiled through a wrapper written into a temporary folder: it includes
the ``*asset*.xml`` fragments beside the source and the source itself by absolute path, with
``meshdir``/``texturedir`` set to the nearest folder (from the source's folder up to the catalog folder)
in which every file those fragments name exists. The wrapper is deleted after compiling; nothing is
written into the catalog.

Paths: every ``<include>`` (followed recursively before compiling) and every mesh/texture/height-field
file MuJoCo read must lie inside ``catalog_dir`` when one is given.
"""

from __future__ import annotations

import hashlib
import logging
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field, replace
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from asset_catalog.annotations import AssetAnnotation
from asset_catalog.asset_model import AssetModel, Joint, JointType, Link, MaterialSpec, MeshPart
from pipeline.types import ItemError
from stages.loaders import _geom as g
from stages.loaders._inertia import combine_mass, judge_masses, mass_properties

log = logging.getLogger(__name__)

_MAX_INCLUDE_DEPTH = 16


def load_mjcf(path: Path, annotation: AssetAnnotation, *, catalog_dir: Path | None = None) -> AssetModel:
    """Compile an MJCF file with MuJoCo and convert it to an AssetModel (links[0] is the root).

    ``catalog_dir``: the catalog folder; included files and mesh/texture files may not leave it.
    Raises ItemError (one line, naming the file) when the file does not compile (MuJoCo's message),
    escapes the catalog, has no body or several free ones, or uses joints that cannot be represented.
    """
    import mujoco

    path = Path(path)
    root = g.read_xml(path)
    _check_includes(root, path, path, catalog_dir, 0)
    if root.tag == "mujocoinclude":
        model = _compile_fragment(path, root, catalog_dir)
    elif root.tag == "mujoco":
        model = _compile(path, path)
    else:
        raise ItemError(f"{path}: root element is <{root.tag}>, expected <mujoco>")
    _check_files(model, path, catalog_dir)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    model_out = _Extractor(model, data, path, annotation).run()
    model_out = replace(model_out, source_sha256=hashlib.sha256(path.read_bytes()).hexdigest())
    return judge_masses(g.source_defines_collision(
        g.scale_and_up(model_out, annotation.meters_per_unit, annotation.up_axis)))


# --------------------------------------------------------------------------------------- compiling


def _one_line(e: Exception) -> str:
    return " ".join(str(e).split())


def _compile(xml_path: Path, source: Path):
    import mujoco

    try:
        return mujoco.MjModel.from_xml_path(str(xml_path))
    except (ValueError, mujoco.FatalError) as e:
        raise ItemError(f"{source}: MJCF does not compile: {_one_line(e)}") from None


def _check_includes(root: ET.Element, file: Path, main: Path, catalog_dir: Path | None, depth: int) -> None:
    """Every <include file> (recursively) stays inside the catalog; resolution relative to the main file's
    folder and to the including file's folder are both checked."""
    if depth > _MAX_INCLUDE_DEPTH:
        raise ItemError(f"{main}: includes nested deeper than {_MAX_INCLUDE_DEPTH}")
    for inc in root.iter("include"):
        name = inc.get("file")
        if not name:
            raise ItemError(f"{file}: <include> without a file")
        for base in dict.fromkeys((main.parent, file.parent)):
            cand = Path(name) if Path(name).is_absolute() else base / name
            resolved = g.inside_catalog(cand, catalog_dir, source=main, what="included file")
            if resolved.is_file():
                _check_includes(g.read_xml(resolved), resolved, main, catalog_dir, depth + 1)


def _check_files(model, source: Path, catalog_dir: Path | None) -> None:
    """Mesh, texture and height-field files MuJoCo read must lie inside the catalog."""
    if catalog_dir is None:
        return
    paths = bytes(model.paths)
    for adrs in (model.mesh_pathadr, model.tex_pathadr, model.hfield_pathadr):
        for adr in adrs:
            if adr < 0:
                continue
            name = paths[adr:].split(b"\0", 1)[0].decode(errors="replace")
            if name:
                g.inside_catalog(Path(name), catalog_dir, source=source, what="asset file")


def _compile_fragment(path: Path, root: ET.Element, catalog_dir: Path | None):
    """Compile a body-chain ``<mujocoinclude>`` through a temporary wrapper (see the module docstring)."""
    if root.find("body") is None:
        raise ItemError(f"{path}: <mujocoinclude> fragment without a top-level <body>; name the MJCF "
                        "file that includes it")
    assets = sorted(p for p in path.parent.glob("*.xml") if p != path and "asset" in p.stem.lower())
    asset_roots = [g.read_xml(p) for p in assets]
    for p, r in zip(assets, asset_roots):
        _check_includes(r, p, path, catalog_dir, 0)
    base = _fragment_base(path, asset_roots, catalog_dir)
    parts = [f"<mujoco model={quoteattr(path.stem)}>"]
    parts += [f"<include file={quoteattr(str(p.resolve()))}/>" for p in assets]
    parts.append(f"<compiler meshdir={quoteattr(str(base))} texturedir={quoteattr(str(base))}/>")
    parts.append(f"<worldbody><include file={quoteattr(str(path.resolve()))}/></worldbody></mujoco>")
    log.info("%s: body-chain fragment compiled through a wrapper including %s (files relative to %s)",
             path, ", ".join(p.name for p in assets) or "no asset fragment", base)
    with tempfile.TemporaryDirectory(prefix="agentworld_mjcf_") as tmp:
        wrapper = Path(tmp) / "wrapper.xml"
        wrapper.write_text("\n".join(parts), encoding="utf-8")
        return _compile(wrapper, path)


def _fragment_base(path: Path, asset_roots: list[ET.Element], catalog_dir: Path | None) -> Path:
    """Nearest folder, from the fragment's own upwards (not above the catalog), where every file named
    by the asset fragments exists."""
    names = [el.get("file") for r in asset_roots for el in r.iter()
             if el.tag in ("mesh", "texture", "hfield", "skin") and el.get("file")]
    stop = Path(catalog_dir).resolve() if catalog_dir is not None else None
    cur = path.parent.resolve()
    while True:
        if all((cur / n).is_file() for n in names):
            return cur
        if cur == stop or cur.parent == cur:
            break
        cur = cur.parent
    raise ItemError(f"{path}: fragment's asset files ({', '.join(names[:3])}...) not found relative to its "
                    "folder or any parent folder in the catalog")


# -------------------------------------------------------------------------------------- extraction


@dataclass
class _LinkAcc:
    """What gathers into one output link: its frame in the world at qpos0 (4x4), geoms and masses."""

    name: str
    world: np.ndarray
    body: int
    visuals: list[MeshPart] = field(default_factory=list)
    collisions: list[MeshPart] = field(default_factory=list)
    masses: list[tuple[float, np.ndarray, np.ndarray]] = field(default_factory=list)
    has_visual_only: bool = False


class _Extractor:
    """Reads a compiled MjModel (+ MjData after mj_kinematics at qpos0) into an AssetModel."""

    def __init__(self, model, data, path: Path, annotation: AssetAnnotation) -> None:
        self.m, self.d, self.path, self.annotation = model, data, path, annotation
        self.materials: dict[str, MaterialSpec] = {}
        self.mat_key: dict[tuple, str] = {}
        self.mat_names = g.NameTable()

    def run(self) -> AssetModel:
        import mujoco

        m = self.m
        top = [b for b in range(1, m.nbody) if m.body_parentid[b] == 0]
        if not top:
            raise ItemError(f"{self.path}: no body in <worldbody> (one asset per file needs one)")
        inside = set(range(1, m.nbody))
        if self.annotation.mjcf_body is not None:    # one asset per top-level body: this one's subtree
            top = [self._top_body(top, self.annotation.mjcf_body)]
            inside = set(top)
            for b in range(top[0] + 1, m.nbody):      # MuJoCo numbers parents before their children
                if int(m.body_parentid[b]) in inside:
                    inside.add(b)
        hinged = m.body_jntnum[top[0]] >= 1 and int(m.jnt_type[m.body_jntadr[top[0]]]) in (
            int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
        wrap = len(top) > 1 or bool(hinged)
        self._log_ignored()
        names, jnames = g.NameTable(), g.NameTable()
        accs: list[_LinkAcc] = []
        link_of: dict[int, int] = {}
        joints: list[tuple[int, int, int]] = []     # (joint id, parent acc, child acc)
        free_root = False
        if wrap:    # a fixed parent link standing in for the world (see the module docstring)
            accs.append(_LinkAcc(name=names.add("world", "world"), world=np.eye(4), body=0))
            link_of[0] = 0
            log.info("%s: %s; wrapped in a fixed parent link %r", self.path,
                     f"{len(top)} top-level bodies" if len(top) > 1 else "root body jointed to the world",
                     accs[0].name)
        for b in sorted(inside):
            jids = list(range(m.body_jntadr[b], m.body_jntadr[b] + m.body_jntnum[b]))
            kinds = [int(m.jnt_type[j]) for j in jids]
            bname = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b)
            what = f"body {bname or b!r}"
            if len(jids) > 1:
                raise ItemError(f"{self.path}: {what} has {len(jids)} joints; "
                                "one hinge or slide per body is supported")
            if kinds and kinds[0] == mujoco.mjtJoint.mjJNT_BALL:
                raise ItemError(f"{self.path}: {what} has a ball joint, which is not supported")
            if kinds and kinds[0] == mujoco.mjtJoint.mjJNT_FREE:
                if b != top[0] or wrap:
                    where = "beside other top-level bodies" if b in top else "below the root body"
                    raise ItemError(f"{self.path}: {what} has a free joint {where} (a second object; "
                                    "one asset per file, or per top-level body with mjcf_body)")
                free_root = True
                kinds, jids = [], []
            body_world = g.transform(self.d.xpos[b], self.d.xmat[b].reshape(3, 3))
            if (b == top[0] and not wrap) or jids:
                t = body_world @ g.transform(m.jnt_pos[jids[0]]) if jids else body_world
                fallback = "base" if b == top[0] and not wrap else f"body{b}"
                accs.append(_LinkAcc(name=names.add(bname, fallback), world=t, body=b))
                link_of[b] = len(accs) - 1
                if jids:
                    joints.append((jids[0], link_of[int(m.body_parentid[b])], link_of[b]))
            else:
                link_of[b] = link_of[int(m.body_parentid[b])]
            self._mass(b, accs[link_of[b]])
        self._geoms(accs, {b: a for b, a in link_of.items() if b != 0 or self.annotation.mjcf_body is None})
        root_inv = g.inverse(accs[0].world)
        links = [self._link(a, root_inv) for a in accs]
        out_joints = [self._joint(j, accs[p], accs[c], jnames) for j, p, c in joints]
        fixed = self.annotation.fixed_base if self.annotation.fixed_base is not None else not free_root
        return AssetModel(name=self.annotation.id, annotation=self.annotation, links=tuple(links),
                          joints=tuple(out_joints), materials=dict(self.materials), fixed_base=bool(fixed))

    def _top_body(self, top: list[int], name: str) -> int:
        import mujoco

        names = {mujoco.mj_id2name(self.m, mujoco.mjtObj.mjOBJ_BODY, b): b for b in top}
        if name not in names:
            raise ItemError(f"{self.path}: mjcf_body {name!r} is not a top-level body; those are "
                            f"{', '.join(repr(n) for n in names if n) or 'unnamed'}")
        return names[name]

    def _log_ignored(self) -> None:
        m = self.m
        ignored = {"sites": m.nsite, "tendons": m.ntendon, "equality constraints": m.neq,
                   "actuators": m.nu, "sensors": m.nsensor}
        ignored = {k: int(v) for k, v in ignored.items() if v}
        if ignored:
            log.info("%s: ignored %s", self.path, ", ".join(f"{v} {k}" for k, v in ignored.items()))

    # -- joints and masses

    def _joint(self, j: int, parent: _LinkAcc, child: _LinkAcc, jnames: g.NameTable) -> Joint:
        import mujoco

        m = self.m
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j)
        kind = JointType.REVOLUTE if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE else JointType.PRISMATIC
        axis = np.asarray(m.jnt_axis[j], float)
        n = float(np.linalg.norm(axis))
        if not np.isfinite(axis).all() or n < 1e-9:
            raise ItemError(f"{self.path}: joint {name or j!r} has a zero or non-finite axis")
        q0 = float(m.qpos0[m.jnt_qposadr[j]])
        lower = upper = None
        if m.jnt_limited[j]:
            lower, upper = (float(v) - q0 for v in m.jnt_range[j])
            if lower > upper:
                raise ItemError(f"{self.path}: joint {name or j!r} range lower {lower} > upper {upper}")
        dof = m.jnt_dofadr[j]
        effort = None
        if m.jnt_actfrclimited[j]:
            effort = float(np.max(np.abs(m.jnt_actfrcrange[j]))) or None
        else:   # else the force range of the joint's actuators, times their gear
            limits = [self._actuator_force(a) for a in range(m.nu)
                      if m.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT and m.actuator_trnid[a, 0] == j]
            limits = [f for f in limits if f is not None]
            effort = sum(limits) or None if limits else None
        return Joint(name=jnames.add(name, f"joint{j}"), type=kind, parent=parent.name, child=child.name,
                     frame=g.pose_of(g.inverse(parent.world) @ child.world),
                     axis=tuple(float(a) for a in axis / n),
                     lower=lower, upper=upper, max_effort=effort, friction=float(m.dof_frictionloss[dof]),
                     damping=float(m.dof_damping[dof]), stiffness=float(m.jnt_stiffness[j]),
                     armature=float(m.dof_armature[dof]))

    def _actuator_force(self, a: int) -> float | None:
        """Largest joint force/torque [N] / [N m] actuator ``a`` can apply: its force range, or for a
        plain motor (fixed gain, no bias) its control range x gain; times the gear. None if unbounded."""
        import mujoco

        m = self.m
        gear = abs(float(m.actuator_gear[a, 0]))
        if m.actuator_forcelimited[a]:
            return float(np.max(np.abs(m.actuator_forcerange[a]))) * gear
        if (m.actuator_ctrllimited[a] and m.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_FIXED
                and m.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_NONE):
            ctrl = float(np.max(np.abs(m.actuator_ctrlrange[a])))
            return ctrl * abs(float(m.actuator_gainprm[a, 0])) * gear
        return None

    def _mass(self, b: int, acc: _LinkAcc) -> None:
        mass = float(self.m.body_mass[b])
        if mass <= 0:
            return
        r = self.d.ximat[b].reshape(3, 3)
        acc.masses.append((mass, np.array(self.d.xipos[b]), r @ np.diag(self.m.body_inertia[b]) @ r.T))

    def _link(self, acc: _LinkAcc, root_inv: np.ndarray) -> Link:
        mass, from_source = None, False
        if acc.masses:
            total, com, tensor = combine_mass(acc.masses)         # world frame
            inv = g.inverse(acc.world)
            rot = inv[:3, :3]
            mass = mass_properties(total, rot @ com + inv[:3, 3], rot @ tensor @ rot.T)
            from_source = True
        return Link(name=acc.name, pose=g.pose_of(root_inv @ acc.world), visuals=tuple(acc.visuals),
                    collision_source=tuple(acc.collisions) if acc.collisions else None, mass=mass,
                    mass_from_source=from_source)

    # -- geoms

    def _geoms(self, accs: list[_LinkAcc], link_of: dict[int, int]) -> None:
        import mujoco

        m = self.m
        collides = (m.geom_contype != 0) | (m.geom_conaffinity != 0)
        alpha = np.array(m.geom_rgba[:, 3], float)
        has_mat = m.geom_matid >= 0
        alpha[has_mat] = m.mat_rgba[m.geom_matid[has_mat], 3]
        shown = (m.geom_group <= 2) & (alpha > 0)
        for gid in range(m.ngeom):
            b = int(m.geom_bodyid[gid])
            if b in link_of and not collides[gid] and shown[gid]:
                accs[link_of[b]].has_visual_only = True
        skipped: dict[str, int] = {}
        for gid in range(m.ngeom):
            b = int(m.geom_bodyid[gid])
            if b not in link_of:
                key = "geoms outside the asset's bodies"
                skipped[key] = skipped.get(key, 0) + 1
                continue
            acc = accs[link_of[b]]
            visual = shown[gid] and (not collides[gid] or not acc.has_visual_only)
            if not visual and not collides[gid]:
                continue
            raw = self._geom_mesh(gid)
            if raw is None:
                kind = mujoco.mjtGeom(int(m.geom_type[gid])).name
                skipped[kind] = skipped.get(kind, 0) + 1
                continue
            gname = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, gid)
            geom_world = g.transform(self.d.geom_xpos[gid], self.d.geom_xmat[gid].reshape(3, 3))
            local = g.inverse(acc.world) @ geom_world
            raw = raw.transformed(local)
            g.check_finite_mesh(raw, file=self.path, what=f"geom {gname or gid!r}")
            label = g.NameTable().add(gname, f"geom{gid}")
            if collides[gid]:   # MuJoCo collides a mesh geom as its convex hull: so does the asset
                col = g.convex_hull(raw) if m.geom_type[gid] == mujoco.mjtGeom.mjGEOM_MESH else raw
                acc.collisions.append(col.part(f"{acc.name}_collision_{label}", None))
            if visual:
                key, textured = self._material(gid)
                vis = g.box_uvs(raw, self._texrepeat(gid)) if textured and raw.uvs is None else raw
                acc.visuals.append(vis.part(f"{acc.name}_visual_{label}", key))
        if skipped:
            log.info("%s: geoms skipped: %s", self.path, ", ".join(f"{v} {k}" for k, v in skipped.items()))

    def _geom_mesh(self, gid: int) -> g.RawMesh | None:
        import mujoco

        m, t = self.m, int(self.m.geom_type[gid])
        size = np.asarray(m.geom_size[gid], float)
        if t == mujoco.mjtGeom.mjGEOM_MESH:
            return self._mesh(int(m.geom_dataid[gid]))
        if t == mujoco.mjtGeom.mjGEOM_BOX:
            return g.box(size)
        if t == mujoco.mjtGeom.mjGEOM_SPHERE:
            return g.ellipsoid((size[0],) * 3)
        if t == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
            return g.ellipsoid(size)
        if t == mujoco.mjtGeom.mjGEOM_CAPSULE:
            return g.capsule(size[0], size[1])
        if t == mujoco.mjtGeom.mjGEOM_CYLINDER:
            return g.cylinder(size[0], size[1])
        return None   # plane, height field, SDF: nothing to tessellate

    def _mesh(self, mid: int) -> g.RawMesh:
        """A compiled MuJoCo mesh in its geom frame, with per-corner normals/UVs welded into vertices."""
        m = self.m
        va, vn = m.mesh_vertadr[mid], m.mesh_vertnum[mid]
        fa, fnum = m.mesh_faceadr[mid], m.mesh_facenum[mid]
        verts = np.asarray(m.mesh_vert[va:va + vn], float)
        faces = np.asarray(m.mesh_face[fa:fa + fnum], np.int64)
        na, nn = m.mesh_normaladr[mid], m.mesh_normalnum[mid]
        ta, tn = m.mesh_texcoordadr[mid], m.mesh_texcoordnum[mid]
        keys = [faces.reshape(-1)]
        normals = uvs = None
        if nn > 0:
            fnorm = np.asarray(m.mesh_facenormal[fa:fa + fnum], np.int64).reshape(-1)
            normals = np.asarray(m.mesh_normal[na:na + nn], float)[fnorm]
            keys.append(fnorm)
        if ta >= 0 and tn > 0:
            ftex = np.asarray(m.mesh_facetexcoord[fa:fa + fnum], np.int64).reshape(-1)
            uvs = np.asarray(m.mesh_texcoord[ta:ta + tn], float)[ftex]
            uvs = np.column_stack([uvs[:, 0], 1.0 - uvs[:, 1]])   # MuJoCo flips v on load; undo it
            keys.append(ftex)
        pos = verts[keys[0]]
        corners = g.RawMesh(pos, np.arange(len(pos), dtype=np.int64).reshape(-1, 3), normals, uvs)
        return g.weld(corners, np.column_stack(keys))

    def _texrepeat(self, gid: int) -> tuple[float, float]:
        mid = int(self.m.geom_matid[gid])
        return tuple(float(v) for v in self.m.mat_texrepeat[mid]) if mid >= 0 else (1.0, 1.0)

    def _material(self, gid: int) -> tuple[str, bool]:
        """Key of the geom's MaterialSpec (created once per distinct look) and whether it has a texture."""
        import mujoco

        m = self.m
        mid = int(m.geom_matid[gid])
        texture = None
        if mid >= 0:
            rgba = np.asarray(m.mat_rgba[mid], float)
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_MATERIAL, mid) or f"material{mid}"
            tid = int(m.mat_texid[mid][int(mujoco.mjtTextureRole.mjTEXROLE_RGB)])
            if tid >= 0:
                texture = self._texture_file(tid)
            rough = float(m.mat_roughness[mid])
            metal = float(m.mat_metallic[mid])
        else:
            rgba = np.asarray(m.geom_rgba[gid], float)
            name, rough, metal = "rgba_" + "".join(f"{int(round(c * 255)):02x}" for c in rgba), -1.0, -1.0
        key = (name, tuple(np.round(rgba, 6)), texture)
        if key not in self.mat_key:
            out = self.mat_names.add(name, "material")
            self.materials[out] = MaterialSpec(
                name=out, base_color=tuple(float(np.clip(c, 0, 1)) for c in rgba[:3]),
                opacity=float(np.clip(rgba[3], 0, 1)),
                roughness=rough if 0 <= rough <= 1 else 0.5, metallic=metal if 0 <= metal <= 1 else 0.0,
                base_color_texture=texture)
            self.mat_key[key] = out
        return self.mat_key[key], texture is not None

    def _texture_file(self, tid: int) -> Path | None:
        adr = int(self.m.tex_pathadr[tid])
        if adr < 0:
            return None   # a builtin (procedural) texture: colour only
        name = bytes(self.m.paths[adr:]).split(b"\0", 1)[0].decode(errors="replace")
        p = Path(name)
        if not name or not p.is_file():
            log.warning("%s: texture file %r not found; colour only", self.path, name)
            return None
        return p.resolve()
