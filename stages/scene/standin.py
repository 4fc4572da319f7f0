"""Asset packages + catalog index without the pipeline's ingest step, for tests and benchmarks.

``build_library(out_dir, categories, variants, seed)`` generates default-catalog assets in memory,
computes colliders (``stages.collision``) and masses (``stages.annotate``), writes USD packages to
``<out_dir>/assets/<id>/<id>.usda`` and the catalog index ``<out_dir>/catalog.sqlite`` whose
``usd_path`` entries are relative to ``out_dir`` (the same layout the ingest step produces in a
work dir). It is the same chain of stage functions the ingest step runs, minus source files.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from pipeline.types import derive_seed

log = logging.getLogger(__name__)

_COLLIDER = {"none": "none", "hull": "convexHull", "hulls": "convexDecomposition", "coacd": "convexDecomposition"}


def build_library(out_dir: Path, *, categories: Sequence[str] | None = None, variants: int = 1,
                  seed: int = 0) -> Path:
    """Write packages + index into ``out_dir``; returns the index path. Skips packages already written."""
    from asset_catalog.default_catalog import generate_default_assets
    from asset_catalog.index import CatalogRecord, index_path, write_index
    from stages.annotate import annotate_with_stats
    from stages.collision import CollisionConfig, collider_kind, compute_colliders
    from usd_schemas import write_asset_package

    out_dir = Path(out_dir)
    records = []
    for g in generate_default_assets(variants_per_category=variants, seed=seed, categories=categories):
        m, a = g.model, g.annotation
        rng = np.random.default_rng(derive_seed(seed, "standin", m.name))
        m = compute_colliders(m, CollisionConfig(), rng)
        m, st = annotate_with_stats(m, rng)
        pkg_dir = out_dir / "assets" / m.name
        pkg = write_asset_package(m, pkg_dir, pipeline_version="standin")
        records.append(CatalogRecord(
            id=m.name, category=a.category, room_types=tuple(str(r) for r in a.room_types),
            placement=str(a.placement), material=str(a.material), interactable=a.interactable,
            co_occurrence=a.co_occurrence, usd_path=f"assets/{m.name}/{pkg.root_layer}",
            bbox_min=tuple(pkg.bbox_min), bbox_max=tuple(pkg.bbox_max),
            dimensions=tuple(float(h - l) for l, h in zip(pkg.bbox_min, pkg.bbox_max)),
            volume=st.volume, mass=st.mass, static_friction=st.static_friction,
            dynamic_friction=st.dynamic_friction, restitution=st.restitution,
            collider=_COLLIDER.get(collider_kind(m), "convexHull"),
            n_colliders=sum(len(lk.colliders) for lk in m.links), is_articulated=m.is_articulated,
            n_joints=len(m.joints), source=a.source))
        log.debug("standin package %s", m.name)
    return write_index(index_path(out_dir), records)
