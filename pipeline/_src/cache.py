"""Content-addressed cache keys.

An item's key is the sha256 of the canonical JSON of::

    {fn, params_type, params (canonical JSON), seed, input file content hashes (in order),
     code version = package version + sha256 of the stage function's module source file,
     keys of the items it depends on}

so an item is recomputed exactly when something it reads changed.

Code outside the stage function's module is covered by the package version only, unless the module
declares what else it runs, as a literal tuple of module or package names (a package stands for all
``.py`` files under it)::

    CODE_DEPS = ("stages.layout", "asset_catalog.materials")

The declaration is read from the module's source (``ast``), without importing it; those files'
hashes join the code version. A planner can also list extra files in ``WorkItem.input_files``.
"""

from __future__ import annotations

import ast
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


def module_source(module_name: str) -> Path:
    """The source file of ``module_name`` (``__init__.py`` for a package), found without importing
    the module itself (its parent packages are imported)."""
    spec = importlib.util.find_spec(module_name)
    if spec is None or not spec.origin or not Path(spec.origin).is_file():
        raise LookupError(f"cannot find the source of module {module_name!r}")
    return Path(spec.origin)


@lru_cache(maxsize=None)
def module_source_sha(module_name: str) -> str:
    """sha256 of the source file of ``module_name``."""
    return sha256_file(module_source(module_name))


def declared_code_deps(source: Path) -> tuple[str, ...]:
    """The ``CODE_DEPS = ("pkg.mod", ...)`` literal of a module's source (empty if none)."""
    tree = ast.parse(source.read_text(encoding="utf-8"), filename=str(source))
    for node in tree.body:
        target = node.target if isinstance(node, ast.AnnAssign) else (
            node.targets[0] if isinstance(node, ast.Assign) and len(node.targets) == 1 else None)
        if isinstance(target, ast.Name) and target.id == "CODE_DEPS" and node.value is not None:
            value = ast.literal_eval(node.value)
            if not isinstance(value, (tuple, list)) or not all(isinstance(v, str) for v in value):
                raise ValueError(f"{source}: CODE_DEPS must be a tuple of module names")
            return tuple(value)
    return ()


def _dep_files(name: str) -> list[Path]:
    src = module_source(name)
    if src.name == "__init__.py":
        return sorted(src.parent.rglob("*.py"))
    return [src]


@lru_cache(maxsize=None)
def code_version(fn: str) -> str:
    """``"<package version>+<sha256 of fn's module source>[+<sha256 of its CODE_DEPS sources>]"`` for a
    ``"module:function"`` string (computed once per process)."""
    module_name = fn.partition(":")[0]
    version = f"{package_version()}+{module_source_sha(module_name)}"
    deps = declared_code_deps(module_source(module_name))
    if deps:
        h = hashlib.sha256()
        for f in sorted({f.resolve() for d in deps for f in _dep_files(d)}):
            h.update(f"{f.name}\x00{sha256_file(f)}\x00".encode())
        version += f"+{h.hexdigest()}"
    return version


def item_key(*, fn: str, params_type: str, params_json: str, seed: int, input_shas: list[str],
             code: str, dep_keys: list[str]) -> str:
    """The cache key (sha256 hex) of one work item."""
    doc = {"fn": fn, "params_type": params_type, "params": params_json, "seed": seed,
           "inputs": input_shas, "code": code, "deps": dep_keys}
    return hashlib.sha256(canonical_json(doc).encode()).hexdigest()
