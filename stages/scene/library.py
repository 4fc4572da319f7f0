"""The catalog as the placement solver sees it: ok records by category and where their packages are.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from asset_catalog.index import CatalogRecord


@dataclass(frozen=True)
class Library:
    """The catalog as the solver sees it: ok records by category, and where their packages are."""

    records: dict[str, tuple[CatalogRecord, ...]]
    root: Path  # usd_path of a record is relative to this folder

    @staticmethod
    def from_index(index_path: Path) -> "Library":
        from asset_catalog.index import query_index

        by: dict[str, list[CatalogRecord]] = {}
        for r in query_index(index_path):
            if r.usd_path:
                by.setdefault(r.category, []).append(r)
        return Library({k: tuple(v) for k, v in by.items()}, Path(index_path).parent)

    def usd(self, r: CatalogRecord) -> Path:
        """The record's package root layer, resolved (memoised per library: the solver asks often)."""
        memo = self.__dict__.setdefault("_usd_memo", {})
        got = memo.get(r.id)
        if got is None:
            got = memo[r.id] = (self.root / str(r.usd_path)).resolve()
        return got

    def pick(self, category: str, room_type: str, rng: np.random.Generator,
             keep=None) -> CatalogRecord | None:
        """A random record of the category (preferring those annotated for the room type); ``keep``:
        optional predicate on records."""
        recs = [r for r in self.records.get(category, ()) if keep is None or keep(r)]
        fit = [r for r in recs if room_type in r.room_types] or list(recs)
        return fit[int(rng.integers(len(fit)))] if fit else None
