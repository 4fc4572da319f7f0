"""The ``scene`` job kind: planning from earlier steps' results, errors, the tiny job end to end (slow)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

from pipeline.types import PlanContext, PlannedFailure, WorkItem
from stages.scene.job import SceneConfig, SceneGroup, plan_scenes, reason_kind
from stages.layout.job import LayoutResult

ROOT = Path(__file__).resolve().parents[2]


def _layout(tmp: Path, lid: str) -> LayoutResult:
    (tmp / lid).mkdir(parents=True, exist_ok=True)
    for n in ("floorplan.json", "layout.usdc"):
        (tmp / lid / n).write_text("x")
    return LayoutResult(usd=str(tmp / lid / "layout.usdc"), plan=str(tmp / lid / "floorplan.json"), seed=1,
                        floors=1, rooms=1, doors=1, windows=1, score=1.0, attempts=1, seconds={})


def test_plan_items_per_layout_and_population(tmp_path: Path):
    layouts = {k: _layout(tmp_path, k) for k in ("living_000", "living_001", "kitchen_000", "flat_000")}
    cfg = SceneConfig(assets_step="assets", layouts_step="layouts", group=(
        SceneGroup(id="living", layouts=("living_*",), populations=3),
        SceneGroup(id="houses", layouts=("flat_*",), populations=1, rooms=("kitchen",)),
        SceneGroup(id="attic", layouts=("attic_*",))))
    ctx = PlanContext(job_file=tmp_path / "j.toml", job_dir=tmp_path, work_dir=tmp_path / "out", seed=0,
                      previous={"layouts": layouts, "assets": {}})
    items = plan_scenes(cfg, ctx)
    work = [i for i in items if isinstance(i, WorkItem)]
    assert [i.item_id for i in work] == ["living_000_p0", "living_000_p1", "living_000_p2", "living_001_p0",
                                        "living_001_p1", "living_001_p2", "flat_000_p0"]
    assert work[-1].params.rooms == ("kitchen",)
    assert work[0].depends_on == ("layouts/living_000",)
    assert Path(work[0].params.index) == tmp_path / "out" / "catalog.sqlite"
    fails = [i for i in items if isinstance(i, PlannedFailure)]
    assert len(fails) == 1 and "attic" in fails[0].reason
    # a missing earlier step fails every group with the step's name
    bad = plan_scenes(cfg, PlanContext(job_file=tmp_path / "j.toml", job_dir=tmp_path, work_dir=tmp_path, seed=0))
    assert all(isinstance(i, PlannedFailure) and "layouts" in i.reason for i in bad)


def test_reason_kinds():
    assert reason_kind("placement: f0_kitchen_1: could not place required fridge (fridge: outside the room)") == \
        "placement: could not place required fridge"
    assert reason_kind("settle: still moving after 2 repairs: x 1.2 cm") == "settle"
    assert reason_kind("placement: f0_kitchen_1: could not place required fridge (fridge: blocks a window) "
                       "[8 arrangements]") == "placement: could not place required fridge"
    from stages.scene.job import _repair_kind

    assert _repair_kind("dropped alarm_clock_01 (moved 1.6 cm)") == "dropped alarm_clock"


@pytest.mark.slow
@pytest.mark.skipif(importlib.util.find_spec("newton_usd_schemas") is None,
                    reason="Newton's add_usd needs newton-usd-schemas")
def test_tiny_scene_job_end_to_end(tmp_path: Path):
    from pipeline import run_job
    from stages.scene.render import contact_sheet, find_scenes

    summary = run_job(ROOT / "jobs" / "scenes_tiny.toml", out=tmp_path, workers=2, progress=False)
    rep = json.loads((tmp_path / "reports" / "scenes_summary.json").read_text())
    assert rep["scenes_emitted"] == 2 and rep["scenes_failed"] == 0
    for key in ("attempts_rejected_by_reason", "room_arrangements_rejected_by_reason", "settle_repairs_by_reason",
                "failed_items"):
        assert isinstance(rep[key], dict)
    # 0 when every instance of both scenes is proven at rest (stages.scene.rest: nothing simulated)
    assert 0.0 <= rep["settle_simulated_s_median"] <= 2.0
    scenes = find_scenes(tmp_path)
    assert len(scenes) == 2
    png = contact_sheet(scenes, tmp_path / "sheet.png", tile=160)
    from PIL import Image

    im = Image.open(png)
    assert im.size[0] >= 160 and len(set(im.convert("L").getdata())) > 20
    assert summary is not None
