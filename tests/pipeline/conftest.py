"""Fixtures of the runner's tests. Helpers live in ``pipeline_testutil``, stage functions and test
job kinds in ``stagefns`` (both importable by worker processes: this folder is put on sys.path)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
for _p in (str(HERE), str(HERE.parents[1])):
    if _p not in sys.path:
        sys.path.insert(0, _p)

import stagefns  # noqa: E402  (needs the path above)


@pytest.fixture
def registry() -> dict[str, str]:
    """The test job kinds (texts, merge, trivial), injected in place of stages.jobkinds.JOB_KINDS."""
    return dict(stagefns.REGISTRY)
