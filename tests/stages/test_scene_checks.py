"""Per-package checks done once (validation cache), rest proven without simulating (checked against
the Newton simulation), and the batched settle of several scenes in one model (CPU)."""

from __future__ import annotations

import importlib.util
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from stages.scene.rules import load_rules
from stages.scene.solver import Library, Populator

CATEGORIES = ["bed", "nightstand", "book", "alarm_clock", "dresser", "rug", "bookshelf", "pillow"]
needs_newton_usd = pytest.mark.skipif(importlib.util.find_spec("newton_usd_schemas") is None,
                                      reason="Newton's add_usd needs newton-usd-schemas")


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    from stages.layout.build import generate_layout
    from stages.layout.spec import LayoutSpec
    from stages.scene.standin import build_library

    root = tmp_path_factory.mktemp("checks")
    index = build_library(root / "lib", categories=CATEGORIES, variants=2, seed=0)
    lay = generate_layout(LayoutSpec(rooms={"bedroom": 1}), 7, root / "layout")
    return Library.from_index(index), lay.plan_json, lay.usd, root


def _scene(world, seed: int, out: Path):
    """A composed bedroom (no settle, no validation) and the Populator that placed it (same seed)."""
    from stages.layout.floorplan import load_floor_plan
    from stages.scene.build import BuildOptions, build_scene

    lib, plan_json, usd, _ = world
    s = build_scene(plan_json, usd, lib, load_rules(), np.random.default_rng(seed), out, out,
                    BuildOptions(n_looks=2, settle=False, validate=False))
    plan = load_floor_plan(plan_json)
    pop = Populator(plan, usd, lib, load_rules(), np.random.default_rng(seed))
    for r in plan.floors[0].rooms:
        pop.populate_room(r)
    assert [i.p.inst for i in pop.insts] == [i.name for i in s.instances]
    return s, pop


def _packages(lib, pop, usd) -> list[Path]:
    return sorted({lib.usd(i.p.record) for i in pop.insts}) + [Path(usd)]


def test_unchanged_packages_are_validated_once(world, tmp_path):
    from stages.scene.checkcache import CheckCache
    from stages.scene.validation import validate_scene

    lib, _, usd, _ = world
    _, pop_a = _scene(world, 5, tmp_path / "a")
    _, pop_b = _scene(world, 6, tmp_path / "b")
    cache = CheckCache(tmp_path / "cache")
    va = validate_scene(tmp_path / "a" / "scene.usda", _packages(lib, pop_a, usd), cache)
    assert va.errors == () and va.packages_validated == va.packages > 1 and va.structures_validated > 0
    again = validate_scene(tmp_path / "a" / "scene.usda", _packages(lib, pop_a, usd), cache)
    assert again.packages_validated == 0 and again.structures_validated == 0 and again.warnings == va.warnings
    shared = set(_packages(lib, pop_a, usd)) & set(_packages(lib, pop_b, usd))
    vb = validate_scene(tmp_path / "b" / "scene.usda", _packages(lib, pop_b, usd),
                        CheckCache(tmp_path / "cache"))       # another process: read from disk
    assert vb.errors == () and vb.packages_validated == vb.packages - len(shared)
    # a package that changes is validated again, and a broken one is caught
    pkg = sorted(p for p in shared if p.suffix == ".usda")[0]
    text = pkg.read_text()
    try:
        pkg.write_text(text.replace("prepend payload = @./", "prepend payload = @./missing_"))
        vc = validate_scene(tmp_path / "b" / "scene.usda", _packages(lib, pop_b, usd), CheckCache(tmp_path / "cache"))
        assert vc.packages_validated == 1 and vc.errors
    finally:
        pkg.write_text(text)
    vd = validate_scene(tmp_path / "b" / "scene.usda", _packages(lib, pop_b, usd), CheckCache(tmp_path / "cache"))
    assert vd.packages_validated == 0 and vd.errors == ()


@needs_newton_usd
def test_proven_rest_agrees_with_the_simulation(world, tmp_path):
    """Every instance proven at rest stays within 1 cm in the full Newton simulation; an object moved
    so that its center of mass is 2 cm past its support's edge is not proven, and falls."""
    from stages.scene import compose
    from stages.scene.checkcache import CheckCache
    from stages.scene.geom import rot2
    from stages.scene.rest import analytic_rest, signed_inside, to_simulate
    from stages.scene.settle import settle_check

    lib, _, _, _ = world
    out = tmp_path / "s"
    _, pop = _scene(world, 5, out)
    cache = CheckCache(None)
    from stages.scene.build import _package_unknown

    proof = analytic_rest(pop, lambda i: _package_unknown(i, cache, 0.01))
    assert proof.unproven == {} and len(proof.proven) == len(pop.insts)
    full = settle_check(out / "scene.usda", early_exit=None)
    assert full.passed, full.offenders

    k, obj = next((k, i) for k, i in enumerate(pop.insts) if i.p.support)
    sup = next(i for i in pop.insts if i.p.inst == obj.p.support)
    surf = max(sup.geo.surfaces, key=lambda s: -abs(sup.p.position[2] + s.z - (obj.p.position[2] + obj.geo.lo[2])))
    poly = surf.polygon @ rot2(sup.p.yaw).T + np.asarray(sup.p.position[:2])
    com = np.asarray(obj.p.position[:2]) + rot2(obj.p.yaw) @ obj.geo.com[:2]
    d = com - poly.mean(axis=0)
    d = d / np.linalg.norm(d) if np.linalg.norm(d) > 1e-6 else np.array([1.0, 0.0])
    t = next(t for t in np.arange(0.0, 3.0, 0.005) if signed_inside(com + t * d, poly) < -0.02)
    xy = np.asarray(obj.p.position[:2]) + t * d
    ctx = pop.room_ctx[obj.p.room]
    moved = pop._instance(obj.p.record, obj.geo, ctx, xy, obj.p.position[2], obj.p.yaw, obj.p.support, 0.0)
    moved.on_floor = False
    moved.p = replace(moved.p, inst=obj.p.inst)
    pop.insts[k] = moved
    proof = analytic_rest(pop, lambda i: _package_unknown(i, cache, 0.01))
    assert obj.p.inst in proof.unproven and sup.p.inst in proof.proven
    specs = [compose.InstanceSpec(name=i.p.inst, usd=lib.usd(i.p.record), position=i.p.position, yaw=i.p.yaw,
                                  material=i.p.record.material, room=i.p.room, support=i.p.support or "",
                                  category=i.p.record.category) for i in pop.insts]
    compose.write_placement(out, out, specs)
    sim = to_simulate(pop, list(proof.unproven))
    assert obj.p.inst in sim and sup.p.inst in sim and len(sim) < len(pop.insts)
    rep = settle_check(out / "scene.usda", instances=sim, early_exit=None)
    assert obj.p.inst in rep.offenders and set(rep.moved) <= set(sim)


def test_rest_is_not_proven_without_authored_mass(world, tmp_path):
    """A dynamic package without authored mass properties (the simulator derives them from the
    collider volumes) has no known center of mass: it and the stack it belongs to are simulated."""
    from dataclasses import replace as dc_replace

    from stages.scene.build import _package_unknown
    from stages.scene.checkcache import CheckCache
    from stages.scene.rest import analytic_rest

    _, pop = _scene(world, 5, tmp_path / "s")
    cache = CheckCache(None)
    obj = next(i for i in pop.insts if i.p.support and i.geo.dynamic)
    obj.geo = dc_replace(obj.geo, mass=0.0)
    proof = analytic_rest(pop, lambda i: _package_unknown(i, cache, 0.01))
    sup = next(i for i in pop.insts if i.p.inst == obj.p.support)
    assert obj.p.inst in proof.unproven and (obj.p.support in proof.unproven) == sup.geo.dynamic
    assert "mass" in proof.unproven[obj.p.inst]


def _two_scenes_one_lifted(world, tmp_path: Path) -> tuple[list[Path], dict]:
    """Scenes of seeds 5 and 6 (their scene.usda paths); in the second one object on a support
    lifted 5 cm in its scene.json (that instance's entry is returned)."""
    scenes = []
    for seed in (5, 6):
        _scene(world, seed, tmp_path / f"s{seed}")
        scenes.append(tmp_path / f"s{seed}" / "scene.usda")
    info = json.loads((tmp_path / "s6" / "scene.json").read_text())
    lifted = next(i for i in info["instances"] if i["support"])
    lifted["position"][2] += 0.05
    (tmp_path / "s6" / "scene.json").write_text(json.dumps(info))
    return scenes, lifted


@needs_newton_usd
def test_batched_settle_of_two_scenes_on_cpu(world, tmp_path):
    from stages.scene.settle_batch import settle_batch

    # one scene with an object lifted 5 cm: it must be the only one that moves more than 1 cm
    scenes, lifted = _two_scenes_one_lifted(world, tmp_path)
    res = settle_batch(scenes, device="cpu", seconds=0.3, progress=False)
    assert res.passed[0] and not res.passed[1], res.moved
    assert res.offenders[1] == (lifted["name"],)
    n = [len(json.loads((s.parent / "scene.json").read_text())["instances"]) for s in scenes]
    assert [len(m) for m in res.moved] == [sum(1 for _ in m) for m in res.moved] and sum(map(len, res.moved)) <= sum(n)


def _scene_sigs(tmp_path, name: str, *, mpu: float = 1.0, scale: str = "(2, 2, 2, 1)", tint: str = "(0.5, 0.4, 0.3, 1)",
                light: float = 800.0) -> set[str]:
    from pxr import Usd

    from stages.scene.validation import _signatures

    p = tmp_path / name / "scene.usda"
    p.parent.mkdir()
    p.write_text(f"""#usda 1.0
(
    defaultPrim = "World"
    metersPerUnit = {mpu}
    upAxis = "Z"
)
def Xform "World"
{{
    def Scope "Looks"
    {{
        def Material "M"
        {{
            def Shader "surface"
            {{
                uniform token info:id = "UsdPreviewSurface"
                color3f inputs:diffuseColor.connect = </World/Looks/M/base.outputs:rgb>
                normal3f inputs:normal.connect = </World/Looks/M/normal.outputs:rgb>
            }}
            def Shader "base"
            {{
                uniform token info:id = "UsdUVTexture"
                float4 inputs:scale = {tint}
                float3 outputs:rgb
            }}
            def Shader "normal"
            {{
                uniform token info:id = "UsdUVTexture"
                float4 inputs:scale = {scale}
                float4 inputs:bias = (-1, -1, -1, 0)
                float3 outputs:rgb
            }}
        }}
    }}
    def Scope "Lights"
    {{
        def SphereLight "L"
        {{
            float inputs:intensity = {light}
            double3 xformOp:translate = (1.5, 2.5, 2.4)
            uniform token[] xformOpOrder = ["xformOp:translate"]
        }}
    }}
}}
""", encoding="utf-8")
    return set(_signatures(Usd.Stage.Open(str(p)), p))


def test_structure_signature_keeps_checked_values_exact(tmp_path) -> None:
    """The omniverse validator runs once per scene structure signature: values it checks (a normal
    map's scale and bias, the layer's metersPerUnit) must enter exactly, so a wrong one is validated
    instead of reusing a verdict; tints (a base color reader's scale) and light intensities (vary per scene) still share one."""
    base = _scene_sigs(tmp_path, "a")
    assert _scene_sigs(tmp_path, "b", tint="(0.2, 0.9, 0.1, 1)", light=1200.0) == base
    assert _scene_sigs(tmp_path, "c", scale="(3, 3, 3, 1)") != base
    assert _scene_sigs(tmp_path, "d", mpu=0.01) != base


@pytest.mark.slow  # 26 s on 2 cores (CI time); test_scenes_as_worlds_of_one_model_settle_as_each_alone stays
@needs_newton_usd
def test_settle_pool_workers_agree_with_the_serial_path(world, tmp_path):
    """Two scenes (one with an object lifted 5 cm) settled one per model by two worker processes,
    one per model in this process, and both in one model: the same bodies, shapes, offenders and
    displacements (per scene, within 0.1 mm between one- and two-scene models)."""
    from stages.scene.settle_batch import settle_batch
    from stages.scene.settle_pool import SettlePool

    scenes, lifted = _two_scenes_one_lifted(world, tmp_path)

    def per_scene(pool: SettlePool):
        out = {}
        for r in pool.run(scenes, chunk=1):
            assert len(r.settle.scenes) == 1 and r.errors == (0,), r
            out[r.settle.scenes[0]] = r
        return [out[s] for s in scenes]

    with SettlePool(["cpu"], 0, seconds=0.3) as pool:
        serial = per_scene(pool)
    with SettlePool(["cpu"], 2, seconds=0.3) as pool:
        parallel = per_scene(pool)
    assert len({r.pid for r in parallel}) == 2 and all(r.pid != serial[0].pid for r in parallel)
    one = settle_batch(scenes, device="cpu", seconds=0.3, progress=False)
    assert one.bodies == sum(r.settle.bodies for r in serial) == sum(r.settle.bodies for r in parallel)
    assert one.shapes == sum(r.settle.shapes for r in serial) == sum(r.settle.shapes for r in parallel)
    for k, (s, p) in enumerate(zip(serial, parallel)):
        assert (s.settle.bodies, s.settle.shapes) == (p.settle.bodies, p.settle.shapes)
        assert s.settle.offenders == p.settle.offenders == (one.offenders[k],)
        for m in (p.settle.moved[0], one.moved[k]):
            assert m.keys() == s.settle.moved[0].keys()
            assert all(abs(m[i] - v) < 1e-4 for i, v in s.settle.moved[0].items()), (m, s.settle.moved[0])
    assert serial[1].settle.offenders == ((lifted["name"],),)


@needs_newton_usd
def test_dof_padding_leaves_the_settle_unchanged(world, tmp_path):
    """Padding a model's degrees of freedom to a multiple of 32 (shared kernels across chunk sizes)
    adds only bodies that stay still: the same bodies counted, the same displacements."""
    from stages.scene.settle_batch import build_worlds, pad_dofs, settle_batch

    _scene(world, 5, tmp_path / "s5")
    scenes = [tmp_path / "s5" / "scene.usda"]
    builder, _ = build_worlds(scenes)
    n = builder.body_count
    added = pad_dofs(builder, 32)
    assert builder.joint_dof_count % 32 == 0 and builder.body_count == n + added
    padded = settle_batch(scenes, device="cpu", seconds=0.2, progress=False)
    plain = settle_batch(scenes, device="cpu", seconds=0.2, progress=False, dof_step=0)
    assert padded.bodies == plain.bodies == n and padded.offenders == plain.offenders
    assert padded.moved[0].keys() == plain.moved[0].keys()
    assert all(abs(padded.moved[0][k] - v) < 1e-5 for k, v in plain.moved[0].items())


@needs_newton_usd
def test_scenes_as_worlds_of_one_model_settle_as_each_alone(world, tmp_path):
    """Three bedrooms (one with an object lifted 5 cm) as the three worlds of one model, padded to
    one structure, settle as each alone: the same instances, offenders and displacements within
    0.5 mm, a twentieth of the settle tolerance (a padded world enumerates its contacts in another
    order than a model alone and the solver iterates to a tolerance: an alarm clock that rocks 6 mm
    differs by 0.13 mm); the worlds have equal body counts and padding is not reported."""
    from stages.scene.settle_batch import build_separate_worlds, settle_batch

    scenes, lifted = _two_scenes_one_lifted(world, tmp_path)
    _scene(world, 9, tmp_path / "s9")
    scenes.append(tmp_path / "s9" / "scene.usda")
    builder, starts, pads = build_separate_worlds(scenes)
    assert builder.world_count == 3 and len(set(np.diff(starts))) == 1 and pads
    together = settle_batch(scenes, device="cpu", seconds=0.3, progress=False)
    alone = [settle_batch([s], device="cpu", seconds=0.3, progress=False) for s in scenes]
    assert together.bodies == sum(a.bodies for a in alone) == len(builder.body_label) - len(pads)
    assert together.offenders[1] == (lifted["name"],) and together.passed == (True, False, True)
    for k, a in enumerate(alone):
        assert a.offenders[0] == together.offenders[k]
        assert a.moved[0].keys() == together.moved[k].keys() and a.moved[0]
        assert all(abs(together.moved[k][i] - v) < 5e-4 for i, v in a.moved[0].items()), (k, a.moved[0])


@needs_newton_usd
def test_graph_stepping_settles_as_eager_stepping(world, tmp_path):
    """The settle stepped through a captured graph (here Warp's CPU capture; a CUDA graph on a GPU)
    ends where eager stepping does: the same displacements to 1 um, and the capture is timed."""
    from stages.scene.settle_batch import settle_batch

    scenes, lifted = _two_scenes_one_lifted(world, tmp_path)
    eager = settle_batch(scenes, device="cpu", seconds=0.1, progress=False)
    graph = settle_batch(scenes, device="cpu", seconds=0.1, progress=False, cuda_graph=True)
    assert "capture" in graph.seconds and "capture" not in eager.seconds
    assert graph.offenders == eager.offenders and graph.moved[1][lifted["name"]] > 0.003
    for g, e in zip(graph.moved, eager.moved):
        assert g.keys() == e.keys() and all(abs(g[k] - v) < 1e-6 for k, v in e.items()), (g, e)
