"""Material classes and the physical rules derived from them.

A material class is the one physical fact a person annotates per asset; density, friction and
restitution follow from these rules (sampled per asset from the stage's seeded generator), and so do
the torsional and rolling friction (fixed per class, not sampled).

Torsional and rolling friction are lengths, as in MuJoCo and Newton (``newton:torsionalFriction``,
``newton:rollingFriction``; URDF's ``spinning_friction`` / ``rolling_friction``): the resisting
torque [N m] is the coefficient [m] times the normal force [N]. Torsional friction is about the
contact patch's size (it stops a body spinning on the floor); rolling friction is about how deep
the surfaces deform (it stops a ball rolling: a solid ball of radius r decelerates at about
5/7 g mu_roll / r). Soft materials (rubber, fabric, food, paper) get more of both. MuJoCo's and
Newton's defaults are 0.005 m and 0.0001 m; a contact takes the larger value of its two bodies.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np


class MaterialClass(StrEnum):
    WOOD = "wood"
    METAL = "metal"
    CERAMIC = "ceramic"
    GLASS = "glass"
    PLASTIC = "plastic"
    FABRIC = "fabric"
    RUBBER = "rubber"
    STONE = "stone"
    PAPER = "paper"
    FOOD = "food"


@dataclass(frozen=True, kw_only=True)
class MaterialRule:
    """Physical properties of one material class.

    density: bulk density of the solid [kg/m^3]
    friction: (mean, half-range) of the dynamic friction coefficient [-]
    restitution: (mean, half-range) of the coefficient of restitution [-], in [0, 1]
    base_color: default linear RGB albedo in [0, 1] when the source has no material
    roughness, metallic: default UsdPreviewSurface values in [0, 1]
    torsional_friction: resistance to spinning about the contact normal [m] (module docstring)
    rolling_friction: resistance to rolling [m] (module docstring)
    """

    density: float
    friction: tuple[float, float]
    restitution: tuple[float, float]
    base_color: tuple[float, float, float]
    roughness: float
    metallic: float = 0.0
    torsional_friction: float = 0.005
    rolling_friction: float = 0.0001


MATERIAL_RULES: dict[MaterialClass, MaterialRule] = {
    MaterialClass.WOOD: MaterialRule(density=700.0, friction=(0.4, 0.1), restitution=(0.3, 0.05),
                                     base_color=(0.55, 0.38, 0.22), roughness=0.6,
                                     torsional_friction=0.005, rolling_friction=0.0003),
    MaterialClass.METAL: MaterialRule(density=7800.0, friction=(0.2, 0.05), restitution=(0.4, 0.05),
                                      base_color=(0.7, 0.7, 0.72), roughness=0.3, metallic=1.0,
                                      torsional_friction=0.003, rolling_friction=0.0001),
    MaterialClass.CERAMIC: MaterialRule(density=2400.0, friction=(0.5, 0.05), restitution=(0.25, 0.05),
                                        base_color=(0.92, 0.92, 0.9), roughness=0.2,
                                        torsional_friction=0.003, rolling_friction=0.0001),
    MaterialClass.GLASS: MaterialRule(density=2500.0, friction=(0.4, 0.05), restitution=(0.3, 0.05),
                                      base_color=(0.85, 0.9, 0.92), roughness=0.05,
                                      torsional_friction=0.003, rolling_friction=0.0001),
    MaterialClass.PLASTIC: MaterialRule(density=1100.0, friction=(0.35, 0.05), restitution=(0.4, 0.05),
                                        base_color=(0.8, 0.2, 0.2), roughness=0.4,
                                        torsional_friction=0.004, rolling_friction=0.0002),
    MaterialClass.FABRIC: MaterialRule(density=300.0, friction=(0.6, 0.1), restitution=(0.1, 0.05),
                                       base_color=(0.45, 0.5, 0.6), roughness=0.9,
                                       torsional_friction=0.01, rolling_friction=0.002),
    MaterialClass.RUBBER: MaterialRule(density=1200.0, friction=(0.9, 0.1), restitution=(0.7, 0.1),
                                       base_color=(0.1, 0.1, 0.1), roughness=0.8,
                                       torsional_friction=0.008, rolling_friction=0.001),
    MaterialClass.STONE: MaterialRule(density=2600.0, friction=(0.6, 0.1), restitution=(0.2, 0.05),
                                      base_color=(0.6, 0.6, 0.58), roughness=0.5,
                                      torsional_friction=0.004, rolling_friction=0.0002),
    MaterialClass.PAPER: MaterialRule(density=600.0, friction=(0.5, 0.1), restitution=(0.1, 0.05),
                                      base_color=(0.9, 0.9, 0.85), roughness=0.9,
                                      torsional_friction=0.005, rolling_friction=0.0005),
    MaterialClass.FOOD: MaterialRule(density=950.0, friction=(0.6, 0.1), restitution=(0.2, 0.05),
                                     base_color=(0.8, 0.6, 0.2), roughness=0.7,
                                     torsional_friction=0.008, rolling_friction=0.001),
}


@dataclass(frozen=True, kw_only=True)
class PhysicalProperties:
    """density [kg/m^3], static and dynamic friction [-], restitution [-], torsional and rolling
    friction [m] (see the module docstring)."""

    density: float
    static_friction: float
    dynamic_friction: float
    restitution: float
    torsional_friction: float = 0.005
    rolling_friction: float = 0.0001


def sample_physical_properties(material: MaterialClass, rng: np.random.Generator) -> PhysicalProperties:
    """Sample friction and restitution uniformly within the class's range (seeded, never global);
    torsional and rolling friction are the class's (no draw, so the samples are as before)."""
    rule = MATERIAL_RULES[MaterialClass(material)]
    fm, fh = rule.friction
    rm, rh = rule.restitution
    dyn = float(rng.uniform(fm - fh, fm + fh))
    rest = float(np.clip(rng.uniform(rm - rh, rm + rh), 0.0, 1.0))
    return PhysicalProperties(density=rule.density, static_friction=dyn * 1.1, dynamic_friction=dyn,
                              restitution=rest, torsional_friction=rule.torsional_friction,
                              rolling_friction=rule.rolling_friction)
