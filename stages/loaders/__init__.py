"""Source loaders: one function per format family, each ``(path, annotation) -> AssetModel``.

- mesh formats (OBJ+MTL, glTF/GLB, STL, PLY): :func:`stages.loaders.mesh.load_mesh_asset`
- URDF: ``stages.loaders.urdf.load_urdf``; MJCF: ``stages.loaders.mjcf.load_mjcf``

:func:`load_source` dispatches by suffix and imports the loader module lazily (trimesh, mujoco and
friends are only imported when a source of that kind is loaded). :class:`LoadLimits` holds the
input limits every loader shares (file size, plausible size of an object).
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import TYPE_CHECKING

from pipeline.types import ItemError
from stages.loaders._source import LoadLimits, check_source_file

if TYPE_CHECKING:
    from asset_catalog.annotations import AssetAnnotation
    from asset_catalog.asset_model import AssetModel

MESH_SUFFIXES = (".obj", ".glb", ".gltf", ".stl", ".ply")
URDF_SUFFIXES = (".urdf",)
MJCF_SUFFIXES = (".xml", ".mjcf")

__all__ = ["MESH_SUFFIXES", "MJCF_SUFFIXES", "URDF_SUFFIXES", "LoadLimits", "check_source_file",
           "load_source", "loader_for"]


def loader_for(path: Path) -> str:
    """``"module:function"`` of the loader for ``path``'s suffix; ItemError for an unknown suffix."""
    suffix = path.suffix.lower()
    if suffix in MESH_SUFFIXES:
        return "stages.loaders.mesh:load_mesh_asset"
    if suffix in URDF_SUFFIXES:
        return "stages.loaders.urdf:load_urdf"
    if suffix in MJCF_SUFFIXES:
        return "stages.loaders.mjcf:load_mjcf"
    raise ItemError(f"{path}: unsupported source type {suffix!r}")


def load_source(path: Path, annotation: "AssetAnnotation", *, limits: LoadLimits | None = None,
                catalog_root: Path | None = None) -> "AssetModel":
    """Load any supported source into an AssetModel (Z-up, meters), after the file checks."""
    limits = limits or LoadLimits()
    check_source_file(path, limits)
    module_name, fn_name = loader_for(path).split(":")
    if module_name == "stages.loaders.mesh":
        from stages.loaders.mesh import load_mesh_asset

        return load_mesh_asset(path, annotation, limits=limits, catalog_root=catalog_root)
    fn = getattr(importlib.import_module(module_name), fn_name)
    return fn(path, annotation, catalog_dir=catalog_root)
