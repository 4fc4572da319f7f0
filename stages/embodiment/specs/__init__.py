"""Embodiment specs shipped with the project (TOML; format in ``stages.embodiment.spec``)."""
