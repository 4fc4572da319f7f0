"""Every job file the repository ships under ``jobs/`` loads and validates (each step's config with
the real stage registry, paths resolved against the repository root), so a job named in the README
cannot fail on its first line."""

from __future__ import annotations

from pathlib import Path

import pytest

from pipeline import load_job

JOBS = sorted((Path(__file__).resolve().parents[2] / "jobs").glob("*.toml"))


def test_the_repository_ships_job_files():
    assert len(JOBS) >= 10, JOBS


@pytest.mark.parametrize("path", JOBS, ids=[p.name for p in JOBS])
def test_shipped_job_loads(path):
    job = load_job(path)
    assert job.steps, f"{path.name}: no steps"
    assert len({s.name for s in job.steps}) == len(job.steps)
    assert job.base_dir == path.parent.parent  # jobs/ resolves against the repository root
