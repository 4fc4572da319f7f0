"""Source-format loaders: each turns one source file into an ``asset_catalog.asset_model.AssetModel``."""
