"""Authoring phase of the asset package writer: ``PackagePlan`` -> two Sdf layers.

Only the Sdf API is used, inside one ``Sdf.ChangeBlock`` per layer (no Usd API in the block).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from pxr import Gf, Kind, Sdf, Vt

from usd_schemas._plan import BodyPlan, JointPlan, MaterialPlan, MeshPlan, PackagePlan, PhysicsMaterialPlan

LABEL_INSTANCE = "class"
_SHADER_SURFACE = "PreviewSurface"
_SHADER_ST = "stReader"


# ---------------------------------------------------------------------------------------------
# small Sdf helpers (valid only inside a ChangeBlock that the caller holds)


def _prim(layer, path: str, type_name: str = "", api: Iterable[str] = (), specifier=None):

    spec = Sdf.CreatePrimInLayer(layer, path)
    spec.specifier = Sdf.SpecifierDef if specifier is None else specifier
    if type_name:
        spec.typeName = type_name
    api = list(api)
    if api:
        spec.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=api))
    return spec


def _attr(spec, name: str, type_name, value=None, *, uniform: bool = False, custom: bool = False,
          interpolation: str | None = None, connect: str | None = None):

    var = Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying
    a = Sdf.AttributeSpec(spec, name, type_name, var, declaresCustom=custom)
    if value is not None:
        a.default = value
    if interpolation:
        a.SetInfo("interpolation", interpolation)
    if connect:
        a.connectionPathList.explicitItems = [Sdf.Path(connect)]
    return a


def _rel(spec, name: str, target: str) -> None:

    r = Sdf.RelationshipSpec(spec, name, custom=False)
    r.targetPathList.explicitItems = [Sdf.Path(target)]


def _stage_metadata(layer, default_prim: str, doc: str) -> None:
    root = layer.pseudoRoot
    layer.defaultPrim = default_prim
    root.SetInfo("upAxis", "Z")
    root.SetInfo("metersPerUnit", 1.0)
    root.SetInfo("kilogramsPerUnit", 1.0)
    root.SetInfo("documentation", doc)


# ---------------------------------------------------------------------------------------------
# root layer


def author_root_layer(layer, plan: PackagePlan, payload_rel: str) -> None:
    """The small interface layer: defaultPrim, stage metrics, annotations, labels, payload."""
    T = Sdf.ValueTypeNames
    with Sdf.ChangeBlock():
        _stage_metadata(layer, plan.asset_id, f"AgentWorld asset package {plan.asset_id}")
        spec = _prim(layer, plan.root, "Xform", ("AgentWorldAssetAPI", f"SemanticsLabelsAPI:{LABEL_INSTANCE}"))
        spec.SetInfo("kind", Kind.Tokens.component)
        spec.payloadList.Prepend(Sdf.Payload(payload_rel, Sdf.Path(plan.root)))
        a = plan.annotation_attrs
        _attr(spec, "agentworld:category", T.Token, a["agentworld:category"], uniform=True)
        _attr(spec, "agentworld:placement", T.Token, a["agentworld:placement"], uniform=True)
        _attr(spec, "agentworld:roomTypes", T.TokenArray, Vt.TokenArray(a["agentworld:roomTypes"]), uniform=True)
        _attr(spec, "agentworld:materialClass", T.Token, a["agentworld:materialClass"], uniform=True)
        _attr(spec, "agentworld:interactable", T.Bool, a["agentworld:interactable"], uniform=True)
        _attr(spec, "agentworld:coOccurrence", T.StringArray, Vt.StringArray(a["agentworld:coOccurrence"]),
              uniform=True)
        _attr(spec, "agentworld:sourceHash", T.String, a["agentworld:sourceHash"], uniform=True)
        _attr(spec, "agentworld:pipelineVersion", T.String, a["agentworld:pipelineVersion"], uniform=True)
        _attr(spec, f"semantics:labels:{LABEL_INSTANCE}", T.TokenArray, Vt.TokenArray([plan.category]))


# ---------------------------------------------------------------------------------------------
# payload layer


def author_payload_layer(layer, plan: PackagePlan) -> None:
    """Geometry, materials and physics under the same root path as the root layer."""

    with Sdf.ChangeBlock():
        _stage_metadata(layer, plan.asset_id, f"AgentWorld asset package {plan.asset_id}: geometry and physics")
        _prim(layer, plan.root, "Xform", ("PhysicsArticulationRootAPI",) if plan.articulated else ())
        _prim(layer, f"{plan.root}/Looks", "Scope")
        for pm in plan.physics_materials:
            _physics_material(layer, pm)
        for m in plan.materials:
            _material(layer, m)
        for b in plan.bodies:
            _body(layer, b, b.physics_material)
        if plan.joints:
            _prim(layer, f"{plan.root}/joints", "Scope")
            for j in plan.joints:
                _joint(layer, j)


def _physics_material(layer, pm: PhysicsMaterialPlan) -> None:
    """UsdPhysics material plus Newton's NewtonMaterialAPI: torsional and rolling friction [m],
    which Newton's importer reads into mu_torsional / mu_rolling (MuJoCo's geom friction 2 and 3)."""
    T = Sdf.ValueTypeNames
    p = pm.props
    spec = _prim(layer, pm.path, "Material", ("PhysicsMaterialAPI", "NewtonMaterialAPI"))
    _attr(spec, "physics:staticFriction", T.Float, float(p.static_friction))
    _attr(spec, "physics:dynamicFriction", T.Float, float(p.dynamic_friction))
    _attr(spec, "physics:restitution", T.Float, float(p.restitution))
    _attr(spec, "physics:density", T.Float, float(p.density))
    _attr(spec, "newton:torsionalFriction", T.Float, float(p.torsional_friction))
    _attr(spec, "newton:rollingFriction", T.Float, float(p.rolling_friction))


def _material(layer, m: MaterialPlan) -> None:
    T = Sdf.ValueTypeNames
    mat = _prim(layer, m.path, "Material")
    surf_path = f"{m.path}/{_SHADER_SURFACE}"
    _attr(mat, "outputs:surface", T.Token, connect=f"{surf_path}.outputs:surface")
    surf = _prim(layer, surf_path, "Shader")
    _attr(surf, "info:id", T.Token, "UsdPreviewSurface", uniform=True)
    _attr(surf, "outputs:surface", T.Token)
    tex = m.textures
    _attr(surf, "inputs:diffuseColor", T.Color3f, Gf.Vec3f(*m.base_color),
          connect=_tex_out(m, "diffuseColor"))
    _attr(surf, "inputs:roughness", T.Float, m.roughness, connect=_tex_out(m, "roughness"))
    _attr(surf, "inputs:metallic", T.Float, m.metallic, connect=_tex_out(m, "metallic"))
    _attr(surf, "inputs:opacity", T.Float, m.opacity)
    if "normal" in tex:
        _attr(surf, "inputs:normal", T.Normal3f, Gf.Vec3f(0, 0, 1), connect=_tex_out(m, "normal"))
    if "occlusion" in tex:
        _attr(surf, "inputs:occlusion", T.Float, 1.0, connect=_tex_out(m, "occlusion"))
    if not tex:
        return
    st = _prim(layer, f"{m.path}/{_SHADER_ST}", "Shader")
    _attr(st, "info:id", T.Token, "UsdPrimvarReader_float2", uniform=True)
    _attr(st, "inputs:varname", T.String, "st")
    _attr(st, "outputs:result", T.Float2)
    for role in sorted(tex):
        ref = tex[role]
        sh = _prim(layer, f"{m.path}/{role}Texture", "Shader")
        _attr(sh, "info:id", T.Token, "UsdUVTexture", uniform=True)
        _attr(sh, "inputs:file", T.Asset, Sdf.AssetPath(ref.rel_path))
        _attr(sh, "inputs:st", T.Float2, connect=f"{m.path}/{_SHADER_ST}.outputs:result")
        _attr(sh, "inputs:sourceColorSpace", T.Token, ref.color_space)
        _attr(sh, "inputs:wrapS", T.Token, "repeat")
        _attr(sh, "inputs:wrapT", T.Token, "repeat")
        if role == "normal":
            _attr(sh, "inputs:scale", T.Float4, Gf.Vec4f(2, 2, 2, 1))
            _attr(sh, "inputs:bias", T.Float4, Gf.Vec4f(-1, -1, -1, 0))
        _attr(sh, f"outputs:{ref.output}", T.Float3 if ref.output == "rgb" else T.Float)


def _tex_out(m: MaterialPlan, role: str) -> str | None:
    ref = m.textures.get(role)
    return None if ref is None else f"{m.path}/{role}Texture.outputs:{ref.output}"


def _body(layer, b: BodyPlan, physics_material: str) -> None:
    T = Sdf.ValueTypeNames
    api = ("PhysicsRigidBodyAPI", "PhysicsMassAPI") if b.rigid and b.mass is not None else (
        ("PhysicsRigidBodyAPI",) if b.rigid else ())
    spec = _prim(layer, b.path, "Xform", api)
    _attr(spec, "xformOp:translate", T.Double3, Gf.Vec3d(*b.translate))
    _attr(spec, "xformOp:orient", T.Quatd, Gf.Quatd(b.orient[0], *b.orient[1:]))
    _attr(spec, "xformOpOrder", T.TokenArray, Vt.TokenArray(["xformOp:translate", "xformOp:orient"]), uniform=True)
    if b.rigid and b.mass is not None:
        ms = b.mass
        _attr(spec, "physics:mass", T.Float, float(ms.mass))
        _attr(spec, "physics:centerOfMass", T.Point3f, Gf.Vec3f(*ms.center_of_mass))
        _attr(spec, "physics:diagonalInertia", T.Float3, Gf.Vec3f(*ms.diagonal_inertia))
        w, x, y, z = ms.principal_axes
        _attr(spec, "physics:principalAxes", T.Quatf, Gf.Quatf(w, x, y, z))
    if b.meshes:
        _prim(layer, f"{b.path}/visuals", "Xform")
        for m in b.meshes:
            _mesh(layer, m, physics_material)
    if b.colliders:
        grp = _prim(layer, f"{b.path}/colliders", "Xform")
        _attr(grp, "purpose", T.Token, "guide", uniform=True)
        if b.collider_approx:
            grp.customData = {"agentworldColliderApprox": b.collider_approx}
        for c in b.colliders:
            _mesh(layer, c, physics_material)


def _mesh(layer, m: MeshPlan, physics_material: str) -> None:
    T = Sdf.ValueTypeNames
    api = ("PhysicsCollisionAPI", "PhysicsMeshCollisionAPI", "MaterialBindingAPI") if m.collider else (
        ("MaterialBindingAPI",) if m.material else ())
    spec = _prim(layer, m.path, "Mesh", api)
    n_faces = len(m.indices) // 3
    _attr(spec, "points", T.Point3fArray, Vt.Vec3fArray.FromNumpy(m.points))
    _attr(spec, "faceVertexCounts", T.IntArray, Vt.IntArray.FromNumpy(np.full(n_faces, 3, dtype=np.int32)))
    _attr(spec, "faceVertexIndices", T.IntArray, Vt.IntArray.FromNumpy(m.indices))
    _attr(spec, "extent", T.Float3Array, Vt.Vec3fArray.FromNumpy(m.extent))
    _attr(spec, "subdivisionScheme", T.Token, "none", uniform=True)
    if m.normals is not None:
        _attr(spec, "primvars:normals", T.Normal3fArray, Vt.Vec3fArray.FromNumpy(m.normals), interpolation="vertex")
        if m.normals_indices is not None:
            _attr(spec, "primvars:normals:indices", T.IntArray, Vt.IntArray.FromNumpy(m.normals_indices))
    if m.st is not None:
        _attr(spec, "primvars:st", T.TexCoord2fArray, Vt.Vec2fArray.FromNumpy(m.st), interpolation="vertex")
        if m.st_indices is not None:
            _attr(spec, "primvars:st:indices", T.IntArray, Vt.IntArray.FromNumpy(m.st_indices))
    if m.collider:
        _attr(spec, "purpose", T.Token, "guide", uniform=True)
        _attr(spec, "physics:approximation", T.Token, "convexHull", uniform=True)
        _rel(spec, "material:binding:physics", physics_material)
        if m.condim is not None:   # MuJoCo's MjcCollisionAPI attribute, read by Newton's SolverMuJoCo
            _attr(spec, "mjc:condim", T.Int, int(m.condim), uniform=True, custom=True)
    elif m.material:
        _rel(spec, "material:binding", m.material)


def _joint(layer, j: JointPlan) -> None:
    T = Sdf.ValueTypeNames
    kind = {"PhysicsRevoluteJoint": "angular", "PhysicsPrismaticJoint": "linear"}.get(j.usd_type)
    api = (f"PhysicsDriveAPI:{kind}",) if j.drive is not None and kind else ()
    spec = _prim(layer, j.path, j.usd_type, api)
    _rel(spec, "physics:body0", j.body0)
    _rel(spec, "physics:body1", j.body1)
    _attr(spec, "physics:localPos0", T.Point3f, Gf.Vec3f(*j.local_pos0))
    _attr(spec, "physics:localRot0", T.Quatf, Gf.Quatf(j.local_rot0[0], *j.local_rot0[1:]))
    _attr(spec, "physics:localPos1", T.Point3f, Gf.Vec3f(*j.local_pos1))
    _attr(spec, "physics:localRot1", T.Quatf, Gf.Quatf(j.local_rot1[0], *j.local_rot1[1:]))
    if kind is None:
        return
    _attr(spec, "physics:axis", T.Token, "X", uniform=True)
    if j.lower is not None:
        _attr(spec, "physics:lowerLimit", T.Float, float(j.lower))
    if j.upper is not None:
        _attr(spec, "physics:upperLimit", T.Float, float(j.upper))
    if j.drive is not None:
        stiffness, damping, max_force = j.drive
        p = f"drive:{kind}:physics"
        _attr(spec, f"{p}:type", T.Token, "force", uniform=True)
        _attr(spec, f"{p}:stiffness", T.Float, float(stiffness))
        _attr(spec, f"{p}:damping", T.Float, float(damping))
        _attr(spec, f"{p}:targetPosition", T.Float, 0.0)
        _attr(spec, f"{p}:targetVelocity", T.Float, 0.0)
        if max_force is not None:
            _attr(spec, f"{p}:maxForce", T.Float, float(max_force))
    # Read by Newton's USD importer (SchemaResolverNewton, the default): joint friction [N m] or [N]
    # and velocity limit [deg/s] or [m/s]. Custom attributes: the NewtonJointAPI schema plugin is
    # not installed here, and applying an unregistered API schema would fail validation.
    if j.friction > 0:
        _attr(spec, "newton:friction", T.Float, float(j.friction), custom=True)
    if j.armature > 0:  # [kg m^2] or [kg]
        _attr(spec, "newton:armature", T.Float, float(j.armature), custom=True)
    if j.max_velocity is not None:
        _attr(spec, "newton:velocityLimit", T.Float, float(j.max_velocity), custom=True)
    if j.limit_solref is not None:   # MuJoCo's MjcJointAPI attribute: Newton's SolverMuJoCo passes it on as is
        _attr(spec, "mjc:solreflimit", T.DoubleArray, Vt.DoubleArray([float(x) for x in j.limit_solref]),
              uniform=True, custom=True)
