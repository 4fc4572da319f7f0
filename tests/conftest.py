"""Shared test fixtures."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

import usd_schemas  # noqa: F401  registers the project schema before any test touches the registry

REPO = Path(__file__).resolve().parents[1]
SHARED_ASSETS = Path(os.environ.get("AGENTWORLD_SHARED_ASSETS", REPO.parent / "shared" / "assets"))


@pytest.fixture(scope="session")
def shared_assets() -> Path:
    """The third-party assets folder (../shared/assets); tests that need it skip where it is absent."""
    if not SHARED_ASSETS.is_dir():
        pytest.skip(f"third-party assets not found at {SHARED_ASSETS}")
    return SHARED_ASSETS
