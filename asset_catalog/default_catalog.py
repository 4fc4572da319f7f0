"""The default catalog: every built-in generator x N seeded variants, written as a catalog folder.

    build_default_catalog(Path("out/catalog"), variants_per_category=5, seed=0)

writes ``<out>/<category>/<id>/...`` source files (OBJ, or URDF + OBJ meshes), ``<out>/annotations.toml``
and ``<out>/generated.json`` (per asset: source kind, joint roles, graspable handles, sampled
parameters). The same seed gives byte-identical files. Each asset's generator is seeded from
(seed, asset id) only, so selecting fewer categories or variants leaves the others unchanged.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from asset_catalog.annotations import ANNOTATION_FILENAME
from asset_catalog.generators import (
    GENERATORS, GENERATORS_BY_CATEGORY, GeneratedAsset, annotations_text, generate, write_asset)
from pipeline.types import derive_seed

log = logging.getLogger(__name__)

GENERATED_INFO_FILENAME = "generated.json"


@dataclass(frozen=True)
class CatalogBuildReport:
    """What ``build_default_catalog`` wrote: the catalog folder, asset ids in order, number of files,
    categories, and the wall time [s]."""

    out_dir: Path
    asset_ids: tuple[str, ...]
    categories: tuple[str, ...]
    n_files: int
    seconds: float


def asset_rng(seed: int, asset_id: str) -> np.random.Generator:
    """The generator of one default-catalog asset: from (catalog seed, asset id) only."""
    return np.random.default_rng(derive_seed(seed, "default_catalog", asset_id))


def generate_default_assets(*, variants_per_category: int = 5, seed: int = 0,
                            categories: Sequence[str] | None = None) -> list[GeneratedAsset]:
    """Generate the default catalog's assets in memory (category order of ``GENERATORS``)."""
    specs = _select(categories)
    if variants_per_category < 1:
        raise ValueError(f"variants_per_category must be >= 1, got {variants_per_category}")
    out = []
    for spec in specs:
        for i in range(variants_per_category):
            asset_id = f"{spec.category}_{i:02d}"
            out.append(generate(spec, asset_rng(seed, asset_id), asset_id))
    return out


def build_default_catalog(out_dir: Path, *, variants_per_category: int = 5, seed: int = 0,
                          categories: Sequence[str] | None = None) -> CatalogBuildReport:
    """Write the default catalog folder (see module docstring) and return what was written."""
    t0 = time.perf_counter()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    assets = generate_default_assets(variants_per_category=variants_per_category, seed=seed,
                                     categories=categories)
    n_files = 0
    info: dict[str, dict] = {}
    for a in assets:
        asset_dir = out_dir / Path(a.annotation.source).parent
        n_files += len(write_asset(a, asset_dir))
        info[a.model.name] = _info(a)
    (out_dir / ANNOTATION_FILENAME).write_text(annotations_text([a.annotation for a in assets]),
                                               encoding="utf-8",
                                               newline="\n")
    (out_dir / GENERATED_INFO_FILENAME).write_text(json.dumps(info, indent=1, sort_keys=True) + "\n",
                                                   encoding="utf-8", newline="\n")
    dt = time.perf_counter() - t0
    cats = tuple(dict.fromkeys(a.annotation.category for a in assets))
    log.info("default catalog: %d assets in %d categories, %d files, %.1f s -> %s", len(assets), len(cats),
             n_files + 2, dt, out_dir)
    return CatalogBuildReport(out_dir=out_dir, asset_ids=tuple(a.model.name for a in assets), categories=cats,
                              n_files=n_files + 2, seconds=dt)


def _select(categories: Sequence[str] | None):
    if categories is None:
        return list(GENERATORS)
    unknown = [c for c in categories if c not in GENERATORS_BY_CATEGORY]
    if unknown:
        raise ValueError(f"unknown categories: {', '.join(unknown)}; known: {', '.join(GENERATORS_BY_CATEGORY)}")
    return [s for s in GENERATORS if s.category in set(categories)]


def _info(a: GeneratedAsset) -> dict:
    return {
        "category": a.annotation.category,
        "source_kind": a.source_kind,
        "joints": {j.name: j.role for j in a.joints},
        "handles": [{"link": h.link, "kind": h.kind, "center": [round(c, 5) for c in h.center],
                     "grip_width": round(h.grip_width, 5), "clearance": round(h.clearance, 5),
                     "bar_axis": [round(c, 5) for c in h.bar_axis]} for h in a.handles],
        "surfaces": [{"link": s.link, "z": round(s.z, 5), "lo": [round(v, 5) for v in s.lo],
                      "hi": [round(v, 5) for v in s.hi], "inside": s.inside, "clear_height": round(s.clear_height, 5)}
                     for s in a.surfaces],
        "params": a.params,
    }


def main(argv: list[str]) -> int:
    """``agentworld catalog build-default --out DIR [--variants N] [--seed S] [--categories a,b]``."""
    import argparse

    p = argparse.ArgumentParser(prog="agentworld catalog build-default",
                                description="Write the built-in procedural catalog (sources + annotations.toml).")
    p.add_argument("--out", type=Path, required=True, help="catalog folder to write")
    p.add_argument("--variants", type=int, default=5, help="variants per category (default 5)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--categories", default=None, help="comma-separated subset (default: all)")
    a = p.parse_args(argv)
    cats = [c.strip() for c in a.categories.split(",") if c.strip()] if a.categories else None
    try:
        rep = build_default_catalog(a.out, variants_per_category=a.variants, seed=a.seed, categories=cats)
    except ValueError as e:
        p.error(str(e))
    print(f"wrote {len(rep.asset_ids)} assets in {len(rep.categories)} categories ({rep.n_files} files) to "
          f"{rep.out_dir} in {rep.seconds:.1f} s")
    return 0
