"""Registration of the project's codeless schema plugin (and Newton's) with USD's plugin registry.

USD builds its schema registry once per process, from the plugins registered at that moment (the
first ``Usd.Stage.Open`` does it). So that import order never matters:

- ``plugin_path_env()`` puts this plugin and ``newton_usd_schemas`` on ``PXR_PLUGINPATH_NAME`` in
  ``os.environ`` without importing pxr. ``usd_schemas`` does it on import, before it imports pxr,
  so pxr finds both plugins when it starts, and so does every process started from this one (the
  process pool's workers, Ray workers, usdview). A shell can do the same:

      export PXR_PLUGINPATH_NAME=<repo>/usd_schemas/agentworld${PXR_PLUGINPATH_NAME:+:$PXR_PLUGINPATH_NAME}

- ``register()`` registers both plugins with ``Plug.Registry`` (idempotent, thread-safe). Where the
  schema registry was already built without them (a script opened a stage with pxr before
  importing anything of ours), it logs one warning and carries on: the schemas' fallback values
  and ``CanApplyAPI`` are then missing in that process, but nothing here needs them. The package
  writer authors every schema attribute and the ``apiSchemas`` list op through Sdf, and the
  validators and Newton's importer read authored values, so packages written, validated and
  simulated in such a process are the same (``tests/usd_schemas/test_schema.py`` checks it).
"""

from __future__ import annotations

import importlib.util
import logging
import os
import threading
from pathlib import Path

log = logging.getLogger(__name__)

PLUGIN_DIR = Path(__file__).resolve().parent / "agentworld"
PLUGIN_NAME = "agentWorld"
ASSET_API = "AgentWorldAssetAPI"
PLUGIN_PATH_VAR = "PXR_PLUGINPATH_NAME"

_lock = threading.Lock()
_registered: bool | None = None   # None: not yet; True: in the schema registry; False: built too early


def plugin_dirs() -> list[Path]:
    """The plugin folders USD needs for our packages: this schema's and, if installed, Newton's
    (found without importing it, since ``newton_usd_schemas`` imports pxr)."""
    dirs = [PLUGIN_DIR]
    spec = importlib.util.find_spec("newton_usd_schemas")
    if spec is not None and spec.submodule_search_locations:
        dirs.append(Path(next(iter(spec.submodule_search_locations))).resolve())
    return dirs


def plugin_path_env() -> str:
    """Add ``plugin_dirs()`` to ``PXR_PLUGINPATH_NAME`` in ``os.environ`` (in front, once each) and
    return its new value. Imports no pxr; takes effect for pxr if pxr is not imported yet, and for
    every process started afterwards."""
    current = [p for p in os.environ.get(PLUGIN_PATH_VAR, "").split(os.pathsep) if p]
    ours = [str(d) for d in plugin_dirs() if str(d) not in current]
    value = os.pathsep.join(ours + current)
    os.environ[PLUGIN_PATH_VAR] = value
    return value


def register() -> bool:
    """Register the AgentWorld (and Newton's) schema plugin with USD (idempotent, thread-safe).

    Returns True if ``AgentWorldAssetAPI`` is in the USD schema registry, False if that registry
    was built before the plugin was registered (one warning; see the module docstring). Raises
    RuntimeError if USD cannot register the plugin at all (a broken ``plugInfo.json``).
    """
    global _registered
    if _registered is not None:
        return _registered
    with _lock:
        if _registered is not None:
            return _registered
        from pxr import Plug, Usd

        reg = Plug.Registry()
        if reg.GetPluginWithName(PLUGIN_NAME) is None:
            reg.RegisterPlugins(str(PLUGIN_DIR))
        _register_companions()
        plugin = reg.GetPluginWithName(PLUGIN_NAME)
        if plugin is None:
            raise RuntimeError(f"{PLUGIN_DIR / 'plugInfo.json'}: USD did not register plugin {PLUGIN_NAME!r}")
        _registered = Usd.SchemaRegistry().FindAppliedAPIPrimDefinition(ASSET_API) is not None
        if _registered:
            log.debug("registered USD plugin %s from %s", PLUGIN_NAME, plugin.path)
        else:
            log.warning(
                "%s: %s is not in USD's schema registry: pxr built it before usd_schemas was imported; "
                "schema fallbacks and CanApplyAPI are missing in this process (packages are written, "
                "validated and simulated the same). Import usd_schemas before pxr, or set %s=%s",
                PLUGIN_DIR, ASSET_API, PLUGIN_PATH_VAR, os.pathsep.join(map(str, plugin_dirs())))
        return _registered


def _register_companions() -> None:
    """Register Newton's schema plugin too, if installed (``newton_usd_schemas`` registers itself on
    import; Newton's importer needs it)."""
    if importlib.util.find_spec("newton_usd_schemas") is not None:
        import newton_usd_schemas  # noqa: F401
    else:
        log.debug("newton_usd_schemas not installed; Newton's add_usd will refuse to load USD")
