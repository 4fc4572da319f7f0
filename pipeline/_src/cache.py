"""Content-addressed cache keys.

An item's key is the sha256 of the canonical JSON of::

    {fn, params_type, params (canonical JSON), seed, input file content hashes (in order),
     code version = package version + sha256 of the stage function's module source file,
     keys of the items it depends on}

so an item is recomputed exactly when something it reads changed. Code outside the stage
function's module is covered by the package version only; a planner that wants finer tracking can
list extra source files in ``WorkItem.input_files``.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import importlib.util
import json
from functools import lru_cache
from pathlib import Path
from typing import Any

_CHUNK = 1 << 20


def canonical_json(obj: Any) -> str:
    """Sorted keys, no whitespace, UTF-8 kept: the same value always gives the same string."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


def sha256_file(path: Path) -> str:
    """sha256 (hex) of a file's content."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(_CHUNK):
            h.update(chunk)
    return h.hexdigest()


@lru_cache(maxsize=1)
def package_version() -> str:
    """The installed ``agentworld`` distribution's version ("0+unknown" when run from a bare checkout)."""
    try:
        return importlib.metadata.version("agentworld")
    except importlib.metadata.PackageNotFoundError:
        return "0+unknown"


@lru_cache(maxsize=None)
def module_source_sha(module_name: str) -> str:
    """sha256 of the source file of ``module_name``, found without importing the module itself."""
    spec = importlib.util.find_spec(module_name)
    if spec is None or not spec.origin or not Path(spec.origin).is_file():
        raise LookupError(f"cannot find the source of module {module_name!r}")
    return sha256_file(Path(spec.origin))


def code_version(fn: str) -> str:
    """``"<package version>+<sha256 of fn's module source>"`` for a ``"module:function"`` string."""
    module_name = fn.partition(":")[0]
    return f"{package_version()}+{module_source_sha(module_name)}"


def item_key(*, fn: str, params_type: str, params_json: str, seed: int, input_shas: list[str],
             code: str, dep_keys: list[str]) -> str:
    """The cache key (sha256 hex) of one work item."""
    doc = {"fn": fn, "params_type": params_type, "params": params_json, "seed": seed,
           "inputs": input_shas, "code": code, "deps": dep_keys}
    return hashlib.sha256(canonical_json(doc).encode()).hexdigest()
