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


def test_the_video_keyframe_interval_reaches_the_dataset_spec():
    """``video_gop`` of a demos step: the engine's dataset spec encodes the RGB videos with it (30 by
    default: the datasets written so far are unchanged)."""
    import pytest
    from pydantic import ValidationError

    from stages.demos.job import DemosConfig
    from stages.engine.engine import EngineConfig

    assert DemosConfig().video_gop == 30 and EngineConfig().dataset_spec().video.gop == 30
    assert EngineConfig(video_gop=2, record_depth=False).dataset_spec().video.gop == 2
    with pytest.raises(ValidationError):
        DemosConfig(video_gop=0)
