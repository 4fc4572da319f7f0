"""Lights as other USD tools read them (issue 18, item 3): the UsdLux values the scene stage and the
demo rooms author must come out as plausible lamps in Blender, while our own camera's light mapping
stays as it was.

Blender's reading is modelled here from its USD importer (5.0.1, ``usd_reader_light.cc``: a sphere
light becomes a point light of ``energy = pi * intensity`` [W] with ``exposure`` and ``normalize``
carried over) and a Cycles render of a lit plane (an unnormalized point light emits ``energy *
2^exposure * 4 pi r^2`` [W]); ``tests/benchmarks/bench_blender_lights.py`` checks the same figures
in Blender itself. Main's ceiling lights read as 11-102 kW there and rendered white.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

BLENDER_LAMP_W = (5.0, 200.0)  # [W] a plausible ceiling lamp as Blender renders it


def _blender_watts(prim) -> float:
    """Power [W] Blender 5.0.1 renders for a UsdLux SphereLight prim (see the module doc)."""
    from pxr import UsdLux

    light = UsdLux.SphereLight(prim)
    intensity = light.GetIntensityAttr().Get()
    exposure = light.GetExposureAttr().Get() or 0.0
    radius = light.GetRadiusAttr().Get()
    area = 1.0 if light.GetNormalizeAttr().Get() else 4.0 * math.pi * radius**2
    return math.pi * intensity * 2.0**exposure * area


def _lights(stage) -> dict:
    from pxr import UsdLux

    # TraverseAll: lighting.usda alone holds its lights under an ``over`` of /World
    return {p.GetName(): p for p in stage.TraverseAll() if p.HasAPI(UsdLux.LightAPI)}


def _scene_stage_lights(tmp_path, ceiling: float, seeds=range(20)):
    """(specs, light prims by name, stage) of the lighting layer the scene stage writes for a 4 m x
    3 m room of ``ceiling`` [m] with daylight, per seed."""
    from pxr import Usd

    from stages.scene.compose import write_lighting
    from stages.scene.lighting import LightingConfig, plan_lights

    poly = np.array([[0, 0], [4, 0], [4, 3], [0, 3]], dtype=float)
    for seed in seeds:
        rng = np.random.default_rng(seed)
        specs = plan_lights([("r", poly, 0.0, ceiling)], LightingConfig(daylight=1.0), rng)
        out = tmp_path / f"{ceiling}_{seed}"
        out.mkdir()
        stage = Usd.Stage.Open(str(write_lighting(out, specs)))
        lights = _lights(stage)
        assert set(lights) == {"Ceiling_r", "Sun", "Sky"}
        yield specs, lights, stage


@pytest.mark.parametrize("ceiling", [2.3, 2.6, 3.5])
def test_scene_stage_lights_read_as_lamps_in_blender(tmp_path, ceiling):
    """Every ceiling light the scene stage writes (sampled floor illuminance 150-800 lux, ceilings
    2.3-3.5 m) renders as a 5-200 W lamp in Blender, and its sky dome as a background darker than
    white (Blender's background strength is the dome's intensity, its exposure ignored)."""
    watts, skies = [], []
    for _, lights, _stage in _scene_stage_lights(tmp_path, ceiling):
        watts.append(_blender_watts(lights["Ceiling_r"]))
        skies.append(lights["Sky"].GetAttribute("inputs:intensity").Get())
    assert BLENDER_LAMP_W[0] <= min(watts) and max(watts) <= BLENDER_LAMP_W[1], (min(watts), max(watts))
    assert 0.01 <= min(skies) and max(skies) <= 0.5, (min(skies), max(skies))  # radiance; white is 1


def test_scene_stage_lights_carry_the_scene_exposure(tmp_path):
    """Physical intensities, the scene exposure on every light (the dome's in its intensity), and
    ``blender_power`` agreeing with the reading above."""
    from stages.scene.lighting import SCENE_EXPOSURE, blender_power

    for specs, lights, _stage in _scene_stage_lights(tmp_path, 2.6, range(5)):
        w = _blender_watts(lights["Ceiling_r"])
        spec = next(s for s in specs if s.type == "SphereLight")
        modelled = blender_power("SphereLight", spec.intensity, spec.exposure, radius=spec.radius)
        assert modelled == pytest.approx(w)
        # physical values: luminous flux [lm] = what Blender renders [W] / 2^exposure
        assert spec.luminous_flux() == pytest.approx(w / 2.0**SCENE_EXPOSURE, rel=1e-5)
        for name, p in lights.items():
            assert p.GetAttribute("inputs:exposure").Get() == (0.0 if name == "Sky" else SCENE_EXPOSURE), name
        sky = next(s for s in specs if s.type == "DomeLight")
        assert sky.intensity == pytest.approx(sky.target_lux / math.pi * 2.0**SCENE_EXPOSURE)
        assert blender_power("DomeLight", sky.intensity, sky.exposure) == pytest.approx(sky.intensity)


def test_demo_room_lights_read_as_lamps_in_blender(tmp_path):
    """The demo room's ceiling light (300 lux by default; the kitchens' looks draw 150-600 lux, to
    which its power is proportional) renders as a 5-200 W lamp, its sun as a sun that leaves a lit
    white wall unclipped."""
    from pxr import Usd

    from stages.demos.looks import CEILING_LUX
    from stages.simulate.demo_scene import write_demo_room

    room = write_demo_room(tmp_path / "room.usda")
    stage = Usd.Stage.Open(str(room.usd))
    lights = _lights(stage)
    w = _blender_watts(lights["Ceiling"])
    for lux in CEILING_LUX:
        assert BLENDER_LAMP_W[0] <= w * lux / 300.0 <= BLENDER_LAMP_W[1], (lux, w)
    sun = lights["Sun"]
    # Blender's sun strength [W/m^2] is 4 x intensity x 2^exposure; a white (albedo 1) wall facing
    # it shows strength / pi
    intensity, exposure = (sun.GetAttribute(f"inputs:{a}").Get() for a in ("intensity", "exposure"))
    strength = 4.0 * intensity * 2.0**exposure
    assert 0.3 <= strength / math.pi <= 1.0, strength
    # the sky dome: Blender's background strength is its intensity, exposure ignored
    assert not lights["Sky"].GetAttribute("inputs:exposure").HasAuthoredValue()
    assert 0.01 <= lights["Sky"].GetAttribute("inputs:intensity").Get() <= 0.5


def test_our_camera_maps_the_lights_as_before(tmp_path):
    """The scene exposure is common to all lights, so the renderer lights of a scene (automatic
    exposure) are those of the same physical lights without it: images do not change."""
    from pxr import Usd

    from stages.scene.compose import write_lighting
    from stages.scene.lighting import SCENE_EXPOSURE, LightingConfig, plan_lights
    from stages.simulate.sensors import map_lights, read_usd_lights

    poly = np.array([[0, 0], [4, 0], [4, 3], [0, 3]], dtype=float)
    specs = plan_lights([("a", poly, 0.0, 2.6), ("b", poly + 5, 0.0, 2.6)], LightingConfig(daylight=1.0),
                        np.random.default_rng(1))
    stage = Usd.Stage.CreateInMemory()
    stage.GetRootLayer().subLayerPaths.append(str(write_lighting(tmp_path, specs)))
    stage.DefinePrim("/World", "Xform")  # as scene.usda does over the lighting layer
    lights = read_usd_lights(stage)
    assert len(lights) == 4
    # the same lights at their physical values (main's effective values): no exposure anywhere
    physical = [dataclasses.replace(lt, intensity=lt.intensity * 2.0 ** (lt.exposure - SCENE_EXPOSURE),
                                    exposure=0.0) for lt in lights]
    (got, sky), (want, sky0) = map_lights(lights), map_lights(physical)
    assert [m.source for m in got] == [m.source for m in want] and len(got) == 3 and sky is not None
    for a, b in zip(got, want, strict=True):
        np.testing.assert_allclose(a.color, b.color, rtol=1e-5)
    np.testing.assert_allclose(sky, sky0, rtol=1e-5)


def test_normalized_lights_read_by_their_surface_area():
    """``inputs:normalize`` divides a light's luminance by its surface area (UsdLux; what Blender's
    exporter writes): a normalized sphere of intensity L 4 pi r^2 reads as one of luminance L."""
    from pxr import Usd, UsdLux

    from stages.simulate.sensors import read_usd_lights

    stage = Usd.Stage.CreateInMemory()
    r = 0.1
    plain = UsdLux.SphereLight.Define(stage, "/W/Plain")
    plain.CreateRadiusAttr(r)
    plain.CreateIntensityAttr(1000.0)
    norm = UsdLux.SphereLight.Define(stage, "/W/Norm")
    norm.CreateRadiusAttr(r)
    norm.CreateIntensityAttr(1000.0 * 4 * math.pi * r * r)
    norm.CreateNormalizeAttr(True)
    rect = UsdLux.RectLight.Define(stage, "/W/Rect")
    rect.CreateWidthAttr(2.0)
    rect.CreateHeightAttr(0.5)
    rect.CreateIntensityAttr(1000.0)
    rect.CreateNormalizeAttr(True)
    by = {lt.path: lt for lt in read_usd_lights(stage)}
    assert by["/W/Norm"].illuminance == pytest.approx(by["/W/Plain"].illuminance, rel=1e-5)
    # normalized rect: I = (intensity / area) * area = intensity [cd] at any size
    assert by["/W/Rect"].illuminance == pytest.approx(1000.0 / 4.0, rel=1e-5)  # / REFERENCE_DISTANCE^2
