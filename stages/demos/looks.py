"""The look of a kitchen task world: material overrides of the placed packages and the lights.

A :class:`KitchenLook` is drawn per world by :func:`sample_look` from the world's generator and
written into the scene layer by :func:`add_look` (through ``stages.simulate.demo_scene``'s
``_Writer``: values computed first, written with the Sdf API in one ``Sdf.ChangeBlock``).

Materials. Each placed package keeps its ``UsdPreviewSurface`` materials under its default prim
(``<pkg>/Looks/<material>/<shader>``); the scene references the package at ``Placed.prim``, so the
override is an ``over`` of ``<Placed.prim>/Looks/<material>/<shader>`` with a new
``inputs:diffuseColor`` (linear RGB, as the packages author it) and roughness (and metallic for
metals). The colour comes from :data:`RULES`, matched on the material's name (the generators'
``b.material(name, ...)``) and the package category, first match wins:

- ``keep``: glass, windows, cavities, liners, cooktops, burners: not overridden (they stay dark,
  or light inside a microwave, as the package made them);
- ``hardware``: handles, one metal finish per kitchen (stainless, black, brass, nickel, copper),
  metallic 1;
- ``metal``: other metal parts (sink steel, can lids): an HSV jitter of their own colour, metallic 1;
- ``appliance``: bodies of fridges, ovens, microwaves: one finish per kitchen (white, stainless,
  black, bisque, graphite, a few retro colours) that each appliance takes with probability
  ``APPLIANCE_MATCH`` (else its own draw);
- ``cabinetry`` (counter body and fronts), ``wood`` (tables, doors), ``countertop`` (stone,
  quartz, butcher block), ``control`` (buttons, knobs), ``ceramic`` (mugs, bowls), ``print``
  (cans): palettes of plausible colours;
- anything else: an HSV jitter of the package's own colour.

The room's floor and walls (boxes of the scene layer, ``primvars:displayColor``) take colours of
the ``floor`` (wood, tile, stone, concrete; no channel above ``FLOOR_MAX``: the demos' cameras
expose for the room, and a white floor in the sun saturated them) and ``wall`` (mostly whites, a few
muted paints) palettes.

Every palette draw gets a small HSV jitter. A material whose colour input is connected to a
texture (or whose surface shader is not a ``UsdPreviewSurface``) is left as the package made it.

Lights (:class:`LightLook`): the ceiling sphere light's illuminance on the floor below it (150-600
lux), colour temperature (2700-6500 K) and position (up to 0.6 m x 0.5 m off the room centre),
the sun's illuminance (100-700 lux) and direction (tilted 10-35 deg about world X, -35..35 deg
about Y), the sky dome's illuminance (80-300 lux). The cameras' exposure is automatic (see
``stages.simulate.sensors``): the images keep their overall brightness, while the balance of sun,
ceiling light and sky, the light's colour and where it hangs change per world.
"""

from __future__ import annotations

import colorsys
import functools
import logging
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pipeline.types import ItemError

if TYPE_CHECKING:
    from stages.demos.packages import Placed

log = logging.getLogger(__name__)

RGB = tuple[float, float, float]

CEILING_LUX = (150.0, 600.0)     # [lux] on the floor below the ceiling light
CEILING_KELVIN = (2700.0, 6500.0)  # [K]
CEILING_JITTER = (0.6, 0.5)      # [m] largest offset of the ceiling light from the room centre (x, y)
SUN_LUX = (100.0, 700.0)         # [lux] on a surface facing the sun
SUN_TILT_X = (10.0, 35.0)        # [deg] magnitude of the sun's tilt about world X (either sign)
SUN_TILT_Y = (-35.0, 35.0)       # [deg] the sun's tilt about world Y
DOME_LUX = (80.0, 300.0)         # [lux] from the sky dome on a horizontal surface
APPLIANCE_MATCH = 0.75           # probability that an appliance takes the kitchen's appliance finish
FLOOR_MAX = 0.5                  # brightest floor channel (linear): a white floor in the sun saturates

APPLIANCES = ("fridge", "oven", "microwave", "dishwasher", "washing_machine")


@dataclass(frozen=True)
class Swatch:
    """A palette entry: linear RGB, roughness range, metallic (None: keep the package's), weight."""

    rgb: RGB
    roughness: tuple[float, float]
    metallic: float | None = None
    weight: float = 1.0


def _sw(rgb, rough, metallic=None, weight=1.0) -> Swatch:
    return Swatch(tuple(float(v) for v in rgb), rough, metallic, weight)


#: palettes by name (linear RGB, like the generators' colours)
PALETTES: dict[str, tuple[Swatch, ...]] = {
    "appliance": (
        _sw((0.93, 0.93, 0.92), (0.25, 0.4), 0.1, 3.0),    # white
        _sw((0.72, 0.73, 0.74), (0.2, 0.35), 0.7, 3.0),    # stainless
        _sw((0.10, 0.10, 0.11), (0.2, 0.35), 0.2, 2.0),    # black
        _sw((0.82, 0.80, 0.76), (0.25, 0.4), 0.1, 1.0),    # bisque
        _sw((0.30, 0.31, 0.33), (0.2, 0.35), 0.6, 1.0),    # graphite steel
        _sw((0.55, 0.72, 0.64), (0.25, 0.4), 0.1, 0.4),    # retro mint
        _sw((0.60, 0.08, 0.07), (0.25, 0.4), 0.1, 0.4),    # retro red
        _sw((0.90, 0.84, 0.66), (0.25, 0.4), 0.1, 0.4),    # retro cream
        _sw((0.12, 0.17, 0.30), (0.25, 0.4), 0.1, 0.4),    # navy
    ),
    "hardware": (
        _sw((0.75, 0.75, 0.77), (0.15, 0.3), 1.0, 3.0),    # stainless
        _sw((0.10, 0.10, 0.11), (0.3, 0.5), 1.0, 1.5),     # matte black
        _sw((0.80, 0.66, 0.38), (0.2, 0.35), 1.0, 1.0),    # brass
        _sw((0.60, 0.60, 0.62), (0.25, 0.4), 1.0, 1.5),    # brushed nickel
        _sw((0.78, 0.50, 0.36), (0.2, 0.35), 1.0, 0.5),    # copper
    ),
    "cabinetry": (
        _sw((0.72, 0.55, 0.36), (0.4, 0.6)),               # oak
        _sw((0.36, 0.23, 0.13), (0.4, 0.6)),               # walnut
        _sw((0.55, 0.30, 0.20), (0.4, 0.6)),               # cherry
        _sw((0.85, 0.74, 0.56), (0.4, 0.6)),               # birch
        _sw((0.93, 0.92, 0.89), (0.3, 0.5), None, 2.0),    # white laminate
        _sw((0.45, 0.46, 0.47), (0.3, 0.5)),               # grey laminate
        _sw((0.20, 0.20, 0.22), (0.3, 0.5)),               # anthracite
        _sw((0.52, 0.60, 0.50), (0.35, 0.55), None, 0.7),  # sage paint
        _sw((0.18, 0.24, 0.36), (0.35, 0.55), None, 0.7),  # navy paint
    ),
    "wood": (
        _sw((0.55, 0.38, 0.22), (0.45, 0.65)),
        _sw((0.72, 0.55, 0.36), (0.45, 0.65)),
        _sw((0.36, 0.23, 0.13), (0.45, 0.65)),
        _sw((0.85, 0.74, 0.56), (0.45, 0.65)),
        _sw((0.62, 0.45, 0.30), (0.45, 0.65)),
        _sw((0.93, 0.92, 0.89), (0.4, 0.6)),               # white paint
        _sw((0.25, 0.25, 0.27), (0.4, 0.6)),               # black stain
    ),
    "countertop": (
        _sw((0.88, 0.87, 0.84), (0.1, 0.3)),               # white quartz
        _sw((0.10, 0.10, 0.11), (0.1, 0.3)),               # black granite
        _sw((0.50, 0.50, 0.48), (0.5, 0.7)),               # concrete
        _sw((0.70, 0.63, 0.52), (0.2, 0.4)),               # beige stone
        _sw((0.62, 0.42, 0.24), (0.4, 0.6)),               # butcher block
        _sw((0.80, 0.80, 0.80), (0.1, 0.25)),              # marble grey
    ),
    "control": (
        _sw((0.12, 0.12, 0.13), (0.35, 0.5)),
        _sw((0.30, 0.30, 0.32), (0.35, 0.5)),
        _sw((0.85, 0.85, 0.85), (0.35, 0.5)),
        _sw((0.70, 0.70, 0.72), (0.3, 0.45), 0.8),
    ),
    "ceramic": (
        _sw((0.95, 0.95, 0.93), (0.15, 0.3), None, 2.0),
        _sw((0.85, 0.30, 0.25), (0.15, 0.3)),
        _sw((0.25, 0.45, 0.70), (0.15, 0.3)),
        _sw((0.90, 0.85, 0.60), (0.15, 0.3)),
        _sw((0.30, 0.55, 0.40), (0.15, 0.3)),
        _sw((0.15, 0.15, 0.17), (0.15, 0.3)),
        _sw((0.80, 0.65, 0.75), (0.15, 0.3)),
    ),
    "floor": (
        _sw((0.45, 0.30, 0.17), (0.4, 0.6)),               # oak boards
        _sw((0.62, 0.47, 0.30), (0.4, 0.6)),               # light oak
        _sw((0.25, 0.16, 0.09), (0.4, 0.6)),               # walnut
        _sw((0.50, 0.50, 0.49), (0.3, 0.5)),               # grey tile
        _sw((0.70, 0.64, 0.54), (0.3, 0.5)),               # beige tile
        _sw((0.60, 0.60, 0.58), (0.2, 0.4)),               # white tile
        _sw((0.55, 0.28, 0.17), (0.5, 0.7)),               # terracotta
        _sw((0.22, 0.23, 0.25), (0.4, 0.6)),               # slate
        _sw((0.42, 0.42, 0.40), (0.6, 0.8)),               # concrete
    ),
    "wall": (
        _sw((0.88, 0.86, 0.80), (0.7, 0.9), None, 3.0),    # warm white
        _sw((0.85, 0.87, 0.88), (0.7, 0.9), None, 2.0),    # cool white
        _sw((0.68, 0.64, 0.57), (0.7, 0.9)),               # greige
        _sw((0.66, 0.68, 0.69), (0.7, 0.9)),               # pale grey
        _sw((0.58, 0.64, 0.52), (0.7, 0.9), None, 0.7),    # sage
        _sw((0.60, 0.68, 0.75), (0.7, 0.9), None, 0.7),    # pale blue
        _sw((0.88, 0.80, 0.55), (0.7, 0.9), None, 0.7),    # butter yellow
        _sw((0.82, 0.66, 0.60), (0.7, 0.9), None, 0.5),    # blush
        _sw((0.45, 0.52, 0.48), (0.7, 0.9), None, 0.4),    # deep green
    ),
    "print": (
        _sw((0.85, 0.20, 0.18), (0.25, 0.4)),
        _sw((0.15, 0.45, 0.80), (0.25, 0.4)),
        _sw((0.20, 0.65, 0.30), (0.25, 0.4)),
        _sw((0.95, 0.75, 0.15), (0.25, 0.4)),
        _sw((0.92, 0.92, 0.92), (0.25, 0.4)),
        _sw((0.10, 0.10, 0.10), (0.25, 0.4)),
        _sw((0.60, 0.30, 0.70), (0.25, 0.4)),
    ),
}


@dataclass(frozen=True)
class LookRule:
    """Materials named one of ``names`` (of a package whose category is in ``categories``, or any
    when empty) get ``kind``: "keep" (no override), "jitter" (HSV jitter of their own colour),
    "metal" (jitter, metallic 1), "hardware" / "appliance" (the kitchen's shared finish), or a
    palette of :data:`PALETTES`."""

    kind: str
    names: tuple[str, ...]
    categories: tuple[str, ...] = ()

    def matches(self, material: str, category: str) -> bool:
        return material in self.names and (not self.categories or category in self.categories)


#: first match wins; unmatched materials get "jitter"
RULES: tuple[LookRule, ...] = (
    LookRule("keep", ("window", "glass", "shelf", "screen", "cavity", "liner", "cooktop", "burner")),
    LookRule("hardware", ("handle",)),
    LookRule("metal", ("steel", "metal", "lid")),
    LookRule("appliance", ("body",), APPLIANCES),
    LookRule("cabinetry", ("body", "front"), ("kitchen_counter", "cabinet", "drawer_unit", "wardrobe")),
    LookRule("countertop", ("countertop",)),
    LookRule("wood", ("wood", "leaf", "frame", "legs", "seat", "body", "front")),
    LookRule("control", ("button", "knob")),
    LookRule("ceramic", ("ceramic",)),
    LookRule("print", ("can",)),
)


# --------------------------------------------------------------------------------------------
# typed values
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PackageMaterial:
    """A material of a package as ingest wrote it. name: the Material prim's name; shader: its
    surface shader's path relative to the package's default prim (``Looks/<name>/<shader>``);
    color_input: the colour input's name (``diffuseColor`` or ``baseColor``); rgb: its linear
    colour (None when textured); roughness, metallic: authored values (None if not authored);
    textured: the colour input is connected to another shader (a texture)."""

    name: str
    shader: str
    color_input: str
    rgb: RGB | None
    roughness: float | None
    metallic: float | None
    textured: bool


@dataclass(frozen=True)
class MaterialOverride:
    """One authored override. role: the placed package's role ("fridge", ...); material: the
    Material prim's name; shader: the surface shader's prim path in the scene; color_input;
    rgb: new linear diffuse colour; roughness [0, 1]; metallic [0, 1] or None (not authored);
    rule: the kind of :data:`RULES` that chose it."""

    role: str
    material: str
    shader: str
    color_input: str
    rgb: RGB
    roughness: float
    metallic: float | None
    rule: str


@dataclass(frozen=True)
class LightLook:
    """The kitchen's lights. ceiling_lux: illuminance on the floor below the ceiling light [lux];
    ceiling_kelvin: its colour temperature [K]; ceiling_offset: (dx, dy) of the light from the
    room centre [m]; sun_lux: illuminance on a surface facing the sun [lux]; sun_tilt: rotation of
    the sun's -Z axis about world X, then Y [deg]; dome_lux: illuminance from the sky dome on a
    horizontal surface [lux]."""

    ceiling_lux: float
    ceiling_kelvin: float
    ceiling_offset: tuple[float, float]
    sun_lux: float
    sun_tilt: tuple[float, float]
    dome_lux: float

    @property
    def sun_direction(self) -> tuple[float, float, float]:
        """Unit vector (3,) the sunlight travels along (world frame)."""
        from scipy.spatial.transform import Rotation

        d = Rotation.from_euler("xy", list(self.sun_tilt), degrees=True).apply([0.0, 0.0, -1.0])
        return tuple(float(v) for v in d)


@dataclass(frozen=True)
class KitchenLook:
    """A world's look: floor and wall colours (linear RGB, the room's own boxes), the packages'
    material overrides (sorted by role, then material) and the lights."""

    floor: RGB
    wall: RGB
    materials: tuple[MaterialOverride, ...]
    lights: LightLook

    def override(self, role: str, material: str) -> MaterialOverride | None:
        """The override of ``material`` of the package placed as ``role`` (None: left as is)."""
        return next((m for m in self.materials if m.role == role and m.material == material), None)


# --------------------------------------------------------------------------------------------
# reading the packages
# --------------------------------------------------------------------------------------------


def package_materials(usd: Path) -> tuple[PackageMaterial, ...]:
    """The UsdPreviewSurface materials of a package (root layer ``usd``), sorted by name."""
    usd = Path(usd).resolve()
    if not usd.is_file():
        raise ItemError(f"{usd}: asset package not found")
    return _package_materials(str(usd), usd.stat().st_mtime_ns)


@functools.lru_cache(maxsize=256)
def _package_materials(usd: str, _mtime_ns: int) -> tuple[PackageMaterial, ...]:
    from pxr import Usd, UsdShade

    stage = Usd.Stage.Open(usd)
    root = stage.GetDefaultPrim() if stage is not None else None
    if not root:
        raise ItemError(f"{usd}: cannot open the asset package (no default prim)")
    out = []
    for prim in Usd.PrimRange(root):
        if not prim.IsA(UsdShade.Material):
            continue
        shader = UsdShade.Material(prim).ComputeSurfaceSource()[0]
        if not shader or shader.GetIdAttr().Get() != "UsdPreviewSurface":
            log.debug("%s: material %s has no UsdPreviewSurface; left as is", usd, prim.GetPath())
            continue
        name = "diffuseColor" if shader.GetInput("diffuseColor") or not shader.GetInput("baseColor") else "baseColor"
        inp = shader.GetInput(name)
        textured = bool(inp) and inp.HasConnectedSource()
        value = inp.Get() if inp and not textured else None
        out.append(PackageMaterial(
            name=prim.GetName(), shader=str(shader.GetPath().MakeRelativePath(root.GetPath())),
            color_input=name, rgb=None if value is None else tuple(float(v) for v in value),
            roughness=_scalar(shader, "roughness"), metallic=_scalar(shader, "metallic"), textured=textured))
    return tuple(sorted(out, key=lambda m: m.name))


def _scalar(shader, name: str) -> float | None:
    inp = shader.GetInput(name)
    if not inp or inp.HasConnectedSource():
        return None
    v = inp.Get()
    return None if v is None else float(v)


# --------------------------------------------------------------------------------------------
# sampling
# --------------------------------------------------------------------------------------------


def rule_for(material: str, category: str) -> str:
    """The kind of the first rule of :data:`RULES` matching the material name and category."""
    return next((r.kind for r in RULES if r.matches(material, category)), "jitter")


def _draw(rng: np.random.Generator, palette: str) -> Swatch:
    sw = PALETTES[palette]
    p = np.array([s.weight for s in sw], float)
    return sw[int(rng.choice(len(sw), p=p / p.sum()))]


def hsv_jitter(rng: np.random.Generator, rgb, hue: float = 0.02, sat: float = 0.1,
               val: float = 0.08) -> RGB:
    """``rgb`` (linear, [0, 1]) with hue shifted by up to ``hue`` (fraction of the circle) and
    saturation and value scaled by up to 1 +- ``sat`` / ``val``; clipped to [0.02, 0.95]."""
    h, s, v = colorsys.rgb_to_hsv(*(float(x) for x in rgb))
    h = (h + rng.uniform(-hue, hue)) % 1.0
    s = float(np.clip(s * rng.uniform(1 - sat, 1 + sat), 0.0, 1.0))
    v = float(np.clip(v * rng.uniform(1 - val, 1 + val), 0.0, 1.0))
    return tuple(float(np.clip(c, 0.02, 0.95)) for c in colorsys.hsv_to_rgb(h, s, v))


def _material_override(rng, role: str, prim: str, m: PackageMaterial, kind: str,
                       shared: dict[str, Swatch]) -> MaterialOverride | None:
    if kind == "keep" or m.textured or m.rgb is None:
        return None
    if kind in ("jitter", "metal"):
        rgb = hsv_jitter(rng, m.rgb, 0.03, 0.15, 0.12)
        rough = float(np.clip((m.roughness if m.roughness is not None else 0.5) + rng.uniform(-0.1, 0.1), 0.05, 1))
        metallic = 1.0 if kind == "metal" else None
    else:
        if kind == "hardware" or (kind == "appliance" and rng.random() < APPLIANCE_MATCH):
            sw = shared[kind]
        else:
            sw = _draw(rng, kind)
        rgb = hsv_jitter(rng, sw.rgb)
        rough, metallic = float(rng.uniform(*sw.roughness)), sw.metallic
    return MaterialOverride(role=role, material=m.name, shader=f"{prim}/{m.shader}", color_input=m.color_input,
                            rgb=rgb, roughness=rough, metallic=metallic, rule=kind)


def sample_lights(rng: np.random.Generator) -> LightLook:
    """Ceiling, sun and sky lights drawn from the ranges of the module doc."""
    kelvin = float(rng.uniform(*CEILING_KELVIN))
    lux = float(rng.uniform(*CEILING_LUX))
    off = (float(rng.uniform(-1, 1) * CEILING_JITTER[0]), float(rng.uniform(-1, 1) * CEILING_JITTER[1]))
    tilt = (float(rng.choice([-1.0, 1.0]) * rng.uniform(*SUN_TILT_X)), float(rng.uniform(*SUN_TILT_Y)))
    return LightLook(ceiling_lux=lux, ceiling_kelvin=kelvin, ceiling_offset=off, sun_lux=float(rng.uniform(*SUN_LUX)),
                     sun_tilt=tilt, dome_lux=float(rng.uniform(*DOME_LUX)))


def sample_look(placed: Mapping[str, Placed], rng: np.random.Generator) -> KitchenLook:
    """Draw a look for the packages ``placed`` (role -> :class:`~stages.demos.kitchen.Placed`):
    the kitchen's shared finishes, floor and wall colours, then every role's materials (roles and
    materials in sorted order), then the lights; every draw from ``rng``."""
    shared = {"hardware": _draw(rng, "hardware"), "appliance": _draw(rng, "appliance")}
    floor = hsv_jitter(rng, _draw(rng, "floor").rgb, 0.02, 0.15, 0.12)
    floor = tuple(c * min(1.0, FLOOR_MAX / max(floor)) for c in floor)
    wall = hsv_jitter(rng, _draw(rng, "wall").rgb, 0.02, 0.15, 0.06)
    out = []
    for role in sorted(placed):
        p = placed[role]
        for m in package_materials(p.asset.usd):
            o = _material_override(rng, role, p.prim, m, rule_for(m.name, p.asset.category), shared)
            if o is not None:
                out.append(o)
    return KitchenLook(floor=floor, wall=wall, materials=tuple(out), lights=sample_lights(rng))


# --------------------------------------------------------------------------------------------
# authoring
# --------------------------------------------------------------------------------------------


def add_look(w, look: KitchenLook, size: tuple[float, float]) -> None:
    """Queue the look on a ``stages.simulate.demo_scene._Writer`` (written later with the Sdf API
    in one change block): one ``over`` per overridden shader and the lights (``/World/Lights``)
    of a room of ``size`` (x, y) [m]."""
    from pxr import Gf, Sdf

    from stages.simulate.demo_scene import _add_lights

    for m in look.materials:
        attrs = {f"inputs:{m.color_input}": (Sdf.ValueTypeNames.Color3f, Gf.Vec3f(*m.rgb)),
                 "inputs:roughness": (Sdf.ValueTypeNames.Float, m.roughness)}
        if m.metallic is not None:
            attrs["inputs:metallic"] = (Sdf.ValueTypeNames.Float, m.metallic)
        # the writer defines its prims; the meta field turns this one into an over of the package's
        # shader (same type name), its ancestors below the referencing prim are typeless overs
        w.prim(m.shader, "Shader", attrs=attrs, meta={"specifier": Sdf.SpecifierOver})
    lt = look.lights
    dx, dy = lt.ceiling_offset
    _add_lights(w, size, ceiling_lux=lt.ceiling_lux, ceiling_kelvin=lt.ceiling_kelvin,
                ceiling_xy=(size[0] / 2 + dx, size[1] / 2 + dy), sun_lux=lt.sun_lux, sun_tilt=lt.sun_tilt,
                dome_lux=lt.dome_lux)


def describe(look: KitchenLook) -> str:
    """One line per role: material -> hex colour (sRGB), and the lights (for logs and reports)."""
    def hexc(rgb) -> str:
        s = [1.055 * c ** (1 / 2.4) - 0.055 if c > 0.0031308 else 12.92 * c for c in rgb]
        return "#" + "".join(f"{int(round(255 * min(max(c, 0.0), 1.0))):02x}" for c in s)

    roles: dict[str, list[str]] = {}
    for m in look.materials:
        roles.setdefault(m.role, []).append(f"{m.material}={hexc(m.rgb)}({m.rule})")
    lt = look.lights
    lines = [f"room: floor={hexc(look.floor)} wall={hexc(look.wall)}"]
    lines += [f"{r}: {' '.join(v)}" for r, v in roles.items()]
    lines.append(f"lights: ceiling {lt.ceiling_lux:.0f} lux {lt.ceiling_kelvin:.0f} K at "
                 f"({lt.ceiling_offset[0]:+.2f}, {lt.ceiling_offset[1]:+.2f}) m, sun {lt.sun_lux:.0f} lux "
                 f"tilt ({lt.sun_tilt[0]:+.0f}, {lt.sun_tilt[1]:+.0f}) deg, sky {lt.dome_lux:.0f} lux")
    return "\n".join(lines)


__all__ = ["KitchenLook", "LightLook", "LookRule", "MaterialOverride", "PackageMaterial", "PALETTES", "RULES",
           "Swatch", "add_look", "describe", "hsv_jitter", "package_materials", "rule_for", "sample_lights",
           "sample_look"]
