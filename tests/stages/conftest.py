"""Fixtures shared by the stage tests."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def teleop_world(tmp_path_factory):
    """The teleop kitchen (world seed 5), built once per test session (about 20 s on 2 cores)."""
    pytest.importorskip("newton")
    pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")
    from stages.teleop.world import teleop_kitchen

    return teleop_kitchen(tmp_path_factory.mktemp("teleop_world"), world_seed=5)
