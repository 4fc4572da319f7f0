"""Lighting of a scene with UsdLux: a ceiling light per room and optional daylight.

Units (UsdLux's physically based reading). A light's ``inputs:intensity`` is its physical value:
luminance [nit = cd/m^2] of the emitter's surface for a ``SphereLight`` (and rect, disk, cylinder
lights), illuminance [lux] on a surface facing it for a ``DistantLight``, luminance [nit] of the
sky for a ``DomeLight`` (so the illuminance it gives a horizontal surface is ``pi * intensity``
[lux]). ``inputs:exposure`` [stops] scales what a renderer emits by ``2^exposure``. Every light
of a scene carries the same exposure, :data:`SCENE_EXPOSURE`: the exposure of a camera for the
lit interior, baked into the lights, so that renderers that show an emitted radiance of 1 as
white and apply no camera exposure of their own (Blender: measured with Cycles; usdview's Storm by
default, not checked here) show the room exposed, one common factor away from the physical
values. The dome light is the exception: its intensity holds the exposure (``2^SCENE_EXPOSURE``
times the physical value, exposure 0), because Blender's importer ignores a dome's exposure.
Renderers with a camera exposure (Omniverse RTX, Karma with a physical camera) should add
``-SCENE_EXPOSURE`` stops there (or use auto exposure). Our own camera
(``stages.simulate.sensors``) exposes automatically for the indoor illuminance, so any factor
common to all lights divides out and its images do not depend on ``SCENE_EXPOSURE``.

Ceiling light: a ``SphereLight`` of radius ``r`` hung ``h`` above the floor centre. Its luminous
intensity straight down is ``I = L * pi * r^2`` [cd] for luminance ``L = intensity`` [nit], its
luminous flux ``4 pi I`` [lm], and the illuminance on the floor right below it (direct light only)
``E = I / h^2`` [lux]. The stage samples the target ``E`` [lux] and the colour temperature [K]
and solves ``intensity = E h^2 / (pi r^2)``. (The targets are direct light, for our camera that
has no bounce light: 150-800 lux from 2.35 m is 10-55 klm, several home fixtures' worth; a path
tracer adds bounce light on top.) Daylight is a ``DistantLight`` (intensity: the sun's
illuminance [lux]) plus a dim ``DomeLight`` sky. Every chosen value is recorded on the light
(``customData``) and returned in ``LightSpec``.

Blender (5.0.1; ``usd_reader_light.cc`` and a Cycles render of a lit plane) reads a sphere light as
a point light of ``energy = pi * intensity`` [W] with Blender's own ``exposure`` and
``normalize`` (off: Cycles then emits ``energy * 2^exposure * 4 pi r^2`` [W], so the watts it
renders are the UsdLux luminous flux in lumens times ``2^exposure``), a distant light as a sun of
strength ``4 * intensity`` [W/m^2] (times ``2^exposure``), and a dome light as the world's
background of strength ``intensity`` (its exposure ignored; the dome is skipped when the Blender
scene has no world); :func:`blender_power` gives these figures. With ``SCENE_EXPOSURE`` -10 a
ceiling light giving 150-800 lux below it from 2.35 m (the default 2.6 m ceiling) renders as
10-54 W in Blender (``tests/benchmarks/bench_blender_lights.py`` renders scenes there and checks
their histograms).
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

LUX_RANGE = (50.0, 20000.0)
KELVIN_RANGE = (2700.0, 6500.0)
EXPOSURE_RANGE = (-16.0, 16.0)
SCENE_EXPOSURE = -10.0  # [stops] inputs:exposure of every light of a scene (see the module doc)


class LightSpec(BaseModel):
    """One light: prim name, type (SphereLight | DistantLight | DomeLight), position [m] (3,),
    radius [m], intensity [nit; lux for the distant light] (physical, before the exposure; the
    dome's times ``2^SCENE_EXPOSURE``, its exposure 0, see the module doc),
    exposure [stops], color temperature [K], target illuminance at the floor [lux] (physical,
    direct light), sun elevation and azimuth [deg] (distant light)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str
    type: str
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius: float = 0.0
    intensity: float = Field(gt=0.0)
    exposure: float = Field(ge=EXPOSURE_RANGE[0], le=EXPOSURE_RANGE[1])
    color_temperature: float = Field(ge=KELVIN_RANGE[0], le=KELVIN_RANGE[1])
    target_lux: float = Field(ge=LUX_RANGE[0], le=LUX_RANGE[1])
    elevation: float = 0.0
    azimuth: float = 0.0

    def floor_lux(self, height: float) -> float:
        """Physical illuminance [lux] right below a sphere light hung ``height`` [m] above the floor
        (direct light; a renderer shows it times ``2^exposure``)."""
        return self.intensity * math.pi * self.radius ** 2 / height ** 2

    def luminous_flux(self) -> float:
        """Physical luminous flux [lm] of a sphere light: ``intensity * pi * 4 pi r^2``."""
        return self.intensity * 4.0 * math.pi ** 2 * self.radius ** 2


class LightingConfig(BaseModel):
    """ceiling_lux, daylight_lux: (min, max) target illuminance [lux]; kelvin: (min, max) [K];
    exposure: every light's ``inputs:exposure`` [stops] (see the module doc); daylight: probability
    of adding daylight; radius [m]; drop [m]: light center below the ceiling."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    ceiling_lux: tuple[float, float] = (150.0, 800.0)
    daylight_lux: tuple[float, float] = (2000.0, 20000.0)
    kelvin: tuple[float, float] = (2700.0, 6500.0)
    exposure: float = Field(default=SCENE_EXPOSURE, ge=EXPOSURE_RANGE[0], le=EXPOSURE_RANGE[1])
    daylight: float = Field(default=0.5, ge=0.0, le=1.0)
    radius: float = Field(default=0.08, gt=0.0)
    drop: float = Field(default=0.25, ge=0.0)


def plan_lights(rooms: list[tuple[str, np.ndarray, float, float]], cfg: LightingConfig,
                rng: np.random.Generator) -> list[LightSpec]:
    """Lights for rooms given as (room id, interior polygon (K, 2) [m], floor elevation [m], ceiling
    height [m]): a ceiling light per room, then daylight with probability ``cfg.daylight``."""
    out = []
    for rid, poly, z0, height in rooms:
        lux = float(rng.uniform(*cfg.ceiling_lux))
        h = height - cfg.drop
        c = _inner_point(poly)
        intensity = lux * h * h / (math.pi * cfg.radius ** 2)
        out.append(LightSpec(name=f"Ceiling_{rid}", type="SphereLight", position=(c[0], c[1], z0 + h),
                             radius=cfg.radius, intensity=intensity, exposure=cfg.exposure,
                             color_temperature=float(rng.uniform(*cfg.kelvin)), target_lux=lux))
    if rng.random() < cfg.daylight:
        lux = float(rng.uniform(*cfg.daylight_lux))
        out.append(LightSpec(name="Sun", type="DistantLight", intensity=lux, exposure=cfg.exposure,
                             color_temperature=float(rng.uniform(5000.0, 6500.0)), target_lux=lux,
                             elevation=float(rng.uniform(20.0, 60.0)), azimuth=float(rng.uniform(0.0, 360.0))))
        sky = max(LUX_RANGE[0], lux * 0.05)
        # the dome holds the exposure in its intensity (Blender ignores a dome's exposure)
        out.append(LightSpec(name="Sky", type="DomeLight", intensity=sky / math.pi * 2.0 ** cfg.exposure,
                             exposure=0.0, color_temperature=6500.0, target_lux=sky))
    return out


def blender_power(kind: str, intensity: float, exposure: float = 0.0, *, radius: float = 0.5,
                  normalize: bool = False) -> float:
    """What Blender 5.0.1 renders for a UsdLux light (see the module doc): a ``SphereLight``'s
    power [W] (its radius [m] as authored, UsdLux's fallback 0.5), a ``DistantLight``'s sun
    strength [W/m^2], a ``DomeLight``'s background strength (radiance; its exposure ignored)."""
    scale = intensity * 2.0 ** exposure
    if kind == "SphereLight":
        return math.pi * scale * (1.0 if normalize else 4.0 * math.pi * radius ** 2)
    if kind == "DistantLight":
        return 4.0 * scale
    if kind == "DomeLight":
        return intensity
    raise ValueError(f"blender_power: {kind} lights are not modelled (SphereLight, DistantLight, DomeLight)")


def _inner_point(poly: np.ndarray) -> tuple[float, float]:
    """The bounding-box center if it lies inside the polygon (L-shaped rooms), else the centroid of
    the vertices nearest to it that does."""
    from stages.scene.geom import points_in_polygon

    c = (poly.min(axis=0) + poly.max(axis=0)) / 2
    if points_in_polygon(c[None], poly)[0]:
        return float(c[0]), float(c[1])
    for v in sorted(poly, key=lambda p: float(np.linalg.norm(p - c))):
        q = (v + c) / 2
        if points_in_polygon(q[None], poly)[0]:
            return float(q[0]), float(q[1])
    return float(poly[0][0]), float(poly[0][1])


def sun_orientation(elevation: float, azimuth: float) -> tuple[float, float, float, float]:
    """Quaternion (w, x, y, z) turning a DistantLight (shines along its -Z) to come from the sky at
    ``elevation`` [deg] above the horizon and ``azimuth`` [deg] from +X."""
    from scipy.spatial.transform import Rotation

    el, az = math.radians(elevation), math.radians(azimuth)
    to_sun = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    z = to_sun
    x = np.cross([0.0, 0.0, 1.0], z)
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    qx, qy, qz, qw = Rotation.from_matrix(np.column_stack([x, y, z])).as_quat()
    return float(qw), float(qx), float(qy), float(qz)
