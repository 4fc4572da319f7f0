"""Lighting of a scene with UsdLux: a ceiling light per room and optional daylight.

A ceiling light is a ``SphereLight`` of radius ``r`` hung ``h`` above the floor center. Its
luminous intensity straight down is ``I = L * pi * r^2`` [cd] for radiance ``L = intensity *
2^exposure`` [nit], so the illuminance on the floor right below it is ``E = I / h^2`` [lux]. The
stage samples the target ``E`` (lux), the color temperature (K) and the exposure, and solves
``intensity = E h^2 / (pi r^2 2^exposure)``. Daylight is a ``DistantLight`` (its intensity x
2^exposure is the illuminance [lux] on a surface facing it) plus a dim ``DomeLight`` sky. Every chosen
value is recorded on the light (``customData``) and returned in ``LightSpec``.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

LUX_RANGE = (50.0, 20000.0)
KELVIN_RANGE = (2700.0, 6500.0)
EXPOSURE_RANGE = (-5.0, 5.0)


class LightSpec(BaseModel):
    """One light: prim name, type (SphereLight | DistantLight | DomeLight), position [m] (3,),
    radius [m], intensity [nit], exposure [stops], color temperature [K], target illuminance at the
    floor [lux], sun elevation and azimuth [deg] (distant light)."""

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
        """Illuminance [lux] right below a sphere light hung ``height`` [m] above the floor."""
        return self.intensity * 2.0 ** self.exposure * math.pi * self.radius ** 2 / height ** 2


class LightingConfig(BaseModel):
    """ceiling_lux, daylight_lux: (min, max) target illuminance [lux]; kelvin: (min, max) [K];
    exposure: (min, max) [stops]; daylight: probability of adding daylight; radius [m]; drop [m]:
    light center below the ceiling."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    ceiling_lux: tuple[float, float] = (150.0, 800.0)
    daylight_lux: tuple[float, float] = (2000.0, 20000.0)
    kelvin: tuple[float, float] = (2700.0, 6500.0)
    exposure: tuple[float, float] = (-2.0, 2.0)
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
        exp = float(rng.uniform(*cfg.exposure))
        h = height - cfg.drop
        c = _inner_point(poly)
        intensity = lux * h * h / (math.pi * cfg.radius ** 2 * 2.0 ** exp)
        out.append(LightSpec(name=f"Ceiling_{rid}", type="SphereLight", position=(c[0], c[1], z0 + h),
                             radius=cfg.radius, intensity=intensity, exposure=exp,
                             color_temperature=float(rng.uniform(*cfg.kelvin)), target_lux=lux))
    if rng.random() < cfg.daylight:
        lux = float(rng.uniform(*cfg.daylight_lux))
        exp = float(rng.uniform(*cfg.exposure))
        out.append(LightSpec(name="Sun", type="DistantLight", intensity=lux / 2.0 ** exp, exposure=exp,
                             color_temperature=float(rng.uniform(5000.0, 6500.0)), target_lux=lux,
                             elevation=float(rng.uniform(20.0, 60.0)), azimuth=float(rng.uniform(0.0, 360.0))))
        sky = max(LUX_RANGE[0], lux * 0.05)
        out.append(LightSpec(name="Sky", type="DomeLight", intensity=sky / math.pi, exposure=0.0,
                             color_temperature=6500.0, target_lux=sky))
    return out


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
