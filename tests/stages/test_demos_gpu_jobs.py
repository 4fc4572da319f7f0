"""The GPU success-rate demos jobs parse, run at least 256 engine worlds, and skip the merge."""

from __future__ import annotations


def test_a_success_rate_demos_job_can_skip_the_merge():
    import tomllib
    from pathlib import Path

    from stages.demos.job import DemosConfig

    assert DemosConfig().merge is True
    for name in ("demos_success_gpu.toml", "demos_success_gpu4.toml"):
        job = tomllib.loads((Path(__file__).parents[2] / "jobs" / name).read_text())
        cfg = DemosConfig(**next(s["config"] for s in job["step"] if s["kind"] == "demos"))
        assert cfg.merge is False and cfg.batch_worlds >= 256 and cfg.mixed
