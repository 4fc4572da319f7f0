"""Catalog packages in a task world: an ingested package (:class:`CatalogAsset`: its
``generated.json`` record, bounds and root link read from its USD) and a package placed in the world
(:class:`Placed`: prim path, pose, frames of its links and joints in the scene).

Frame: world, Z up, metres, radians; a placed package's pose is the position of its origin and a
yaw about +Z. The kitchen (:mod:`stages.demos.kitchen`) places them; its look
(:mod:`stages.demos.looks`) overrides their materials.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pipeline.types import ItemError


@dataclass(frozen=True, eq=False)
class CatalogAsset:
    """One ingested package: asset_id, category, usd (root layer, absolute), info: its
    ``generated.json`` record (surfaces, handles, joints, params). ``lo`` / ``hi`` (3,) bounds in the
    asset frame [m] and ``root_link`` (its first rigid body's name) are read from the USD on first use."""

    asset_id: str
    category: str
    usd: Path
    info: dict = field(repr=False)

    @property
    def params(self) -> dict:
        return self.info.get("params", {})

    @functools.cached_property
    def _facts(self) -> tuple[tuple, tuple, str]:
        return _package_facts(self.usd)

    @property
    def lo(self) -> tuple[float, float, float]:
        return self._facts[0]

    @property
    def hi(self) -> tuple[float, float, float]:
        return self._facts[1]

    @property
    def root_link(self) -> str:
        return self._facts[2]


def _package_facts(usd: Path) -> tuple[tuple, tuple, str]:
    """Bounds (lo, hi) in the asset frame [m] and the first rigid-body link's name."""
    from pxr import Usd, UsdGeom, UsdPhysics

    stage = Usd.Stage.Open(str(usd))
    if stage is None or not stage.GetDefaultPrim():
        raise ItemError(f"{usd}: cannot open the asset package (no default prim)")
    root = stage.GetDefaultPrim()
    cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), [UsdGeom.Tokens.default_, UsdGeom.Tokens.render])
    r = cache.ComputeWorldBound(root).ComputeAlignedRange()
    links = [c.GetName() for c in root.GetChildren() if c.HasAPI(UsdPhysics.RigidBodyAPI)]
    return (tuple(float(v) for v in r.GetMin()), tuple(float(v) for v in r.GetMax()),
            "base" if "base" in links or not links else links[0])


def link_bounds(usd: Path, link: str) -> tuple[np.ndarray, np.ndarray]:
    """Bounds (lo, hi) (3,) [m] of one link prim of a package in the asset frame (zero joint positions)."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(usd))
    prim = stage.GetDefaultPrim().GetChild(link)
    if not prim:
        raise ItemError(f"{usd}: no link {link!r}")
    cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), [UsdGeom.Tokens.default_, UsdGeom.Tokens.render])
    r = cache.ComputeRelativeBound(prim, stage.GetDefaultPrim()).ComputeAlignedRange()
    return np.array(r.GetMin(), float), np.array(r.GetMax(), float)


def _rot(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True, eq=False)
class Placed:
    """A package placed in the world: name (prim ``/World/<name>``), the asset, position (3,) of its
    origin [m] and yaw [rad] about +Z."""

    name: str
    asset: CatalogAsset
    position: tuple[float, float, float]
    yaw: float

    @property
    def prim(self) -> str:
        return f"/World/{self.name}"

    @property
    def info(self) -> dict:
        return self.asset.info

    def matrix(self) -> np.ndarray:
        """4x4 asset frame -> world."""
        m = np.eye(4)
        m[:3, :3] = _rot(self.yaw)
        m[:3, 3] = self.position
        return m

    def to_world(self, p) -> np.ndarray:
        """A point (3,) of the asset frame in the world [m]."""
        return _rot(self.yaw) @ np.asarray(p, float) + np.asarray(self.position, float)

    def dir_to_world(self, v) -> np.ndarray:
        return _rot(self.yaw) @ np.asarray(v, float)

    def body(self, link: str | None = None) -> str:
        """Prim path of a link (rigid body) in the scene (default: the package's root link)."""
        return f"{self.prim}/{link or self.asset.root_link}"

    def joint(self, name: str) -> str:
        """Prim path of a joint of the package in the scene."""
        return f"{self.prim}/joints/{name}"

    def rect(self, lo2, hi2) -> tuple[float, float, float, float]:
        """World AABB (xmin, ymin, xmax, ymax) of an asset-frame rectangle (lo (2,), hi (2,))."""
        pts = np.array([self.to_world((x, y, 0.0))[:2] for x in (lo2[0], hi2[0]) for y in (lo2[1], hi2[1])])
        return (*pts.min(0), *pts.max(0))

    def footprint(self) -> tuple[float, float, float, float]:
        """World AABB of the package's bounds [m]."""
        return self.rect(self.asset.lo[:2], self.asset.hi[:2])
