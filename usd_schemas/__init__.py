"""The project's USD layer: its codeless schema, the asset package writer and validation.

Public API::

    register() -> bool                           # schema plugins -> Plug.Registry (idempotent)
    write_asset_package(model, out_dir, *, pipeline_version) -> AssetPackage
    validate_package(path) -> ValidationReport

Importing this package puts the schema plugins on ``PXR_PLUGINPATH_NAME`` (before it imports
pxr), then imports pxr and registers them; a process that used pxr first still works (see
``_registry``). ``pipeline`` never imports this package at top level.
"""

from __future__ import annotations

from usd_schemas._registry import ASSET_API, PLUGIN_DIR, plugin_path_env, register

plugin_path_env()

from usd_schemas._package import AssetPackage, write_asset_package  # noqa: E402  (after the plugin path)
from usd_schemas._validate import ValidationIssue, ValidationReport, validate_package  # noqa: E402

register()

__all__ = [
    "ASSET_API",
    "PLUGIN_DIR",
    "AssetPackage",
    "ValidationIssue",
    "ValidationReport",
    "plugin_path_env",
    "register",
    "validate_package",
    "write_asset_package",
]
