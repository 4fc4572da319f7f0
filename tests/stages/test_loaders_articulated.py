"""URDF and MJCF loaders: the shared articulated assets, the Panda URDF, and bad inputs.

Expected numbers are read from the source XML files (see the comments); kinematics are checked
against MuJoCo (MJCF) and Pinocchio (URDF) at non-zero joint positions.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from asset_catalog.annotations import AssetAnnotation, load_annotations
from asset_catalog.asset_model import AssetModel, JointType
from pipeline.types import ItemError
from stages.loaders.mjcf import load_mjcf
from stages.loaders.urdf import load_urdf

DATA = Path(__file__).resolve().parents[1] / "data" / "shared_articulated"
PANDA = "robots/franka_panda__example_robot_data/example-robot-data/robots/panda_description/urdf/panda.urdf"
R, P = JointType.REVOLUTE, JointType.PRISMATIC
_DEG = math.pi / 180.0

# id -> (link count, fixed base, {joint: (type, lower, upper)}), from the XML files
EXPECTED: dict[str, tuple[int, bool, dict[str, tuple[JointType, float, float]]]] = {
    # hingecabinet_body.xml: two doors, range -1.57..0 and 0..1.57 (compiler angle radian)
    "vk_hinge_cabinet": (3, True, {"leftdoorhinge": (R, -1.57, 0.0), "rightdoorhinge": (R, 0.0, 1.57)}),
    "vk_slide_cabinet": (2, True, {"slidedoor_joint": (P, 0.0, 0.44)}),
    "vk_box_cabinet": (2, True, {"boxdoorhinge": (R, -1.57, 0.0)}),
    "vk_microwave": (2, True, {"micro0joint": (R, -2.094, 0.0)}),
    # oven_body.xml: knobs hinge -1.57..0, burners slide -0.009..0, light switch -0.7..0, light -0.05..0
    "vk_oven": (11, True, {**{f"knob{i}_joint": (R, -1.57, 0.0) for i in range(1, 5)},
                           **{f"burner{i}_joint": (P, -0.009, 0.0) for i in range(1, 5)},
                           "lightswitch_joint": (R, -0.7, 0.0), "light_joint": (P, -0.05, 0.0)}),
    # dishwasher_body.xml: top rack slide 0..0.274, door hinge -1.5..0 (bottom_rack is commented out)
    "vk_dishwasher": (3, True, {"top_rack": (P, 0.0, 0.274), "door": (R, -1.5, 0.0)}),
    # lightButtons: default class range -0.005..0 for the 3 lights and 3 buttons
    "vk_light_buttons": (7, True, {**{f"{c}_light": (P, -0.005, 0.0) for c in ("red", "green", "blue")},
                                   **{f"{c}_button": (P, -0.005, 0.0) for c in ("red", "green", "blue")}}),
    "vk_kettle": (1, False, {}),
    # LIBERO: 3 slide drawers each
    "libero_white_cabinet": (4, True, {n: (P, -0.16, 0.01) for n in ("top_level", "middle_level",
                                                                      "bottom_level")}),
    "libero_wooden_cabinet": (4, True, {n: (P, -0.16, 0.01) for n in ("top_level", "middle_level",
                                                                       "bottom_level")}),
    "libero_short_cabinet": (4, True, {n: (P, -0.005, 0.16) for n in ("middle_level", "top_region",
                                                                       "bottom_region")}),
    # robosuite door: range "0.0 0.4" read in degrees (no compiler angle="radian" in the file)
    "robosuite_door": (2, True, {"hinge": (R, 0.0, 0.4 * _DEG)}),
    "robosuite_door_lock": (3, True, {"hinge": (R, 0.0, 0.4 * _DEG),
                                      "latch_joint": (R, -1.57 * _DEG, 1.57 * _DEG)}),
    "ycb_apple_urdf": (1, False, {}),
}


def _annotations() -> dict[str, AssetAnnotation]:
    cat = load_annotations(DATA)
    assert not cat.invalid
    return {a.id: a for a in cat.assets}


def load(ann: AssetAnnotation, catalog: Path) -> AssetModel:
    loader = load_urdf if ann.source.endswith(".urdf") else load_mjcf
    return loader(catalog / ann.source, ann, catalog_dir=catalog)


def fk(model: AssetModel, q: dict[str, float]) -> dict[str, np.ndarray]:
    """Link frames (4x4) in the root frame at joint positions ``q`` (missing joints: 0)."""
    from scipy.spatial.transform import Rotation

    out = {model.links[0].name: model.links[0].pose.matrix()}
    for j in model.joints:   # loaders emit joints parents-first
        motion = np.eye(4)
        v = q.get(j.name, 0.0)
        if j.type == R:
            motion[:3, :3] = Rotation.from_rotvec(np.asarray(j.axis) * v).as_matrix()
        elif j.type == P:
            motion[:3, 3] = np.asarray(j.axis) * v
        out[j.child] = out[j.parent] @ j.frame.matrix() @ motion
    return out


def test_annotation_file_covers_every_expected_asset():
    assert set(_annotations()) == set(EXPECTED)


@pytest.mark.parametrize("asset_id", sorted(EXPECTED))
def test_shared_asset_loads_with_expected_joints(shared_assets, asset_id):
    ann = _annotations()[asset_id]
    model = load(ann, shared_assets)
    n_links, fixed, joints = EXPECTED[asset_id]
    assert len(model.links) == n_links
    assert model.fixed_base is fixed
    got = {j.name: (j.type, j.lower, j.upper) for j in model.joints}
    assert set(got) == set(joints)
    for name, (kind, lo, hi) in joints.items():
        assert got[name][0] == kind, name
        assert got[name][1] == pytest.approx(lo, abs=1e-6), name
        assert got[name][2] == pytest.approx(hi, abs=1e-6), name
    names = [lk.name for lk in model.links]
    assert len(set(names)) == len(names)
    parents_first = {names[0]}
    for j in model.joints:
        assert j.parent in parents_first and j.child not in parents_first
        parents_first.add(j.child)
        assert abs(np.linalg.norm(j.axis) - 1.0) < 1e-9
    # zero configuration: composing joint frames reproduces the link poses
    frames = fk(model, {})
    for lk in model.links:
        np.testing.assert_allclose(frames[lk.name], lk.pose.matrix(), atol=1e-9)
    for lk in model.links:
        for part in lk.visuals + (lk.collision_source or ()):
            assert part.vertices.ndim == 2 and part.vertices.shape[1] == 3
            assert np.isfinite(part.vertices).all()
            assert part.faces.max() < len(part.vertices)
            if part.uvs is not None:
                assert part.uvs.shape == (len(part.vertices), 2)
            if part.material is not None:
                assert part.material in model.materials
    assert any(lk.visuals for lk in model.links)
    assert any(lk.collision_source for lk in model.links)
    for spec in model.materials.values():
        if spec.base_color_texture is not None:
            assert spec.base_color_texture.is_file()
            assert spec.base_color_texture.resolve().is_relative_to(shared_assets.resolve())
    # every moving link has a mass from the source (MuJoCo's compiled inertia) or none at all
    for lk in model.links:
        assert (lk.mass is not None) == lk.mass_from_source
        if lk.mass is not None:
            assert lk.mass.mass > 0 and min(lk.mass.diagonal_inertia) > 0


def test_mjcf_visual_and_collision_split(shared_assets):
    """furniture_sim: visuals group 1 contype 0 conaffinity 0; colliders group 4 conaffinity 1 (9 boxes in
    the hinge cabinet's carcass). LIBERO: visual mesh group 1, collision boxes group 0. robosuite door:
    group 1 colliding geoms only, so they are both visual and collision."""
    ann = _annotations()
    cab = load(ann["vk_hinge_cabinet"], shared_assets)
    assert len(cab.links[0].visuals) == 9 and len(cab.links[0].collision_source) == 9
    libero = load(ann["libero_short_cabinet"], shared_assets)
    drawer = libero.link("drawer_middle")
    assert len(drawer.visuals) == 1 and len(drawer.collision_source) == 10
    assert drawer.visuals[0].uvs is not None           # the .msh mesh carries texture coordinates
    door = load(ann["robosuite_door"], shared_assets)
    assert [len(lk.visuals) for lk in door.links] == [len(lk.collision_source) for lk in door.links] == [2, 3]
    # the oven's burners have visual geoms only: the source says they do not collide (not "unknown")
    oven = load(ann["vk_oven"], shared_assets)
    assert oven.link("Burner_1").collision_source == () and oven.link("Burner_1").visuals
    assert len(oven.link("knob_1").collision_source) == 2


@pytest.mark.parametrize("asset_id,joint,value", [
    ("vk_hinge_cabinet", "leftdoorhinge", -1.0), ("vk_microwave", "micro0joint", -1.2),
    ("robosuite_door_lock", "latch_joint", 0.02), ("libero_short_cabinet", "top_region", 0.12),
    ("vk_dishwasher", "door", -0.8), ("vk_oven", "knob3_joint", -0.9)])
def test_mjcf_kinematics_match_mujoco(shared_assets, asset_id, joint, value):
    """Box collision geoms placed by our joint frames at q != 0 sit where MuJoCo puts them."""
    import mujoco

    ann = _annotations()[asset_id]
    model = load(ann, shared_assets)
    m = mujoco.MjModel.from_xml_path(str(shared_assets / ann.source))
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    top = [b for b in range(1, m.nbody) if m.body_parentid[b] == 0][0]
    root_world = np.eye(4)
    root_world[:3, :3], root_world[:3, 3] = d.xmat[top].reshape(3, 3), d.xpos[top]
    jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, joint)
    d.qpos[:] = m.qpos0
    d.qpos[m.jnt_qposadr[jid]] += value
    mujoco.mj_kinematics(m, d)
    frames = fk(model, {joint: value})
    checked = 0
    for lk in model.links:
        for part in lk.collision_source or ():
            label = part.name[len(f"{lk.name}_collision_"):]
            gid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, label)
            if gid < 0 and label.startswith("geom") and label[4:].isdigit():
                gid = int(label[4:])
            if gid < 0 or m.geom_type[gid] != mujoco.mjtGeom.mjGEOM_BOX:
                continue
            centre = root_world @ frames[lk.name] @ np.append(part.vertices.mean(axis=0), 1.0)
            np.testing.assert_allclose(centre[:3], d.geom_xpos[gid], atol=1e-6)
            checked += 1
    assert checked >= 3


def test_panda_urdf(shared_assets):
    """example-robot-data panda.urdf: 7 revolute + 2 prismatic fingers (the second mimics the first;
    kept as a joint) + 3 fixed joints, 13 links; package:// meshes resolve inside the catalog."""
    ann = AssetAnnotation(id="panda", source=PANDA, category="robot", material="metal")
    model = load_urdf(shared_assets / PANDA, ann, catalog_dir=shared_assets)
    movable = [j for j in model.joints if j.type != JointType.FIXED]
    assert len(movable) == 9 and len(model.links) == 13
    assert [j.type for j in movable] == [R] * 7 + [P] * 2
    j4 = next(j for j in model.joints if j.name == "panda_joint4")
    assert (j4.lower, j4.upper, j4.max_effort, j4.max_velocity) == (-3.0718, -0.0698, 87.0, 2.175)
    assert j4.damping == pytest.approx(0.003)
    f2 = next(j for j in model.joints if j.name == "panda_finger_joint2")
    assert (f2.lower, f2.upper) == (0.0, 0.04) and f2.axis == (0.0, -1.0, 0.0)
    assert model.fixed_base is False                   # no 'world' link in this URDF
    link0 = model.link("panda_link0")
    assert len(link0.visuals) == 12                    # 12 coloured <triangles> groups in link0.dae
    assert len(link0.collision_source) == 1
    assert link0.mass_from_source and link0.mass.mass == pytest.approx(0.629769)
    colours = {model.materials[p.material].base_color for lk in model.links for p in lk.visuals}
    assert len(colours) >= 3                            # white, dark grey, black parts of the arm
    # kinematics agree with Pinocchio's URDF parser at an arbitrary configuration
    import pinocchio as pin

    pm = pin.buildModelFromUrdf(str(shared_assets / PANDA))
    pd = pm.createData()
    q = np.array([0.3, -0.5, 0.7, -1.9, 0.4, 1.6, -0.8, 0.02, 0.03])
    pin.forwardKinematics(pm, pd, q)
    pin.updateFramePlacements(pm, pd)
    ours = fk(model, {j.name: float(v) for j, v in zip(movable, q)})
    for name in ("panda_link3", "panda_link7", "panda_hand_tcp", "panda_leftfinger", "panda_rightfinger"):
        ref = pd.oMf[pm.getFrameId(name)].homogeneous
        np.testing.assert_allclose(ours[name], ref, atol=1e-9, err_msg=name)


def test_ycb_urdf_scale_and_texture(shared_assets):
    ann = _annotations()["ycb_apple_urdf"]
    model = load(ann, shared_assets)
    (link,) = model.links
    v = np.vstack([p.vertices for p in link.visuals])
    assert 0.06 < float((v.max(0) - v.min(0)).max()) < 0.09       # a 7.5 cm apple, not 75 cm
    (mat,) = {model.materials[p.material] for p in link.visuals}
    assert mat.base_color_texture is not None and mat.base_color_texture.name == "texture_map.png"
    assert link.visuals[0].uvs is not None
    assert link.mass is None and not link.mass_from_source          # 1 kg placeholder rejected
    assert len(link.collision_source) == 1                          # the VHACD OBJ


def test_mjcf_fragment_needs_no_file_in_catalog(shared_assets, tmp_path):
    """The body-chain wrapper lives in a temporary folder: nothing is written beside the source."""
    ann = _annotations()["vk_kettle"]
    before = sorted((shared_assets / ann.source).parent.iterdir())
    model = load(ann, shared_assets)
    assert sorted((shared_assets / ann.source).parent.iterdir()) == before
    assert model.links[0].name == "kettleroot0" and model.links[0].mass.mass == pytest.approx(0.88)


# ------------------------------------------------------------------------------------ bad inputs


def _ann(source: str, **kw) -> AssetAnnotation:
    return AssetAnnotation(id="bad", source=source, category="test", **kw)


_BOX_LINK = '<link name="{n}"><visual><geometry><box size="0.1 0.1 0.1"/></geometry></visual></link>'


def _urdf(tmp: Path, body: str, name: str = "r.urdf") -> Path:
    p = tmp / name
    p.write_text(f'<?xml version="1.0"?>\n<robot name="r">{body}</robot>')
    return p


def _expect(loader, path: Path, catalog: Path, *needles: str) -> str:
    with pytest.raises(ItemError) as e:
        loader(path, _ann(path.name), catalog_dir=catalog)
    msg = str(e.value)
    assert "\n" not in msg and str(path) in msg
    for n in needles:
        assert n in msg, msg
    return msg


def _joint(name, parent, child, kind="revolute", origin='xyz="0 0 0.1"', limit='lower="-1" upper="1"'):
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin {origin}/><axis xyz="0 0 1"/><limit {limit} effort="1" velocity="1"/></joint>')


def test_urdf_cycle(tmp_path):
    links = "".join(_BOX_LINK.format(n=n) for n in "abc")
    p = _urdf(tmp_path, links + _joint("j1", "a", "b") + _joint("j2", "b", "c") + _joint("j3", "c", "a"))
    msg = _expect(load_urdf, p, tmp_path, "cycle")
    assert all(n in msg for n in ("a", "b", "c"))


def test_urdf_missing_parent(tmp_path):
    p = _urdf(tmp_path, _BOX_LINK.format(n="a") + _BOX_LINK.format(n="b") + _joint("j", "ghost", "b"))
    _expect(load_urdf, p, tmp_path, "'j'", "'ghost'", "does not exist")


def test_urdf_nan_origin(tmp_path):
    p = _urdf(tmp_path, _BOX_LINK.format(n="a") + _BOX_LINK.format(n="b")
              + _joint("j", "a", "b", origin='xyz="0 nan 0"'))
    _expect(load_urdf, p, tmp_path, "non-finite", "'j'")


def test_urdf_contact_extension(tmp_path):
    """<contact> per link: friction, spinning (torsional) and rolling friction, restitution; links
    without one keep None; a negative or missing value is a one-line error."""
    contact = ('<contact><lateral_friction value="0.7"/><spinning_friction value="0.01"/>'
               '<rolling_friction value="0.002"/><stiffness value="3e4"/></contact>')
    a = _BOX_LINK.format(n="a").replace("</link>", contact + "</link>")
    m = load_urdf(_urdf(tmp_path, a + _BOX_LINK.format(n="b") + _joint("j", "a", "b")), _ann("r.urdf"),
                  catalog_dir=tmp_path)
    c = m.link("a").contact
    assert (c.friction, c.torsional_friction, c.rolling_friction, c.restitution) == (0.7, 0.01, 0.002, None)
    assert m.link("b").contact is None
    bad = _BOX_LINK.format(n="a").replace("</link>", '<contact><rolling_friction value="-1"/></contact></link>')
    _expect(load_urdf, _urdf(tmp_path, bad), tmp_path, "link 'a' contact", "rolling_friction", ">= 0")
    bad = _BOX_LINK.format(n="a").replace("</link>", "<contact><spinning_friction/></contact></link>")
    _expect(load_urdf, _urdf(tmp_path, bad), tmp_path, "spinning_friction", "no value")


def test_urdf_solreflimit_extension(tmp_path):
    """<limit solreflimit="time_constant damping_ratio">: the joint's limit stops (Joint.limit_solref);
    a joint without one keeps None; a non-positive value is a one-line error."""
    ab = _BOX_LINK.format(n="a") + _BOX_LINK.format(n="b")
    m = load_urdf(_urdf(tmp_path, ab + _joint("j", "a", "b", limit='lower="0" upper="1" solreflimit="0.02 2"')),
                  _ann("r.urdf"), catalog_dir=tmp_path)
    assert m.joints[0].limit_solref == (0.02, 2.0)
    m = load_urdf(_urdf(tmp_path, ab + _joint("j", "a", "b")), _ann("r.urdf"), catalog_dir=tmp_path)
    assert m.joints[0].limit_solref is None
    _expect(load_urdf, _urdf(tmp_path, ab + _joint("j", "a", "b", limit='lower="0" upper="1" solreflimit="0.02 0"')),
            tmp_path, "'j'", "solreflimit", "positive")


def test_urdf_limits_axis_duplicates_roots(tmp_path):
    ab = _BOX_LINK.format(n="a") + _BOX_LINK.format(n="b")
    _expect(load_urdf, _urdf(tmp_path, ab + _joint("j", "a", "b", limit='lower="1" upper="-1"')), tmp_path,
            "lower limit 1.0 > upper limit -1.0")
    _expect(load_urdf, _urdf(tmp_path, ab + _joint("j", "a", "b").replace('xyz="0 0 1"', 'xyz="0 0 0"')),
            tmp_path, "zero axis")
    _expect(load_urdf, _urdf(tmp_path, ab + _BOX_LINK.format(n="a")), tmp_path, "duplicate link name 'a'")
    _expect(load_urdf, _urdf(tmp_path, ab), tmp_path, "exactly one root", "found 2")
    _expect(load_urdf, _urdf(tmp_path, ab + _joint("j", "a", "b", kind="planar")), tmp_path,
            "unsupported type")


def test_urdf_mesh_escaping_catalog(tmp_path):
    catalog = tmp_path / "catalog"
    catalog.mkdir()
    import trimesh

    trimesh.creation.box().export(tmp_path / "outside.stl")
    for uri in ("../outside.stl", str(tmp_path / "outside.stl"), "package://x/../../outside.stl"):
        body = f'<link name="a"><visual><geometry><mesh filename="{uri}"/></geometry></visual></link>'
        _expect(load_urdf, _urdf(catalog, body), catalog, "escapes the catalog")
    # the same file inside the catalog loads, with scale applied
    trimesh.creation.box().export(catalog / "inside.stl")
    body = ('<link name="a"><visual><geometry><mesh filename="inside.stl" scale="2 2 2"/>'
            '</geometry></visual></link>')
    p = _urdf(catalog, body)
    model = load_urdf(p, _ann(p.name), catalog_dir=catalog)
    np.testing.assert_allclose(np.ptp(model.links[0].visuals[0].vertices, axis=0), [2, 2, 2])


def test_urdf_doctype_and_malformed(tmp_path):
    p = tmp_path / "e.urdf"
    p.write_text('<?xml version="1.0"?><!DOCTYPE r [<!ENTITY a "aaaa">]><robot name="r">&a;</robot>')
    _expect(load_urdf, p, tmp_path, "DOCTYPE")
    p.write_text('<robot name="r"><link name="a">')
    _expect(load_urdf, p, tmp_path, "malformed XML")


def test_urdf_world_link_fixes_base(tmp_path):
    p = _urdf(tmp_path, '<link name="world"/>' + _BOX_LINK.format(n="a") + _BOX_LINK.format(n="b")
              + _joint("w", "world", "a", kind="fixed") + _joint("j", "a", "b"))
    model = load_urdf(p, _ann(p.name), catalog_dir=tmp_path)
    assert model.fixed_base and [lk.name for lk in model.links] == ["a", "b"] and len(model.joints) == 1
    assert load_urdf(p, _ann(p.name, fixed_base=False), catalog_dir=tmp_path).fixed_base is False
    free = _urdf(tmp_path, '<link name="world"/>' + _BOX_LINK.format(n="a")
                 + _joint("w", "world", "a", kind="floating"), name="free.urdf")
    model = load_urdf(free, _ann(free.name), catalog_dir=tmp_path)
    assert model.fixed_base is False and [lk.name for lk in model.links] == ["a"] and not model.joints
    elsewhere = _urdf(tmp_path, _BOX_LINK.format(n="a") + _BOX_LINK.format(n="b")
                      + _joint("f", "a", "b", kind="floating"), name="f2.urdf")
    _expect(load_urdf, elsewhere, tmp_path, "floating joint 'f'")


def _mjcf(tmp: Path, body: str, name: str = "m.xml", extra: str = "") -> Path:
    p = tmp / name
    p.write_text(f'<mujoco model="m">{extra}<worldbody>{body}</worldbody></mujoco>')
    return p


def test_mjcf_does_not_compile(tmp_path):
    p = _mjcf(tmp_path, '<body><geom type="mesh" mesh="nope"/></body>')
    _expect(load_mjcf, p, tmp_path, "does not compile", "nope")


def test_mjcf_unsupported_structures(tmp_path):
    geom = '<geom type="box" size=".1 .1 .1"/>'
    _expect(load_mjcf, _mjcf(tmp_path, f'<body>{geom}<body><joint type="ball"/>{geom}</body></body>'),
            tmp_path, "ball joint")
    _expect(load_mjcf, _mjcf(tmp_path, f'<body><freejoint/>{geom}</body><body pos="1 0 0">{geom}</body>'),
            tmp_path, "free joint beside other top-level bodies")
    two = f'<body>{geom}<body><joint type="hinge"/><joint type="slide"/>{geom}</body></body>'
    _expect(load_mjcf, _mjcf(tmp_path, two), tmp_path, "2 joints")


def test_mjcf_include_escaping_catalog(tmp_path):
    catalog = tmp_path / "catalog"
    catalog.mkdir()
    (tmp_path / "evil.xml").write_text('<mujocoinclude><body><geom size=".1"/></body></mujocoinclude>')
    p = _mjcf(catalog, "", extra='<include file="../evil.xml"/>')
    _expect(load_mjcf, p, catalog, "escapes the catalog")


def test_mjcf_free_root_and_welded_bodies(tmp_path):
    """A free joint on the root gives a movable base; a jointless child body merges into its parent
    (masses add up); a slide joint anchored off the body origin gets its frame at the anchor."""
    xml = ('<body><freejoint/><geom type="box" size=".1 .1 .1" mass="2"/>'
           '<body pos="0 0 .3"><geom type="sphere" size=".05" mass="1"/>'
           '<body pos=".2 0 0"><joint type="hinge" axis="0 2 0" pos=".1 0 0" range="-30 45"/>'
           '<geom type="box" size=".05 .05 .05" mass=".5"/></body></body></body>')
    p = _mjcf(tmp_path, xml)
    model = load_mjcf(p, _ann(p.name), catalog_dir=tmp_path)
    assert model.fixed_base is False and len(model.links) == 2
    root, child = model.links
    assert root.mass.mass == pytest.approx(3.0) and root.mass.center_of_mass[2] == pytest.approx(0.1)
    (j,) = model.joints
    assert j.axis == pytest.approx((0, 1, 0)) and (j.lower, j.upper) == pytest.approx((-30 * _DEG, 45 * _DEG))
    np.testing.assert_allclose(j.frame.position, (0.3, 0, 0.3), atol=1e-12)
    np.testing.assert_allclose(child.visuals[0].vertices.mean(axis=0), (-0.1, 0, 0), atol=1e-12)


# ------------------------------------------------------------------ USD package + Newton joint limits

# The furniture_sim joints carry MuJoCo frictionloss (2 N m on the cabinet and microwave doors, 2 N on the
# slide door, 1 N m / 1 N on the oven's light switch and light block, 0.1 N m on the robosuite latch):
# joint_limit_check sizes its drive to hold twice the joint's static load (friction + gravity), so
# these joints must reach their limits with the check's defaults.
_ARTICULATED = sorted(i for i, (_, _, joints) in EXPECTED.items() if joints)
_DEFAULT_LIMIT_ASSET = "libero_white_cabinet"


def with_hull_colliders(model: AssetModel) -> AssetModel:
    """Colliders from the collision stage (for these sources: one convex hull per collision part)."""
    from stages.collision import CollisionConfig, compute_colliders

    return compute_colliders(model, CollisionConfig(), np.random.default_rng(0))


def _limit_check(shared_assets: Path, tmp_path: Path, asset_id: str):
    pytest.importorskip("newton_usd_schemas", reason="newton's USD importer needs newton-usd-schemas")
    usd_schemas = pytest.importorskip("usd_schemas")
    physics_checks = pytest.importorskip("stages.physics_checks")
    model = with_hull_colliders(load(_annotations()[asset_id], shared_assets))
    pkg = usd_schemas.write_asset_package(model, tmp_path / asset_id, pipeline_version="test")
    report = usd_schemas.validate_package(pkg.root_path)
    assert report.ok, report.summary()
    assert pkg.joint_count == len(model.joints) + 1          # + the joint fixing the root to the world
    result = physics_checks.joint_limit_check(pkg.root_path, device="cpu")
    assert len(result.joints) == len(model.joints)
    return result


def test_articulated_package_joints_reach_limits_in_newton(shared_assets, tmp_path):
    """One representative in the default suite: 3 drawers driven to -0.16 m and +0.01 m."""
    result = _limit_check(shared_assets, tmp_path, _DEFAULT_LIMIT_ASSET)
    assert result.passed, result.reasons
    for j in result.joints:
        assert j.reached_lower == pytest.approx(-0.16, abs=0.005)
        assert j.reached_upper == pytest.approx(0.01, abs=0.005)


@pytest.mark.slow
@pytest.mark.parametrize("asset_id", [i for i in _ARTICULATED if i != _DEFAULT_LIMIT_ASSET])
def test_every_articulated_package_joints_reach_limits_in_newton(shared_assets, tmp_path, asset_id):
    result = _limit_check(shared_assets, tmp_path, asset_id)
    assert result.passed, result.reasons
    for j in result.joints:     # and really moved across its range (not only within the tolerance)
        if j.upper - j.lower > 2 * j.tolerance:
            assert j.reached_upper - j.reached_lower > 0.9 * (j.upper - j.lower), j


# ------------------------------------------------------------------------ small synthetic sources


def test_urdf_primitives_materials_inertia_mimic(tmp_path, caplog):
    from PIL import Image

    Image.new("RGB", (4, 4), (200, 10, 10)).save(tmp_path / "red.png")
    body = """
      <material name="blue"><color rgba="0 0 1 1"/></material>
      <link name="base">
        <visual><geometry><box size="0.2 0.4 0.6"/></geometry><material name="blue"/></visual>
        <collision><origin xyz="0 0 0.5" rpy="0 1.5707963267948966 0"/>
          <geometry><cylinder radius="0.1" length="0.4"/></geometry></collision>
        <inertial><origin xyz="0 0 0.1"/><mass value="2.0"/>
          <inertia ixx="0.08" ixy="0" ixz="0" iyy="0.07" iyz="0" izz="0.03"/></inertial>
      </link>
      <link name="ball">
        <visual><geometry><sphere radius="0.05"/></geometry>
          <material name="tex"><texture filename="red.png"/></material></visual>
      </link>
      <link name="twin"><visual><geometry><capsule radius="0.02" length="0.1"/></geometry></visual></link>
      <joint name="spin" type="continuous"><parent link="base"/><child link="ball"/>
        <origin xyz="0 0 0.35"/><axis xyz="0 0 3"/><dynamics damping="0.5" friction="0.1"/></joint>
      <joint name="copy" type="prismatic"><parent link="base"/><child link="twin"/><axis xyz="1 0 0"/>
        <limit lower="-0.1" upper="0.2" effort="0" velocity="1"/><mimic joint="spin"/></joint>"""
    p = _urdf(tmp_path, body)
    with caplog.at_level("INFO", logger="stages.loaders.urdf"):
        model = load_urdf(p, _ann(p.name, material="plastic"), catalog_dir=tmp_path)
    assert any("mimic" in r.message for r in caplog.records)
    base, ball, twin = model.links
    box = base.visuals[0]
    np.testing.assert_allclose(np.ptp(box.vertices, axis=0), [0.2, 0.4, 0.6], atol=1e-12)
    assert model.materials[box.material].base_color == (0.0, 0.0, 1.0)
    cyl = base.collision_source[0]                 # rotated about Y: its axis now along X
    np.testing.assert_allclose(np.ptp(cyl.vertices, axis=0), [0.4, 0.2, 0.2], atol=1e-3)
    np.testing.assert_allclose(cyl.vertices.mean(axis=0), [0, 0, 0.5], atol=1e-3)
    sphere = ball.visuals[0]
    assert np.linalg.norm(sphere.vertices, axis=1).max() == pytest.approx(0.05)
    assert model.materials[sphere.material].base_color_texture == (tmp_path / "red.png").resolve()
    assert sphere.uvs is not None                  # box-projected for the texture
    assert np.ptp(twin.visuals[0].vertices[:, 2]) == pytest.approx(0.14)
    assert base.mass_from_source and base.mass.mass == 2.0 and base.mass.center_of_mass == (0, 0, 0.1)
    assert sorted(base.mass.diagonal_inertia) == pytest.approx([0.03, 0.07, 0.08])
    spin, copy = model.joints
    assert spin.type == R and spin.lower is None and spin.upper is None and spin.axis == (0, 0, 1)
    assert (spin.damping, spin.friction) == (0.5, 0.1)
    assert copy.type == P and (copy.lower, copy.upper) == (-0.1, 0.2) and copy.max_effort is None
    assert ball.pose.position == pytest.approx((0, 0, 0.35))


_DAE = """<?xml version="1.0"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
 <asset><unit name="centimeter" meter="0.01"/><up_axis>Y_UP</up_axis></asset>
 <library_effects><effect id="e"><profile_COMMON><technique sid="t"><phong>
   <diffuse><color>0.1 0.2 0.3 1</color></diffuse></phong></technique></profile_COMMON></effect>
 </library_effects>
 <library_materials><material id="m" name="paint"><instance_effect url="#e"/></material></library_materials>
 <library_geometries><geometry id="g"><mesh>
   <source id="p"><float_array id="pa" count="12">0 0 0 10 0 0 10 20 0 0 20 0</float_array>
     <technique_common><accessor source="#pa" count="4" stride="3"/></technique_common></source>
   <vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
   <polylist material="s" count="1"><input semantic="VERTEX" source="#v" offset="0"/>
     <vcount>4</vcount><p>0 1 2 3</p></polylist>
 </mesh></geometry></library_geometries>
 <library_visual_scenes><visual_scene id="vs"><node id="n"><translate>0 0 5</translate>
   <instance_geometry url="#g"><bind_material><technique_common>
     <instance_material symbol="s" target="#m"/></technique_common></bind_material></instance_geometry>
 </node></visual_scene></library_visual_scenes>
 <scene><instance_visual_scene url="#vs"/></scene>
</COLLADA>"""


def test_urdf_collada_units_up_axis_and_colour(tmp_path):
    (tmp_path / "quad.dae").write_text(_DAE)
    link = '<link name="a"><visual><geometry><mesh filename="quad.dae"/></geometry></visual></link>'
    p = _urdf(tmp_path, link)
    model = load_urdf(p, _ann(p.name), catalog_dir=tmp_path)
    (part,) = model.links[0].visuals
    assert part.faces.shape == (2, 3) and len(part.vertices) == 4      # the quad, fan-triangulated
    # centimetres -> metres, then Y up -> Z up: (x, y, z) -> (x, -z, y); node translate z = 5 cm
    np.testing.assert_allclose(part.vertices.min(axis=0), [0.0, -0.05, 0.0], atol=1e-12)
    np.testing.assert_allclose(part.vertices.max(axis=0), [0.1, -0.05, 0.2], atol=1e-12)
    mat = model.materials[part.material]
    assert mat.name == "paint" and mat.base_color == pytest.approx((0.1, 0.2, 0.3))


def test_units_and_up_axis_annotation(tmp_path):
    body = (_BOX_LINK.format(n="a") + _BOX_LINK.format(n="b")
            + _joint("j", "a", "b", kind="prismatic", origin='xyz="0 1 0"', limit='lower="0" upper="2"'))
    p = _urdf(tmp_path, body)
    model = load_urdf(p, _ann(p.name, meters_per_unit=0.5, up_axis="Y"), catalog_dir=tmp_path)
    (j,) = model.joints
    assert (j.lower, j.upper) == (0.0, 1.0) and j.frame.position == pytest.approx((0, 0.5, 0))
    np.testing.assert_allclose(np.ptp(model.links[0].visuals[0].vertices, axis=0), [0.05] * 3)
    frames = fk(model, {})
    np.testing.assert_allclose(frames["b"][:3, 3], [0, 0, 0.5], atol=1e-12)   # source +Y is now up


def test_mjcf_reference_position_texture_and_groups(tmp_path):
    """A joint with ref != 0: limits are relative to the reference pose (the zero configuration).
    menagerie-style groups: group 2 visual-only mesh, group 3 colliding primitive."""
    from PIL import Image

    Image.new("RGB", (4, 4), (0, 200, 0)).save(tmp_path / "green.png")
    import trimesh

    trimesh.creation.box(extents=(0.1, 0.1, 0.1)).export(tmp_path / "cube.stl")
    extra = ('<compiler angle="radian"/><asset><mesh name="cube" file="cube.stl"/>'
             '<texture name="t" type="2d" file="green.png"/>'
             '<material name="m" texture="t" rgba="1 1 1 1"/></asset>')
    xml = ('<body><geom type="box" size=".2 .2 .2"/>'
           '<body pos="0 0 .5"><joint type="hinge" axis="1 0 0" ref="0.3" range="0 1"/>'
           '<geom type="mesh" mesh="cube" group="2" contype="0" conaffinity="0" material="m"/>'
           '<geom type="capsule" size=".05 .1" group="3"/></body></body>')
    p = _mjcf(tmp_path, xml, extra=extra)
    model = load_mjcf(p, _ann(p.name), catalog_dir=tmp_path)
    (j,) = model.joints
    assert (j.lower, j.upper) == pytest.approx((-0.3, 0.7))
    child = model.links[1]
    assert len(child.visuals) == 1 and len(child.collision_source) == 1
    vis = child.visuals[0]
    assert model.materials[vis.material].base_color_texture == (tmp_path / "green.png").resolve()
    assert vis.uvs is not None and vis.uvs.shape == (len(vis.vertices), 2)
    np.testing.assert_allclose(np.ptp(vis.vertices, axis=0), [0.1] * 3, atol=1e-6)
    np.testing.assert_allclose(np.ptp(child.collision_source[0].vertices, axis=0), [0.1, 0.1, 0.3], atol=1e-6)
    # the root's box has no visual-only sibling: it is both visual and collider
    assert len(model.links[0].visuals) == len(model.links[0].collision_source) == 1


@pytest.mark.slow
@pytest.mark.parametrize("asset_id", sorted(i for i, (_, _, joints) in EXPECTED.items() if not joints))
def test_rigid_urdf_mjcf_package_comes_to_rest_in_newton(shared_assets, tmp_path, asset_id):
    """The jointless sources (MJCF kettle fragment, YCB URDF) dropped on a plane come to rest."""
    pytest.importorskip("newton_usd_schemas", reason="newton's USD importer needs newton-usd-schemas")
    usd_schemas = pytest.importorskip("usd_schemas")
    physics_checks = pytest.importorskip("stages.physics_checks")
    model = with_hull_colliders(load(_annotations()[asset_id], shared_assets))
    pkg = usd_schemas.write_asset_package(model, tmp_path / asset_id, pipeline_version="test")
    assert usd_schemas.validate_package(pkg.root_path).ok
    report = physics_checks.rest_check(pkg.root_path, device="cpu")
    assert report.passed, report.reasons


def test_mjcf_robots_free_base_actuator_limits(shared_assets):
    """newton-assets h1.xml: free joint at the pelvis (movable base), 19 hinges, effort limits from the
    motors' ctrlrange (knee 300 N m, ankle 40 N m). menagerie 2f85.xml: its 4-bar linkage closes through
    equality constraints (dropped), leaving a tree of 8 hinges on a fixed base."""
    src = "robots/unitree_h1__newton_assets/mjcf/h1.xml"
    h1 = load_mjcf(shared_assets / src,
                   AssetAnnotation(id="h1", source=src, category="robot", material="metal"),
                   catalog_dir=shared_assets)
    assert h1.fixed_base is False and len(h1.joints) == 19 and all(j.type == R for j in h1.joints)
    effort = {j.name: j.max_effort for j in h1.joints}
    assert effort["left_knee_joint"] == 300.0 and effort["right_ankle_joint"] == 40.0
    src = "robots/robotiq_2f85__menagerie/2f85.xml"
    grip = load_mjcf(shared_assets / src,
                     AssetAnnotation(id="g", source=src, category="robot", material="metal"),
                     catalog_dir=shared_assets)
    assert grip.fixed_base is True and len(grip.joints) == 8 and len(grip.links) == 9
    # MuJoCo collides mesh geoms as their convex hulls; the collision parts are those hulls
    import trimesh

    cols = [p for lk in grip.links for p in lk.collision_source or ()]
    assert cols and all(trimesh.Trimesh(p.vertices, p.faces).is_convex for p in cols)
    assert not all(trimesh.Trimesh(p.vertices, p.faces).is_convex for lk in grip.links for p in lk.visuals)


@pytest.mark.parametrize("asset_id,values", [
    ("robosuite_door_lock", {"hinge": 0.005, "latch_joint": -0.02}),
    ("vk_oven", {"knob2_joint": -1.0, "burner3_joint": -0.005, "lightswitch_joint": -0.5}),
    ("libero_short_cabinet", {"middle_level": 0.1, "top_region": 0.05}),
])
def test_newton_kinematics_of_written_package_match_the_model(shared_assets, tmp_path, asset_id, values):
    """Newton's add_usd of the written package, at joint positions != 0, puts every body where the
    AssetModel's joint frames put the link (writer + importer keep frames, axes and signs)."""
    pytest.importorskip("newton_usd_schemas", reason="newton's USD importer needs newton-usd-schemas")
    usd_schemas = pytest.importorskip("usd_schemas")
    import newton
    from scipy.spatial.transform import Rotation

    model = with_hull_colliders(load(_annotations()[asset_id], shared_assets))
    pkg = usd_schemas.write_asset_package(model, tmp_path / asset_id, pipeline_version="test")
    builder = newton.ModelBuilder()
    builder.add_usd(str(pkg.root_path), floating=False, load_visual_shapes=False)
    sim = builder.finalize(device="cpu")
    q = sim.joint_q.numpy()
    labels = [lbl.rsplit("/", 1)[-1] for lbl in builder.joint_label]
    for name, v in values.items():
        q[builder.joint_q_start[labels.index(name)]] = v
    state = sim.state()
    newton.eval_fk(sim, sim.joint_q.__class__(q, dtype=sim.joint_q.dtype, device="cpu"), sim.joint_qd, state)
    body_q = state.body_q.numpy()
    ours = fk(model, values)
    for b, label in enumerate(builder.body_label):
        link = label.rsplit("/", 1)[-1]
        np.testing.assert_allclose(body_q[b, :3], ours[link][:3, 3], atol=1e-5, err_msg=link)
        r = Rotation.from_quat(body_q[b, 3:7]).as_matrix()
        np.testing.assert_allclose(r, ours[link][:3, :3], atol=1e-5, err_msg=link)


_DAE_TEX = """<?xml version="1.0"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
 <asset><up_axis>Z_UP</up_axis></asset>
 <library_images><image id="img"><init_from>{uri}</init_from></image></library_images>
 <library_effects><effect id="e"><profile_COMMON>
   <newparam sid="surf"><surface type="2D"><init_from>img</init_from></surface></newparam>
   <newparam sid="samp"><sampler2D><source>surf</source></sampler2D></newparam>
   <technique sid="t"><lambert><diffuse><texture texture="samp" texcoord="UV"/></diffuse></lambert>
   </technique>
 </profile_COMMON></effect></library_effects>
 <library_materials><material id="m" name="wood"><instance_effect url="#e"/></material></library_materials>
 <library_geometries><geometry id="g"><mesh>
   <source id="p"><float_array id="pa" count="9">0 0 0 1 0 0 0 1 0</float_array>
     <technique_common><accessor source="#pa" count="3" stride="3"/></technique_common></source>
   <source id="t"><float_array id="ta" count="6">0 0 1 0 0 1</float_array>
     <technique_common><accessor source="#ta" count="3" stride="2"/></technique_common></source>
   <vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
   <triangles material="s" count="1"><input semantic="VERTEX" source="#v" offset="0"/>
     <input semantic="TEXCOORD" source="#t" offset="1"/><p>0 0 1 1 2 2</p></triangles>
 </mesh></geometry></library_geometries>
 <library_visual_scenes><visual_scene id="vs"><node id="n"><instance_geometry url="#g"><bind_material>
   <technique_common><instance_material symbol="s" target="#m"/></technique_common></bind_material>
 </instance_geometry></node></visual_scene></library_visual_scenes>
 <scene><instance_visual_scene url="#vs"/></scene>
</COLLADA>"""


def test_mesh_textures_stay_inside_the_catalog(tmp_path):
    """Collada image textures (sampler2D -> surface -> image) load with their UVs; a Collada image or
    an MTL map_Kd outside the catalog folder is rejected like a mesh path."""
    from PIL import Image

    catalog = tmp_path / "catalog"
    catalog.mkdir()
    Image.new("RGB", (2, 2)).save(catalog / "wood%20grain.png".replace("%20", " "))
    Image.new("RGB", (2, 2)).save(tmp_path / "outside.png")
    (catalog / "tri.dae").write_text(_DAE_TEX.format(uri="wood%20grain.png"))
    link = '<link name="a"><visual><geometry><mesh filename="{}"/></geometry></visual></link>'
    p = _urdf(catalog, link.format("tri.dae"))
    model = load_urdf(p, _ann(p.name), catalog_dir=catalog)
    (part,) = model.links[0].visuals
    mat = model.materials[part.material]
    assert mat.name == "wood" and mat.base_color_texture == (catalog / "wood grain.png").resolve()
    np.testing.assert_allclose(sorted(map(tuple, part.uvs)), [(0, 0), (0, 1), (1, 0)])
    (catalog / "tri.dae").write_text(_DAE_TEX.format(uri="../outside.png"))
    _expect(load_urdf, p, catalog, "Collada texture", "escapes the catalog")
    (catalog / "m.obj").write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl x\nf 1 2 3\n")
    (catalog / "m.mtl").write_text("newmtl x\nmap_Kd ../outside.png\n")
    _expect(load_urdf, _urdf(catalog, link.format("m.obj")), catalog, "texture", "escapes the catalog")


# ---------------------------------------------------------------- through the ingest job (runner)


def _ingest(shared_assets: Path, out: Path, only=(), executor: str = "inline", workers: int = 1):
    from pipeline import build_job, run_job

    config: dict = {"catalog": str(shared_assets), "annotations": str(DATA / "annotations.toml")}
    if only:
        config["only"] = list(only)
    job = {"name": "articulated", "seed": 0, "out": str(out), "executor": executor, "workers": workers}
    data = {"job": job,
            "step": [{"name": "assets", "kind": "ingest", "config": config}]}
    return run_job(build_job(data, source="<test>", base_dir=out.parent), progress=False)


def _check_ingested(out: Path, ids) -> None:
    import usd_schemas
    from asset_catalog.index import index_path, query_index

    recs = {r.id: r for r in query_index(index_path(out))}
    assert set(recs) == set(ids)
    for r in recs.values():
        report = usd_schemas.validate_package(out / r.usd_path)
        assert report.ok, (r.id, report.summary())
    pytest.importorskip("newton_usd_schemas", reason="newton's USD importer needs newton-usd-schemas")
    from stages.physics_checks import joint_limit_check, rest_check

    for r in recs.values():
        if EXPECTED[r.id][2]:
            rep = joint_limit_check(out / r.usd_path, device="cpu")
            assert rep.passed and len(rep.joints) == len(EXPECTED[r.id][2]), (r.id, rep.reasons)
        else:
            rep = rest_check(out / r.usd_path, device="cpu")
            assert rep.passed, (r.id, rep.reasons)


def test_ingest_job_articulated_subset(shared_assets, tmp_path):
    """URDF and MJCF entries through the real ingest stage (collision, annotate, writer, validation):
    each package validates and, with Newton's USD importer, its joints reach their limits."""
    ids = ("vk_microwave", "libero_short_cabinet", "ycb_apple_urdf")
    summary = _ingest(shared_assets, tmp_path / "out", only=ids)
    (step,) = summary.steps
    assert step.failed == 0 and step.done == len(ids), step.failures
    _check_ingested(tmp_path / "out", ids)


@pytest.mark.slow
def test_ingest_job_every_articulated_entry(shared_assets, tmp_path):
    summary = _ingest(shared_assets, tmp_path / "out", executor="local", workers=2)
    (step,) = summary.steps
    assert step.failed == 0 and step.done == len(EXPECTED), step.failures
    _check_ingested(tmp_path / "out", EXPECTED)


def test_loading_is_deterministic(shared_assets, tmp_path):
    """Two loads of the same sources write byte-identical packages."""
    import usd_schemas

    for asset_id in ("vk_oven", "ycb_apple_urdf"):
        ann = _annotations()[asset_id]
        blobs = []
        for k in range(2):
            pkg = usd_schemas.write_asset_package(load(ann, shared_assets), tmp_path / f"{asset_id}{k}",
                                                  pipeline_version="test")
            blobs.append([(tmp_path / f"{asset_id}{k}" / f).read_bytes() for f in pkg.files])
        assert blobs[0] == blobs[1], asset_id
