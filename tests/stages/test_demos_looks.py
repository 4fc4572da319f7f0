"""The look of a demonstration kitchen (stages.demos.looks): material overrides of the placed
default-catalog packages and the lights, drawn from the world's seed, written as overs in the scene
layer, and seen by Newton (shape colours of the model) and by the camera light mapping.

The kitchen catalog (the default catalog's kitchen categories, one package of each ingested by the
real job steps) is the session's, from tests/stages/conftest.py.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest


@pytest.fixture(scope="module")
def library(kitchen_library):
    """The kitchen catalog's packages (tests/stages/conftest.py, built once per session)."""
    return kitchen_library


@pytest.fixture(scope="module")
def worlds(library, tmp_path_factory):
    """Kitchens of seeds 5, 5 and 6, in sibling folders (their relative references are equal)."""
    from stages.demos.kitchen import write_kitchen

    d = tmp_path_factory.mktemp("look_worlds")
    return [write_kitchen(d / name, library, scene_id="k", rng=np.random.default_rng(seed))
            for name, seed in (("a", 5), ("b", 5), ("c", 6))]


def _srgb(rgb) -> np.ndarray:
    c = np.asarray(rgb, float)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)


# -- determinism ----------------------------------------------------------------------------------


def test_same_seed_gives_the_same_look_and_the_same_scene_layer(worlds):
    a, b, c = worlds
    assert a.look == b.look and a.look != c.look
    assert a.usd.read_text() == b.usd.read_text()
    assert a.materials == {"floor": a.look.floor, "wall": a.look.wall}
    ov = a.look.override("fridge", "body")
    assert ov is not None and ov.shader == "/World/Fridge/Looks/body/PreviewSurface"


def test_the_look_draws_shift_no_pick_or_pose(library, tmp_path, monkeypatch):
    """The look comes from a child generator: a look sampler that draws 1000 numbers more changes
    the look, not the picks, poses or spawn of the world."""
    import stages.demos.kitchen as kitchen
    from stages.demos.looks import sample_look

    def hungry(placed, rng):
        rng.random(1000)
        return sample_look(placed, rng)

    def facts(w):
        return ({k: (p.asset.asset_id, p.position, p.yaw) for k, p in w.placed.items()}, w.spawn, w.size)

    w0 = kitchen.write_kitchen(tmp_path / "a", library, scene_id="k", rng=np.random.default_rng(11))
    monkeypatch.setattr(kitchen, "sample_look", hungry)
    w1 = kitchen.write_kitchen(tmp_path / "b", library, scene_id="k", rng=np.random.default_rng(11))
    assert facts(w0) == facts(w1) and w0.look != w1.look


# -- what the look changes, seen by Newton ----------------------------------------------------------


def _shape_colors_by_material(usd: Path) -> dict[str, np.ndarray]:
    """Newton's model shape colours (sRGB) of the visual shapes of the scene, by bound material path."""
    import newton
    from pxr import Usd, UsdShade

    from stages.simulate.world import load_scene

    builder = newton.ModelBuilder()
    scene = load_scene(builder, usd)
    model = builder.finalize(device="cpu")
    colors = model.shape_color.numpy()
    stage = Usd.Stage.Open(str(usd))
    out: dict[str, list] = {}
    for i, path in enumerate(scene.shape_path):
        prim = stage.GetPrimAtPath(path) if path else None
        if not prim:
            continue
        mat = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()[0]
        if mat:
            out.setdefault(str(mat.GetPath()), []).append(colors[i])
    return {k: np.asarray(v) for k, v in out.items()}


def test_different_seeds_recolour_the_packages_in_the_newton_model(worlds):
    pytest.importorskip("newton")
    pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")
    from stages.demos.looks import package_materials

    a, _, c = worlds
    # the appliance / cabinetry material whose colour differs most between the two seeds
    pairs = [(m, c.look.override(m.role, m.material)) for m in a.look.materials
             if m.rule in ("appliance", "cabinetry")]
    m_a, m_c = max(pairs, key=lambda p: float(np.abs(np.subtract(p[0].rgb, p[1].rgb)).max()))
    assert np.abs(np.subtract(m_a.rgb, m_c.rgb)).max() > 0.05, (m_a, m_c)
    material = m_a.shader.rsplit("/", 1)[0]
    got_a, got_c = _shape_colors_by_material(a.usd), _shape_colors_by_material(c.usd)
    # every shape bound to the material takes the authored colour (Newton keeps sRGB shape colours)
    assert len(got_a[material]) >= 1
    np.testing.assert_allclose(got_a[material], np.tile(_srgb(m_a.rgb), (len(got_a[material]), 1)), atol=2e-3)
    np.testing.assert_allclose(got_c[material], np.tile(_srgb(m_c.rgb), (len(got_c[material]), 1)), atol=2e-3)
    assert np.abs(got_a[material] - got_c[material]).max() > 0.05
    # a kept material (the fridge's liner) is the package's own colour in both worlds
    fridge = a.placed["fridge"]
    liner = next(m for m in package_materials(fridge.asset.usd) if m.name == "liner")
    assert a.look.override("fridge", "liner") is None
    for got in (got_a, got_c):
        np.testing.assert_allclose(got["/World/Fridge/Looks/liner"][0], _srgb(liner.rgb), atol=2e-3)
    assert sum(len(v) for k, v in got_a.items() if "/Looks/" in k) > 20


def test_the_camera_lights_follow_the_look(worlds):
    from pxr import Usd

    from stages.scene.lighting import SCENE_EXPOSURE
    from stages.simulate.sensors import auto_exposure_lux, kelvin_to_rgb, read_usd_lights

    a, _, c = worlds
    read = {}
    for w in (a, c):
        lights = {lt.path.rsplit("/", 1)[1]: lt for lt in read_usd_lights(Usd.Stage.Open(str(w.usd)))}
        assert set(lights) == {"Sun", "Ceiling", "Sky"}
        lk = w.look.lights
        ceil, sun, sky = lights["Ceiling"], lights["Sun"], lights["Sky"]
        # photometric values as authored: floor illuminance below the ceiling light, sun, sky
        assert ceil.intensity * ceil.area / ceil.position[2] ** 2 == pytest.approx(lk.ceiling_lux, rel=1e-4)
        np.testing.assert_allclose(ceil.color, kelvin_to_rgb(lk.ceiling_kelvin), rtol=1e-5)
        np.testing.assert_allclose(ceil.position[:2], np.add(np.divide(w.size, 2), lk.ceiling_offset), atol=1e-5)
        # UsdLux's values include the scene exposure common to all lights
        assert sun.illuminance == pytest.approx(lk.sun_lux * 2.0**SCENE_EXPOSURE, rel=1e-5)
        np.testing.assert_allclose(sun.direction, lk.sun_direction, atol=1e-5)
        assert sky.illuminance == pytest.approx(lk.dome_lux * 2.0**SCENE_EXPOSURE, rel=1e-5)
        read[w.usd] = (ceil, sun, sky, auto_exposure_lux(tuple(lights.values())))
    (ca, sa, ka, ea), (cc, sc, kc, ec) = read[a.usd], read[c.usd]
    assert abs(ca.intensity - cc.intensity) > 0.05 * ca.intensity
    assert np.abs(np.subtract(ca.color, cc.color)).max() > 0.01
    assert abs(sa.intensity - sc.intensity) > 1.0 and sa.direction != sc.direction
    assert ca.position != cc.position and ea != ec


def test_the_scene_layer_validates(worlds):
    import usd_schemas

    a = worlds[0]
    report = usd_schemas.validate_package(a.usd)
    assert report.ok, report.summary()
    mine = [i.line() for i in report.issues if "/Looks/" in i.at or "/Lights" in i.at]
    assert not mine, mine


# -- the rules -----------------------------------------------------------------------------------


def test_looks_stay_plausible_over_many_seeds(worlds):
    from stages.demos.looks import (
        CEILING_KELVIN,
        CEILING_LUX,
        DOME_LUX,
        FLOOR_MAX,
        PALETTES,
        SUN_LUX,
        package_materials,
        sample_look,
    )

    placed = worlds[0].placed
    own = {(r, m.name): m for r, p in placed.items() for m in package_materials(p.asset.usd)}
    looks = [sample_look(placed, np.random.default_rng(s)) for s in range(60)]
    finishes = set()
    for lk in looks:
        rules = {(m.role, m.material): m for m in lk.materials}
        # windows, cavities, glass shelves, liners, cooktops stay as the packages made them
        for key in (("microwave", "window"), ("oven", "window"), ("oven", "cavity"), ("microwave", "cavity"),
                    ("fridge", "shelf"), ("fridge", "liner"), ("oven", "cooktop")):
            if key in own:
                assert key not in rules, key
        for m in lk.materials:
            assert all(0.02 <= v <= 0.95 for v in m.rgb) and 0.0 <= m.roughness <= 1.0
            if m.rule in ("hardware", "metal"):
                assert m.metallic == 1.0, m
        fridge = rules[("fridge", "body")]
        assert fridge.rule == "appliance"
        near = min(PALETTES["appliance"], key=lambda s: np.abs(np.subtract(s.rgb, fridge.rgb)).max())
        assert np.abs(np.subtract(near.rgb, fridge.rgb)).max() < 0.15
        finishes.add(near.rgb)
        assert rules[("table", "wood")].rule == "wood" and rules[("counter", "countertop")].rule == "countertop"
        assert max(lk.floor) <= FLOOR_MAX + 1e-9
        lt = lk.lights
        assert CEILING_LUX[0] <= lt.ceiling_lux <= CEILING_LUX[1]
        assert CEILING_KELVIN[0] <= lt.ceiling_kelvin <= CEILING_KELVIN[1]
        assert SUN_LUX[0] <= lt.sun_lux <= SUN_LUX[1] and DOME_LUX[0] <= lt.dome_lux <= DOME_LUX[1]
        assert lt.sun_direction[2] < -0.65  # from above, at most ~48 deg off the vertical
    assert len(finishes) >= 4
    assert len({lk.floor for lk in looks}) == len(looks)


def test_textured_materials_are_left_as_they_are(tmp_path):
    from stages.demos.kitchen import CatalogAsset, Placed
    from stages.demos.looks import package_materials, sample_look

    usd = tmp_path / "box_00.usda"
    usd.write_text('''#usda 1.0
(
    defaultPrim = "box_00"
)
def Xform "box_00"
{
    def Scope "Looks"
    {
        def Material "ceramic"
        {
            token outputs:surface.connect = </box_00/Looks/ceramic/PreviewSurface.outputs:surface>
            def Shader "PreviewSurface"
            {
                uniform token info:id = "UsdPreviewSurface"
                color3f inputs:diffuseColor = (0.9, 0.9, 0.9)
                float inputs:roughness = 0.3
                token outputs:surface
            }
        }
        def Material "print"
        {
            token outputs:surface.connect = </box_00/Looks/print/PreviewSurface.outputs:surface>
            def Shader "PreviewSurface"
            {
                uniform token info:id = "UsdPreviewSurface"
                color3f inputs:diffuseColor.connect = </box_00/Looks/print/Texture.outputs:rgb>
                token outputs:surface
            }
            def Shader "Texture"
            {
                uniform token info:id = "UsdUVTexture"
                asset inputs:file = @./wood.png@
                float3 outputs:rgb
            }
        }
    }
}
''')
    mats = {m.name: m for m in package_materials(usd)}
    assert mats["print"].textured and mats["print"].rgb is None
    assert not mats["ceramic"].textured and mats["ceramic"].rgb == pytest.approx((0.9, 0.9, 0.9))
    assert mats["ceramic"].shader == "Looks/ceramic/PreviewSurface"
    asset = CatalogAsset(asset_id="box_00", category="mug", usd=usd, info={})
    look = sample_look({"mug": Placed("Mug", asset, (0.0, 0.0, 0.0), 0.0)}, np.random.default_rng(0))
    assert [(m.material, m.rule, m.shader) for m in look.materials] == [
        ("ceramic", "ceramic", "/World/Mug/Looks/ceramic/PreviewSurface")]
