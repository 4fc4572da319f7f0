"""write_asset_package and validate_package on assets built in code."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import usd_schemas
import usd_test_models as M
from asset_catalog.asset_model import MeshPart
from pipeline.types import ItemError

VERSION = "0.1.0"


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> dict[str, tuple[object, usd_schemas.AssetPackage]]:
    root = tmp_path_factory.mktemp("packages")
    models = [M.box_model(), M.bowl_model(), M.cabinet_model(), M.cabinet_model("cabinet_fixed", fixed_base=True),
              M.tilted_hinge_model(), M.textured_model(root / "sources")]
    return {m.name: (m, usd_schemas.write_asset_package(m, root / m.name, pipeline_version=VERSION)) for m in models}


def _stage(pkg: usd_schemas.AssetPackage):
    from pxr import Usd

    return Usd.Stage.Open(str(pkg.root_path))


ALL = ["box_01", "bowl_01", "cabinet_01", "cabinet_fixed", "flap_01", "crate_01"]


@pytest.mark.parametrize("name", ALL)
def test_package_opens_and_validates_with_zero_errors(written, name):
    _, pkg = written[name]
    stage = _stage(pkg)
    assert stage.GetCompositionErrors() == []
    report = usd_schemas.validate_package(pkg.root_path)
    assert report.ok, report.summary()
    assert report.errors == ()
    assert report.disabled_rules == ()


def test_root_layer_interface(written):
    from pxr import Kind, Sdf, Usd, UsdGeom, UsdPhysics, UsdSemantics

    model, pkg = written["bowl_01"]
    assert pkg.root_layer == "bowl_01.usda" and pkg.payload_layer == "bowl_01_payload.usdc"
    assert set(pkg.files) == {"bowl_01.usda", "bowl_01_payload.usdc"}
    layer = Sdf.Layer.FindOrOpen(str(pkg.root_path))
    assert layer.defaultPrim == "bowl_01"
    root_spec = layer.GetPrimAtPath("/bowl_01")
    assert [p.assetPath for p in root_spec.payloadList.prependedItems] == ["./bowl_01_payload.usdc"]
    assert not root_spec.nameChildren, "the root layer holds no geometry"
    stage = _stage(pkg)
    assert UsdGeom.GetStageUpAxis(stage) == "Z"
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert UsdPhysics.GetStageKilogramsPerUnit(stage) == 1.0
    prim = stage.GetDefaultPrim()
    assert prim.GetTypeName() == "Xform" and Usd.ModelAPI(prim).GetKind() == Kind.Tokens.component
    assert prim.HasAPI("AgentWorldAssetAPI")
    assert prim.GetAttribute("agentworld:category").Get() == "bowl"
    assert prim.GetAttribute("agentworld:placement").Get() == "on_surface"
    assert prim.GetAttribute("agentworld:materialClass").Get() == "ceramic"
    assert prim.GetAttribute("agentworld:interactable").Get() is True
    assert list(prim.GetAttribute("agentworld:coOccurrence").Get()) == ["table", "counter"]
    assert prim.GetAttribute("agentworld:pipelineVersion").Get() == VERSION
    labels = UsdSemantics.LabelsAPI(prim, "class")
    assert prim.HasAPI(UsdSemantics.LabelsAPI, "class")
    assert list(labels.GetLabelsAttr().Get()) == ["bowl"]
    box_stage = _stage(written["box_01"][1])
    box_prim = box_stage.GetDefaultPrim()
    assert box_prim.GetAttribute("agentworld:sourceHash").Get() == "ab" * 32
    assert list(box_prim.GetAttribute("agentworld:roomTypes").Get()) == ["kitchen"]


def test_payload_loads_by_default_and_can_be_left_unloaded(written):
    from pxr import Usd

    _, pkg = written["box_01"]
    stage = _stage(pkg)
    assert stage.GetPrimAtPath("/box_01/body/visuals/box").IsValid()
    unloaded = Usd.Stage.Open(str(pkg.root_path), Usd.Stage.LoadNone)
    assert not unloaded.GetPrimAtPath("/box_01/body").IsValid()
    assert unloaded.GetDefaultPrim().GetAttribute("agentworld:category").Get() == "box"


def test_meshes_colliders_and_physics(written):
    from pxr import UsdGeom, UsdPhysics, UsdShade

    model, pkg = written["bowl_01"]
    stage = _stage(pkg)
    body = stage.GetPrimAtPath("/bowl_01/bowl")
    assert body.HasAPI(UsdPhysics.RigidBodyAPI) and body.HasAPI(UsdPhysics.MassAPI)
    mass = UsdPhysics.MassAPI(body)
    ms = model.links[0].mass
    assert mass.GetMassAttr().Get() == pytest.approx(ms.mass, rel=1e-6)
    assert np.allclose(mass.GetCenterOfMassAttr().Get(), ms.center_of_mass, atol=1e-6)
    assert np.allclose(mass.GetDiagonalInertiaAttr().Get(), ms.diagonal_inertia, rtol=1e-5)
    q = mass.GetPrincipalAxesAttr().Get()
    assert np.allclose([q.GetReal(), *q.GetImaginary()], ms.principal_axes, atol=1e-6)

    vis = UsdGeom.Mesh(stage.GetPrimAtPath("/bowl_01/bowl/visuals/bowl"))
    src = model.links[0].visuals[0]
    assert np.allclose(np.asarray(vis.GetPointsAttr().Get()), src.vertices, atol=1e-6)
    assert list(vis.GetFaceVertexCountsAttr().Get()) == [3] * len(src.faces)
    assert np.array_equal(np.asarray(vis.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3), src.faces)
    assert vis.GetSubdivisionSchemeAttr().Get() == "none"
    normals = UsdGeom.PrimvarsAPI(vis).GetPrimvar("normals")
    assert normals.GetInterpolation() == "vertex"
    flat = np.asarray(normals.ComputeFlattened())
    assert flat.shape == src.vertices.shape
    assert np.allclose(flat, src.normals, atol=1e-6)
    assert normals.IsIndexed() and len(normals.Get()) < len(src.vertices), "repeated normals stored once"
    ext = np.asarray(vis.GetExtentAttr().Get())
    assert np.allclose(ext, [src.vertices.min(0), src.vertices.max(0)], atol=1e-6)
    assert UsdGeom.Imageable(vis).ComputePurpose() == UsdGeom.Tokens.default_
    assert UsdShade.MaterialBindingAPI(vis).ComputeBoundMaterial()[0].GetPath() == "/bowl_01/Looks/default_material"

    cols = [p for p in stage.Traverse() if p.HasAPI(UsdPhysics.CollisionAPI)]
    assert len(cols) == len(model.links[0].colliders) == 9 == pkg.collider_count
    phys_mat = stage.GetPrimAtPath("/bowl_01/Looks/PhysicsMaterial")
    pm = UsdPhysics.MaterialAPI(phys_mat)
    assert pm.GetDynamicFrictionAttr().Get() == pytest.approx(M.CERAMIC.dynamic_friction)
    assert pm.GetStaticFrictionAttr().Get() == pytest.approx(M.CERAMIC.static_friction)
    assert pm.GetRestitutionAttr().Get() == pytest.approx(M.CERAMIC.restitution)
    assert pm.GetDensityAttr().Get() == pytest.approx(M.CERAMIC.density)
    assert phys_mat.GetAttribute("newton:torsionalFriction").Get() == pytest.approx(M.CERAMIC.torsional_friction)
    assert phys_mat.GetAttribute("newton:rollingFriction").Get() == pytest.approx(M.CERAMIC.rolling_friction)
    assert "NewtonMaterialAPI" in phys_mat.GetMetadata("apiSchemas").GetAddedOrExplicitItems()
    for c in cols:
        assert c.GetAttribute("mjc:condim").Get() == 6   # rolling friction: MuJoCo needs 6 dimensions
        assert c.GetTypeName() == "Mesh" and c.GetParent().GetName() == "colliders"
        assert UsdPhysics.MeshCollisionAPI(c).GetApproximationAttr().Get() == "convexHull"
        assert UsdGeom.Imageable(c).ComputePurpose() == UsdGeom.Tokens.guide
        bound = UsdShade.MaterialBindingAPI(c).ComputeBoundMaterial("physics")[0]
        assert bound.GetPath() == phys_mat.GetPath()
    assert stage.GetPrimAtPath("/bowl_01/bowl/colliders").GetCustomDataByKey(
        "agentworldColliderApprox") == "convexDecomposition"
    lo, hi = np.array(pkg.bbox_min), np.array(pkg.bbox_max)
    assert np.allclose(hi - lo, [0.16, 0.16, 0.06], atol=2e-3)


def test_textures_are_copied_and_bound(written):
    from pxr import Sdf, UsdShade

    model, pkg = written["crate_01"]
    tex_files = [f for f in pkg.files if f.startswith("textures/")]
    assert len(tex_files) == 3, "albedo, normal and one shared ARM file"
    for f in tex_files:
        assert (pkg.out_dir / f).is_file()
        assert " " not in f
    stage = _stage(pkg)
    mat = UsdShade.Material(stage.GetPrimAtPath("/crate_01/Looks/crate"))
    surface = mat.ComputeSurfaceSource()[0]
    assert surface.GetIdAttr().Get() == "UsdPreviewSurface"
    files = {}
    for role, output in (("diffuseColor", "rgb"), ("normal", "rgb"), ("roughness", "g"), ("metallic", "b"),
                         ("occlusion", "r")):
        src, out_name, _ = surface.GetInput(role).GetConnectedSource()
        assert out_name == output, role
        tex = UsdShade.Shader(src.GetPrim())
        assert tex.GetIdAttr().Get() == "UsdUVTexture"
        path = tex.GetInput("file").Get()
        assert path.path.startswith("./textures/")
        assert Path(path.resolvedPath).is_file()
        files[role] = path.path
        st_src = tex.GetInput("st").GetConnectedSource()[0]
        assert UsdShade.Shader(st_src.GetPrim()).GetIdAttr().Get() == "UsdPrimvarReader_float2"
        assert UsdShade.Shader(st_src.GetPrim()).GetInput("varname").Get() == "st"
        cs = tex.GetInput("sourceColorSpace").Get()
        assert cs == ("sRGB" if role == "diffuseColor" else "raw"), role
    assert files["roughness"] == files["metallic"] == files["occlusion"]
    normal_tex = UsdShade.Shader(surface.GetInput("normal").GetConnectedSource()[0].GetPrim())
    assert tuple(normal_tex.GetInput("scale").Get()) == (2, 2, 2, 1)
    assert tuple(normal_tex.GetInput("bias").Get()) == (-1, -1, -1, 0)
    mesh = stage.GetPrimAtPath("/crate_01/crate/visuals/crate")
    from pxr import UsdGeom

    st = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("st")
    assert st.GetTypeName() == Sdf.ValueTypeNames.TexCoord2fArray and st.GetInterpolation() == "vertex"
    assert np.allclose(np.asarray(st.ComputeFlattened()), model.links[0].visuals[0].uvs)
    assert st.IsIndexed() and len(st.Get()) == 4, "a cube's 24 corners use 4 distinct UVs"


def test_package_is_relocatable(written, tmp_path):
    _, pkg = written["crate_01"]
    moved = tmp_path / "moved"
    shutil.copytree(pkg.out_dir, moved)
    report = usd_schemas.validate_package(moved / pkg.root_layer)
    assert report.ok, report.summary()


def test_output_is_deterministic(tmp_path):
    tex = tmp_path / "src"
    for d in ("a", "b"):
        for model in (M.textured_model(tex), M.cabinet_model()):
            usd_schemas.write_asset_package(model, tmp_path / d / model.name, pipeline_version=VERSION)
    files_a = sorted(p.relative_to(tmp_path / "a") for p in (tmp_path / "a").rglob("*") if p.is_file())
    files_b = sorted(p.relative_to(tmp_path / "b") for p in (tmp_path / "b").rglob("*") if p.is_file())
    assert files_a == files_b and len(files_a) == 7
    for rel in files_a:
        assert (tmp_path / "a" / rel).read_bytes() == (tmp_path / "b" / rel).read_bytes(), rel


def _joint_world_frames(stage, joint_path):
    """World transforms (4x4, column vectors) of a joint's frame seen from body0 and from body1."""
    from pxr import Gf, UsdGeom, UsdPhysics

    joint = UsdPhysics.Joint(stage.GetPrimAtPath(joint_path))
    cache = UsdGeom.XformCache()
    frames = []
    for rel, pos, rot in ((joint.GetBody0Rel(), joint.GetLocalPos0Attr(), joint.GetLocalRot0Attr()),
                          (joint.GetBody1Rel(), joint.GetLocalPos1Attr(), joint.GetLocalRot1Attr())):
        body = stage.GetPrimAtPath(rel.GetTargets()[0])
        world = np.array(cache.GetLocalToWorldTransform(body)).T  # USD row vectors -> column vectors
        local = np.eye(4)
        q = rot.Get()
        local[:3, :3] = np.array(Gf.Matrix3d(Gf.Rotation(Gf.Quatd(q.GetReal(), Gf.Vec3d(q.GetImaginary())))).GetTranspose())
        local[:3, 3] = pos.Get()
        frames.append(world @ local)
    return frames


@pytest.mark.parametrize("name,joint,model_joint", [
    ("cabinet_01", "/cabinet_01/joints/door_hinge", "door_hinge"),
    ("cabinet_01", "/cabinet_01/joints/drawer_slide", "drawer_slide"),
    ("flap_01", "/flap_01/joints/hinge", "hinge"),
])
def test_joint_frames_axes_and_limits(written, name, joint, model_joint):
    from pxr import UsdPhysics

    model, pkg = written[name]
    stage = _stage(pkg)
    f0, f1 = _joint_world_frames(stage, joint)
    assert np.allclose(f0, f1, atol=1e-5), "body0 and body1 frames coincide at the zero configuration"
    mj = next(j for j in model.joints if j.name == model_joint)
    parent = model.link(mj.parent)
    axis_world = (parent.pose.matrix() @ mj.frame.matrix())[:3, :3] @ np.asarray(mj.axis)
    assert np.allclose(f0[:3, 0], axis_world, atol=1e-5), "USD joint X axis is the model's axis"
    assert np.allclose(f0[:3, 3], (parent.pose.matrix() @ mj.frame.matrix())[:3, 3], atol=1e-6)
    prim = stage.GetPrimAtPath(joint)
    if mj.type == "revolute":
        j = UsdPhysics.RevoluteJoint(prim)
        scale = 180.0 / math.pi
    else:
        j = UsdPhysics.PrismaticJoint(prim)
        scale = 1.0
    assert j.GetAxisAttr().Get() == "X"
    assert j.GetLowerLimitAttr().Get() == pytest.approx(mj.lower * scale, rel=1e-6, abs=1e-6)
    assert j.GetUpperLimitAttr().Get() == pytest.approx(mj.upper * scale, rel=1e-6)


def test_drives_friction_and_velocity_limits(written):
    from pxr import UsdPhysics

    model, pkg = written["cabinet_01"]
    stage = _stage(pkg)
    door = stage.GetPrimAtPath("/cabinet_01/joints/door_hinge")
    drive = UsdPhysics.DriveAPI(door, "angular")
    assert door.HasAPI(UsdPhysics.DriveAPI, "angular")
    assert drive.GetDampingAttr().Get() == pytest.approx(0.5 * math.pi / 180.0)
    assert drive.GetStiffnessAttr().Get() == 0.0
    assert not drive.GetMaxForceAttr().HasAuthoredValue()
    assert door.GetAttribute("newton:friction").Get() == pytest.approx(0.05)
    assert door.GetAttribute("newton:velocityLimit").Get() == pytest.approx(3.0 * 180.0 / math.pi, rel=1e-6)
    assert list(door.GetAttribute("mjc:solreflimit").Get()) == [0.02, 2.0]   # the stops, as MuJoCo's solref
    drawer = stage.GetPrimAtPath("/cabinet_01/joints/drawer_slide")
    ddrive = UsdPhysics.DriveAPI(drawer, "linear")
    assert ddrive.GetDampingAttr().Get() == pytest.approx(2.0)
    assert ddrive.GetMaxForceAttr().Get() == pytest.approx(50.0)
    assert ddrive.GetTypeAttr().Get() == "force"
    assert not drawer.GetAttribute("newton:friction").IsValid()
    assert not drawer.GetAttribute("mjc:solreflimit").IsValid()   # none given: the simulator's default


def test_articulation_root_and_bases(written):
    from pxr import UsdPhysics

    stage = _stage(written["cabinet_01"][1])
    root = stage.GetPrimAtPath("/cabinet_01")
    assert root.HasAPI(UsdPhysics.ArticulationRootAPI)
    assert not any(p.IsA(UsdPhysics.FixedJoint) for p in stage.Traverse()), "movable base: no joint to the world"
    bodies = [p for p in stage.Traverse() if p.HasAPI(UsdPhysics.RigidBodyAPI)]
    assert [b.GetName() for b in bodies] == ["body", "door", "drawer"]

    fixed = _stage(written["cabinet_fixed"][1])
    fj = UsdPhysics.FixedJoint(fixed.GetPrimAtPath("/cabinet_fixed/joints/root_fixed"))
    assert [str(t) for t in fj.GetBody0Rel().GetTargets()] == ["/cabinet_fixed"]
    assert [str(t) for t in fj.GetBody1Rel().GetTargets()] == ["/cabinet_fixed/body"]

    box = _stage(written["box_01"][1])
    assert not box.GetPrimAtPath("/box_01").HasAPI(UsdPhysics.ArticulationRootAPI)


def test_static_fixed_rigid_asset_has_no_rigid_body(tmp_path):
    from dataclasses import replace

    from pxr import Usd, UsdPhysics

    model = replace(M.box_model("shelf_01"), fixed_base=True)
    pkg = usd_schemas.write_asset_package(model, tmp_path, pipeline_version=VERSION)
    stage = Usd.Stage.Open(str(pkg.root_path))
    assert not any(p.HasAPI(UsdPhysics.RigidBodyAPI) for p in stage.Traverse())
    assert any(p.HasAPI(UsdPhysics.CollisionAPI) for p in stage.Traverse())
    assert pkg.body_count == 0
    assert usd_schemas.validate_package(pkg.root_path).ok


def _bad_part(**kw) -> MeshPart:
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    args = {"name": "tri", "vertices": v, "faces": np.array([[0, 1, 2]])} | kw
    return MeshPart(**args)


@pytest.mark.parametrize("part,message", [
    (_bad_part(vertices=np.array([[0, 0, np.nan], [1, 0, 0], [0, 1, 0.0]])), "NaN"),
    (_bad_part(faces=np.array([[0, 1, 5]])), "face index out of range"),
    (_bad_part(vertices=np.zeros((0, 3))), "non-empty"),
    (_bad_part(material="nope"), "undefined material"),
])
def test_bad_models_fail_with_one_line_reason(tmp_path, part, message):
    from dataclasses import replace

    model = M.box_model("bad_01")
    link = replace(model.links[0], visuals=(part,))
    with pytest.raises(ItemError, match=message) as err:
        usd_schemas.write_asset_package(model.replace_links((link,)), tmp_path, pipeline_version=VERSION)
    assert "\n" not in str(err.value) and "bad_01" in str(err.value)
    assert not list(tmp_path.glob("*.usd*")), "nothing written for a bad model"


def test_missing_texture_and_bad_joint_fail(tmp_path):
    from dataclasses import replace

    model = M.textured_model(tmp_path / "src")
    (tmp_path / "src" / "crate_albedo.png").unlink()
    with pytest.raises(ItemError, match="crate_albedo.png: texture .* not found"):
        usd_schemas.write_asset_package(model, tmp_path / "out", pipeline_version=VERSION)
    cab = M.cabinet_model()
    bad = replace(cab, joints=(replace(cab.joints[0], child="ghost"), cab.joints[1]))
    with pytest.raises(ItemError, match="unknown link 'ghost'"):
        usd_schemas.write_asset_package(bad, tmp_path / "out2", pipeline_version=VERSION)
    cyc = replace(cab, joints=(replace(cab.joints[0], parent="drawer"), replace(cab.joints[1], parent="door")))
    with pytest.raises(ItemError, match="not reachable from the root link"):
        usd_schemas.write_asset_package(cyc, tmp_path / "out3", pipeline_version=VERSION)
    axis0 = replace(cab, joints=(replace(cab.joints[0], axis=(0.0, 0.0, 0.0)), cab.joints[1]))
    with pytest.raises(ItemError, match="not a unit vector"):
        usd_schemas.write_asset_package(axis0, tmp_path / "out4", pipeline_version=VERSION)


def test_validation_reports_real_problems(written, tmp_path):
    """The validators are live: a package with a broken payload and wrong units has errors."""
    _, pkg = written["box_01"]
    broken = tmp_path / "broken"
    shutil.copytree(pkg.out_dir, broken)
    (broken / pkg.payload_layer).unlink()
    report = usd_schemas.validate_package(broken / pkg.root_layer)
    assert not report.ok
    assert {i.source for i in report.errors} >= {"composition"}
    meta = tmp_path / "meta"
    shutil.copytree(pkg.out_dir, meta)
    root = meta / pkg.root_layer
    root.write_text(root.read_text().replace('    defaultPrim = "box_01"\n', "").replace('    upAxis = "Z"\n', ""))
    report2 = usd_schemas.validate_package(root)
    rules = {i.rule for i in report2.errors}
    assert {"usdValidation:StageMetadataChecker", "usdGeomValidators:StageMetadataChecker"} <= rules, report2.summary()
    assert any(i.source == "omni" for i in report2.errors), report2.summary()
    assert usd_schemas.validate_package(tmp_path / "nope.usda").errors[0].message == "file not found"


def test_axis_rotation_maps_x_onto_axis():
    from usd_schemas._plan import axis_to_x_rotation

    rng = np.random.default_rng(0)
    axes = [(1.0, 0, 0), (-1.0, 0, 0), (0, 0, 1.0), (0, -1.0, 0)] + [tuple(a / np.linalg.norm(a))
                                                                    for a in rng.normal(size=(20, 3))]
    for a in axes:
        r = axis_to_x_rotation(a)
        assert np.allclose(r @ [1, 0, 0], a, atol=1e-12)
        assert np.allclose(r.T @ r, np.eye(3), atol=1e-12) and np.linalg.det(r) == pytest.approx(1.0)


def test_newton_loads_packages(written):
    pytest.importorskip("newton_usd_schemas", reason="Newton's add_usd needs newton-usd-schemas")
    import newton

    expected = {"box_01": (1, 1), "bowl_01": (1, 9), "cabinet_01": (3, 3), "cabinet_fixed": (3, 3),
                "flap_01": (2, 2), "crate_01": (1, 1)}
    for name, (bodies, colliders) in expected.items():
        b = newton.ModelBuilder()
        b.add_usd(str(written[name][1].root_path), load_visual_shapes=False)
        assert b.body_count == bodies, name
        collide = int(newton.ShapeFlags.COLLIDE_SHAPES)
        assert sum(1 for f in b.shape_flags if f & collide) == colliders, name
        model = written[name][0]
        total = sum(lk.mass.mass for lk in model.links)
        assert sum(b.body_mass) == pytest.approx(total, rel=1e-5), name
    visual = newton.ModelBuilder()
    visual.add_usd(str(written["crate_01"][1].root_path))  # indexed normals and UVs, textured material
    assert visual.shape_count == 2
    assert any(lbl.endswith("/visuals/crate") for lbl in visual.shape_label)


def test_newton_kinematics_follow_the_model_axis(written):
    """Turning the oblique hinge by 0.5 rad in Newton moves the flap as the model says."""
    pytest.importorskip("newton_usd_schemas", reason="Newton's add_usd needs newton-usd-schemas")
    import newton

    model, pkg = written["flap_01"]
    b = newton.ModelBuilder()
    b.add_usd(str(pkg.root_path), load_visual_shapes=False)
    sim = b.finalize(device="cpu")
    q = sim.joint_q.numpy()
    hinge = next(i for i, lbl in enumerate(b.joint_label) if lbl.endswith("/hinge"))
    q[b.joint_q_start[hinge]] = 0.5
    sim.joint_q.assign(q)
    state = sim.state()
    newton.eval_fk(sim, sim.joint_q, sim.joint_qd, state)
    flap = next(i for i, lbl in enumerate(b.body_label) if lbl.endswith("/flap"))
    px, py, pz, qx, qy, qz, qw = state.body_q.numpy()[flap]
    got = np.eye(4)
    got[:3, :3] = Rotation.from_quat([qx, qy, qz, qw]).as_matrix()
    got[:3, 3] = (px, py, pz)
    j = model.joints[0]
    frame = model.link("base").pose.matrix() @ j.frame.matrix()
    turn = np.eye(4)
    turn[:3, :3] = Rotation.from_rotvec(0.5 * np.asarray(j.axis)).as_matrix()
    want = frame @ turn @ np.linalg.inv(frame) @ model.link("flap").pose.matrix()
    assert np.allclose(got, want, atol=1e-5)

