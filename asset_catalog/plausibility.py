"""Plausible size and mass per category, and the rule that tells a unit mistake from an odd asset.

An asset authored in centimetres but read as metres ingests 100 times too large and (mass from density x
volume) up to 10^6 times too heavy: a 16 mm rubber duck becomes a 1.6 m, 1,400 kg one. The ingest stage
judges every asset after its mass is known:

- ``size`` is the largest bounding-box dimension [m], ``mass`` the total mass [kg];
- the ranges are the annotation's ``plausible_size`` / ``plausible_mass`` where given, else the
  category's row of :data:`PLAUSIBLE` (exact category name), else :data:`GENERIC`;
- inside both ranges: plausible, nothing is said;
- outside, a *unit mistake* is suspected when some factor ``f`` of :data:`UNIT_MISTAKES` (the source's
  unit read as metres, or metres read as that unit) brings both back into range: the size scales by ``f``;
  a mass computed from the geometry scales by ``f^2`` (a hollow shell) to ``f^3`` (a solid), and a mass
  given by the annotation or the source does not scale. The item then fails with a one-line error that
  suggests ``meters_per_unit = (current meters_per_unit) x f`` for every such factor;
- outside with no such factor: a warning (an odd but possibly real asset); the item goes on.

The ranges are deliberately wide (a category's smallest to largest real member, with margin): a range
narrower than a factor of 100 between low and high is what lets a centimetre mistake always show.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal


@dataclass(frozen=True)
class PlausibleRange:
    """size: (low, high) of the largest bounding-box dimension [m]; mass: (low, high) of the total
    mass [kg]."""

    size: tuple[float, float]
    mass: tuple[float, float]


def _r(size_lo: float, size_hi: float, mass_lo: float, mass_hi: float) -> PlausibleRange:
    return PlausibleRange((size_lo, size_hi), (mass_lo, mass_hi))


_SMALL_DEVICE = _r(0.03, 0.5, 0.01, 4.0)
_DRINKWARE = _r(0.04, 0.4, 0.01, 3.0)
_FRUIT = _r(0.02, 0.4, 0.003, 4.0)
_CABINET = _r(0.1, 3.0, 0.5, 400.0)     # LIBERO's drawer cabinets are 0.2-0.26 m
_TABLE = _r(0.3, 4.0, 2.0, 300.0)

PLAUSIBLE: dict[str, PlausibleRange] = {
    # furniture
    "sofa": _r(0.8, 4.5, 8.0, 300.0), "armchair": _r(0.5, 1.6, 4.0, 120.0),
    "coffee_table": _TABLE, "dining_table": _TABLE, "table": _TABLE, "desk": _TABLE,
    "tv_stand": _r(0.5, 3.5, 4.0, 200.0), "bookshelf": _r(0.3, 3.5, 2.0, 300.0),
    "shelf": _r(0.2, 3.5, 0.5, 300.0), "bed": _r(1.2, 3.2, 10.0, 400.0),
    "nightstand": _r(0.25, 1.2, 2.0, 100.0), "wardrobe": _r(0.8, 3.5, 15.0, 500.0),
    "closet": _r(0.8, 3.5, 15.0, 500.0), "dresser": _r(0.4, 2.5, 8.0, 300.0),
    "chair": _r(0.3, 1.5, 1.0, 60.0), "stool": _r(0.2, 1.2, 0.5, 40.0),
    "kitchen_counter": _r(0.5, 5.0, 15.0, 800.0), "rug": _r(0.4, 6.0, 0.2, 80.0),
    "floor_lamp": _r(0.6, 2.5, 0.5, 60.0), "cabinet": _CABINET, "drawer_cabinet": _CABINET,
    "door": _r(1.2, 3.2, 3.0, 150.0), "bin": _r(0.15, 1.2, 0.1, 30.0),
    "trash_can": _r(0.15, 1.2, 0.1, 30.0),
    # appliances and fittings
    "fridge": _r(0.5, 2.4, 15.0, 400.0), "microwave": _r(0.2, 0.9, 1.0, 50.0),
    "oven": _r(0.4, 1.5, 10.0, 200.0), "dishwasher": _r(0.4, 1.2, 10.0, 150.0),
    "light_switch": _r(0.02, 0.6, 0.005, 3.0), "light_bulb": _r(0.04, 0.3, 0.005, 1.0),
    "kettle": _r(0.1, 0.5, 0.2, 5.0),
    # tableware and kitchen
    "bowl": _r(0.05, 0.45, 0.02, 4.0), "plate": _r(0.08, 0.5, 0.03, 4.0),
    "mug": _DRINKWARE, "cup": _DRINKWARE, "wine_glass": _DRINKWARE, "bottle": _r(0.05, 0.6, 0.01, 5.0),
    "water_bottle": _r(0.05, 0.6, 0.01, 5.0), "can": _r(0.04, 0.35, 0.01, 3.0),
    "pitcher": _r(0.08, 0.5, 0.05, 5.0), "teapot": _r(0.08, 0.5, 0.05, 5.0),
    "tea_set": _r(0.1, 1.5, 0.1, 10.0), "frying_pan": _r(0.15, 0.8, 0.1, 6.0),
    "cutlery": _r(0.05, 0.5, 0.002, 1.0), "kitchen_utensil": _r(0.05, 0.6, 0.002, 2.0),
    "milk_carton": _r(0.06, 0.5, 0.01, 4.0), "cereal_box": _r(0.08, 0.6, 0.01, 3.0),
    "sponge": _r(0.03, 0.3, 0.001, 0.5),
    "dish_rack": _r(0.15, 0.8, 0.1, 6.0), "nut": _r(0.01, 0.5, 0.001, 5.0),
    # food
    "apple": _FRUIT, "orange": _FRUIT, "fruit": _FRUIT, "banana": _r(0.06, 0.4, 0.03, 1.0),
    "bread": _r(0.03, 0.7, 0.01, 3.0),
    # small objects
    "book": _r(0.08, 0.6, 0.03, 6.0), "box": _r(0.03, 1.2, 0.005, 40.0),
    "crumpled_paper": _r(0.01, 0.3, 0.0005, 0.3), "pillow": _r(0.2, 1.2, 0.05, 6.0),
    "cushion": _r(0.04, 0.6, 0.03, 1.0),
    "alarm_clock": _r(0.04, 0.4, 0.02, 3.0), "hanger": _r(0.15, 0.8, 0.01, 1.0),
    "toy": _r(0.012, 1.0, 0.001, 10.0), "rubber_duck": _r(0.02, 0.6, 0.003, 3.0),
    "ball": _r(0.02, 0.6, 0.002, 5.0), "piggy_bank": _r(0.05, 0.5, 0.02, 8.0),
    "toothbrush": _r(0.08, 0.35, 0.003, 0.3), "toothpaste": _r(0.05, 0.35, 0.01, 0.5),
    "stapler": _SMALL_DEVICE, "phone": _SMALL_DEVICE, "computer_mouse": _SMALL_DEVICE,
    "camera": _SMALL_DEVICE, "headphones": _SMALL_DEVICE, "binoculars": _SMALL_DEVICE,
    "flashlight": _SMALL_DEVICE,
    # robots (whole arms, humanoids and mobile manipulators)
    "robot": _r(0.2, 3.0, 0.5, 400.0),
}
"""Plausible range per category (exact ``annotation.category``)."""

GENERIC = _r(0.005, 10.0, 1e-4, 3000.0)
"""The fallback for a category without a row: catches only gross mistakes (a 16 cm thing in mm is 160 m,
already refused by the loaders' absurd-scale limit; in cm, 16 m)."""

UNIT_MISTAKES: dict[float, str] = {
    0.001: "millimetres", 0.01: "centimetres", 0.0254: "inches", 0.3048: "feet",
    1000.0: "metres annotated as millimetres", 100.0: "metres annotated as centimetres",
    1 / 0.0254: "metres annotated as inches",
}
"""Factor on ``meters_per_unit`` -> the mistake (the source's unit read as metres, or the reverse)."""


@dataclass(frozen=True)
class Judgement:
    """verdict: "ok" | "unit" (fail: a unit mistake) | "odd" (warn); message: one line, empty when ok;
    factors: the ``meters_per_unit`` factors that make the asset plausible (for "unit")."""

    verdict: Literal["ok", "unit", "odd"]
    message: str = ""
    factors: tuple[float, ...] = ()


def range_for(category: str, size: tuple[float, float] | None = None,
              mass: tuple[float, float] | None = None) -> tuple[PlausibleRange, str]:
    """The plausible range of a category with the annotation's overrides, and where it came from."""
    base = PLAUSIBLE.get(category)
    where = f"category {category!r}" if base is not None else f"generic (no row for {category!r})"
    base = base or GENERIC
    if size is not None or mass is not None:
        where += " with annotated " + " and ".join(
            n for n, v in (("plausible_size", size), ("plausible_mass", mass)) if v is not None)
    return PlausibleRange(size or base.size, mass or base.mass), where


def judge(category: str, size_m: float, mass_kg: float, *, meters_per_unit: float = 1.0,
          mass_scales: bool = True, size_range: tuple[float, float] | None = None,
          mass_range: tuple[float, float] | None = None) -> Judgement:
    """Judge an ingested asset (see the module docstring).

    size_m: largest bounding-box dimension [m]; mass_kg: total mass [kg]; meters_per_unit: the one the
    source was read with; mass_scales: the mass came from the geometry (not annotated, not from the source);
    size_range / mass_range: the annotation's overrides ([m], [kg]).
    """
    rng, where = range_for(category, size_range, mass_range)

    def inside(v: float, r: tuple[float, float]) -> bool:
        return r[0] <= v <= r[1]

    def mass_fits(f: float) -> bool:
        if not mass_scales:
            return inside(mass_kg, rng.mass)
        lo, hi = sorted((mass_kg * f ** 2, mass_kg * f ** 3))
        return lo <= rng.mass[1] and hi >= rng.mass[0]

    if inside(size_m, rng.size) and inside(mass_kg, rng.mass):
        return Judgement("ok")
    seen = (f"largest dimension {size_m:.3g} m and mass {mass_kg:.3g} kg are implausible for {where} "
            f"({rng.size[0]:g}-{rng.size[1]:g} m, {rng.mass[0]:g}-{rng.mass[1]:g} kg)")
    factors = tuple(f for f in UNIT_MISTAKES if inside(size_m * f, rng.size) and mass_fits(f))
    if not factors:
        return Judgement("odd", f"{seen}; no unit mistake explains it (set plausible_size / plausible_mass "
                                "in the annotation if it is right)")
    hints = " or ".join(f"{meters_per_unit * f:.6g} ({UNIT_MISTAKES[f]})" for f in factors)
    return Judgement("unit", f"{seen}: likely a unit mistake, set meters_per_unit = {hints} (or widen "
                             "plausible_size / plausible_mass in the annotation)", factors)
