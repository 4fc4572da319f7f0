"""The project's USD layer: its codeless schema, the asset package writer and validation.

Public API::

    register()                                   # schema plugin -> Plug.Registry (idempotent)
    write_asset_package(model, out_dir, *, pipeline_version) -> AssetPackage
    validate_package(path) -> ValidationReport

Importing this package imports pxr and registers the AgentWorld schema plugin, so that it is
registered before anything in the process first uses the USD schema registry. ``pipeline`` never
imports this package at top level.
"""

from __future__ import annotations

from usd_schemas._package import AssetPackage, write_asset_package
from usd_schemas._registry import ASSET_API, PLUGIN_DIR, register
from usd_schemas._validate import ValidationIssue, ValidationReport, validate_package

register()

__all__ = [
    "ASSET_API",
    "PLUGIN_DIR",
    "AssetPackage",
    "ValidationIssue",
    "ValidationReport",
    "register",
    "validate_package",
    "write_asset_package",
]
