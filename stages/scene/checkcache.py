"""Results of the per-package scene checks, computed once per package content.

A scene references asset packages and a layout layer that many scenes share; what can be checked
on a package alone (its USD validation, its rest on a flat floor) is checked once and kept here,
keyed by ``kind`` and the package's content hash (sha256 over the relative path and bytes of every
file in the package folder: a package that changes gets a new key, so a stale entry is never read).

``CheckCache(root)`` keeps entries as JSON files ``<root>/<kind>/<key>.json`` (written atomically:
several worker processes may share it; the scene job puts it under ``<work dir>/cache/scene_checks``)
and in memory; ``CheckCache(None)`` keeps them in memory only (one process).
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

_HASHES: dict[tuple[str, int, int], str] = {}  # (folder, newest mtime_ns, total size) -> content hash


def content_hash(folder: Path) -> str:
    """sha256 hex of every file below ``folder`` (relative path + bytes, sorted by path). Memoised
    per process on (folder, newest mtime, total size)."""
    folder = Path(folder).resolve()
    files = sorted(p for p in folder.rglob("*") if p.is_file() and not p.name.startswith("."))
    stats = [p.stat() for p in files]
    memo = (str(folder), max((s.st_mtime_ns for s in stats), default=0), sum(s.st_size for s in stats))
    if memo in _HASHES:
        return _HASHES[memo]
    h = hashlib.sha256()
    for p in files:
        h.update(p.relative_to(folder).as_posix().encode() + b"\0")
        h.update(p.read_bytes())
        h.update(b"\0")
    _HASHES[memo] = h.hexdigest()
    return _HASHES[memo]


class CheckCache:
    """Per-package check results by (kind, key); see the module docstring. ``misses`` counts the
    entries computed (``put``) by this instance, ``hits`` those found."""

    def __init__(self, root: Path | None = None):
        self.root = Path(root) if root is not None else None
        self._mem: dict[tuple[str, str], dict[str, Any]] = {}
        self.hits = 0
        self.misses = 0

    def get(self, kind: str, key: str) -> dict[str, Any] | None:
        v = self._mem.get((kind, key))
        if v is None and self.root is not None:
            p = self.root / kind / f"{key}.json"
            if p.is_file():
                try:
                    v = json.loads(p.read_text(encoding="utf-8"))
                except (OSError, ValueError):
                    v = None  # a torn or foreign file: computed again and rewritten
                if v is not None:
                    self._mem[(kind, key)] = v
        if v is not None:
            self.hits += 1
        return v

    def put(self, kind: str, key: str, value: dict[str, Any]) -> None:
        self.misses += 1
        self._mem[(kind, key)] = value
        if self.root is None:
            return
        d = self.root / kind
        d.mkdir(parents=True, exist_ok=True)
        tmp = d / f".{key}.{os.getpid()}.tmp"
        tmp.write_text(json.dumps(value, sort_keys=True) + "\n", encoding="utf-8")
        os.replace(tmp, d / f"{key}.json")


_PROCESS_CACHES: dict[str, CheckCache] = {}


def process_cache(root: Path | None) -> CheckCache:
    """One CheckCache per root (None: memory only) for the whole process, so that a worker that
    builds many scenes reads each entry from disk once."""
    k = str(Path(root).resolve()) if root is not None else ""
    if k not in _PROCESS_CACHES:
        _PROCESS_CACHES[k] = CheckCache(root)
    return _PROCESS_CACHES[k]
