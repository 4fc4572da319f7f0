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

from pydantic import BaseModel, ConfigDict, Field

from pipeline.types import ItemError

if TYPE_CHECKING:
    from asset_catalog.annotations import AssetAnnotation
    from asset_catalog.asset_model import AssetModel

MESH_SUFFIXES = (".obj", ".glb", ".gltf", ".stl", ".ply")
URDF_SUFFIXES = (".urdf",)
MJCF_SUFFIXES = (".xml", ".mjcf")


class LoadLimits(BaseModel):
    """Limits on inputs; a source outside them fails alone with a one-line reason.

    max_file_mb: largest accepted source file [MiB];
    min_dimension_m / max_dimension_m: the asset's largest bounding-box dimension must lie in this
    range after unit conversion [m];
    unit_guess_dimension_m: a mesh without an annotated ``meters_per_unit`` whose largest dimension
    exceeds this many source units is rejected as "probably millimetres/centimetres" [m at 1 m/unit];
    min_hull_volume_m3: a rigid body whose convex hull encloses less than this is flat [m^3].
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    max_file_mb: float = Field(default=200.0, gt=0.0)
    min_dimension_m: float = Field(default=0.001, gt=0.0)
    max_dimension_m: float = Field(default=50.0, gt=0.0)
    unit_guess_dimension_m: float = Field(default=20.0, gt=0.0)
    min_hull_volume_m3: float = Field(default=1e-9, ge=0.0)


def check_source_file(path: Path, limits: LoadLimits) -> None:
    """Raise ItemError if ``path`` is missing, not a regular file, unreadable or larger than allowed."""
    try:
        st = path.stat()
    except FileNotFoundError:
        raise ItemError(f"{path}: source file not found") from None
    except OSError as e:
        raise ItemError(f"{path}: unreadable source file ({e.strerror})") from None
    if not path.is_file():
        raise ItemError(f"{path}: not a regular file")
    size_mb = st.st_size / (1024 * 1024)
    if size_mb > limits.max_file_mb:
        raise ItemError(f"{path}: file is {size_mb:.1f} MiB, over the {limits.max_file_mb:g} MiB limit "
                        f"(max_file_mb)")
    if st.st_size == 0:
        raise ItemError(f"{path}: empty file (0 bytes)")


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
