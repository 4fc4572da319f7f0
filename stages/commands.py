"""Extra ``agentworld`` subcommands contributed by stage modules.

``COMMANDS`` maps a subcommand name (e.g. ``"render-layout"``) to ``"module:function"`` where
``function(argv: list[str]) -> int`` parses its own arguments and returns the exit status. The CLI
lists the names in ``--help`` and imports a module only when its subcommand runs. One line per
entry; the built-in names (run, ingest, catalog, status) cannot be overridden.
"""

COMMANDS: dict[str, str] = {
    "render-dataset": "stages.dataset.render:cli",
    "render-layout": "stages.layout.render:cli",
    "catalog-build-default": "asset_catalog.default_catalog:main",
    "render-assets": "stages.render_assets:main",
    "render-scenes": "stages.scene.render:cli",
}
