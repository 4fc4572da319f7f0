"""Registration of the project's codeless schema plugin with USD's plugin registry.

``register()`` must run before anything first uses ``Usd.SchemaRegistry`` in the process (opening a
stage does): the schema registry reads the plugins' ``generatedSchema.usda`` once. Every public
function of ``usd_schemas`` calls it first. A process that uses the schema without importing this
package (usdview, another tool) can find it through the environment instead:

    export PXR_PLUGINPATH_NAME=<repo>/usd_schemas/agentworld${PXR_PLUGINPATH_NAME:+:$PXR_PLUGINPATH_NAME}
"""

from __future__ import annotations

import logging
import threading
from pathlib import Path

log = logging.getLogger(__name__)

PLUGIN_DIR = Path(__file__).resolve().parent / "agentworld"
PLUGIN_NAME = "agentWorld"
ASSET_API = "AgentWorldAssetAPI"

_lock = threading.Lock()
_registered = False


def register() -> None:
    """Register the AgentWorld schema plugin (idempotent, thread-safe).

    Raises RuntimeError if the plugin cannot be registered or its AgentWorldAssetAPI does not
    reach the schema registry (e.g. the schema registry was built before registration).
    """
    global _registered
    if _registered:
        return
    with _lock:
        if _registered:
            return
        from pxr import Plug, Usd

        reg = Plug.Registry()
        if reg.GetPluginWithName(PLUGIN_NAME) is None:
            reg.RegisterPlugins(str(PLUGIN_DIR))
        _register_companions()
        plugin = reg.GetPluginWithName(PLUGIN_NAME)
        if plugin is None:
            raise RuntimeError(f"{PLUGIN_DIR / 'plugInfo.json'}: USD did not register plugin {PLUGIN_NAME!r}")
        if Usd.SchemaRegistry().FindAppliedAPIPrimDefinition(ASSET_API) is None:
            raise RuntimeError(
                f"{PLUGIN_DIR}: {ASSET_API} is not in the USD schema registry; register() must run "
                "before the schema registry is first used (or set PXR_PLUGINPATH_NAME)"
            )
        log.debug("registered USD plugin %s from %s", PLUGIN_NAME, plugin.path)
        _registered = True


def _register_companions() -> None:
    """Register Newton's schema plugin too, if installed, before this module first builds the
    schema registry (``newton_usd_schemas`` registers itself on import and must come first, or
    Newton's importer later finds no Newton schemas)."""
    import importlib.util

    if importlib.util.find_spec("newton_usd_schemas") is not None:
        import newton_usd_schemas  # noqa: F401
    else:
        log.debug("newton_usd_schemas not installed; Newton's add_usd will refuse to load USD")
