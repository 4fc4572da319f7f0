"""The humanoids the locomotion stack trains, by ``EnvConfig.robot`` name."""

from __future__ import annotations

from stages.locomotion.config import ROBOT_NAMES
from stages.locomotion.h1 import H1
from stages.locomotion.robot import G1, HumanoidDescription

ROBOTS: dict[str, HumanoidDescription] = {"g1": G1, "h1": H1}
assert tuple(ROBOTS) == ROBOT_NAMES, "config.ROBOT_NAMES must list the registry's humanoids"


def humanoid(name: str) -> HumanoidDescription:
    """The description of a humanoid; ValueError naming the known ones for another name."""
    try:
        return ROBOTS[name]
    except KeyError:
        raise ValueError(f"unknown humanoid {name!r} (known: {', '.join(sorted(ROBOTS))})") from None
