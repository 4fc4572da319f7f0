"""The device driver of issue 17 (stages/policy/scripts/gpu_policies.py): the step budget it derives
from a probe's training curve, and the table it writes from runs' train.json / eval.json."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "stages" / "policy" / "scripts" / "gpu_policies.py"


@pytest.fixture(scope="module")
def driver():
    spec = importlib.util.spec_from_file_location("gpu_policies", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_seconds_per_step_and_start_up_from_a_curve(driver, tmp_path):
    # logged every 10 steps, 0.5 s a step after 40 s of start-up
    rows = ["step,samples,epochs,loss,grad_norm,lr,update_s,data_s,wall_s"]
    rows += [f"{s},{16 * s},0.1,1.0,1.0,1e-5,0.4,0.1,{40 + 0.5 * s:.2f}" for s in (10, 20, 30, 40, 50)]
    (tmp_path / "curve.csv").write_text("\n".join(rows) + "\n")
    per, startup = driver._seconds_per_step(tmp_path)
    assert per == pytest.approx(0.5)
    assert startup == pytest.approx(40.0)
    (tmp_path / "curve.csv").write_text(rows[0] + "\n" + rows[1] + "\n")
    with pytest.raises(RuntimeError, match="fewer than 2 curve rows"):
        driver._seconds_per_step(tmp_path)


def test_table_lists_trained_runs_with_their_held_out_success(driver, tmp_path):
    runs, out = tmp_path / "runs", tmp_path / "out"
    act = runs / "push_pull_act"
    (act / "eval").mkdir(parents=True)
    (act / "train.json").write_text(json.dumps({"steps": 900, "wall_seconds": 812.5, "last_loss": 0.21}))
    (act / "eval" / "eval.json").write_text(json.dumps({"overall": {"episodes": 50, "successes": 31}}))
    (runs / "push_pull_diffusion").mkdir()  # no train.json: its training failed, not in the table
    assert driver.main(["table", "--runs", str(runs), "--out", str(out)]) == 0
    rows = json.loads((out / "table.json").read_text())
    assert rows == [{"family": "push_pull", "task": "push_object", "policy": "act", "paper_act": 0.72,
                     "steps": 900, "train_wall_s": 812.5, "last_loss": 0.21, "episodes": 50, "successes": 31,
                     "success_rate": 0.62}]
    assert "| push_pull | push_object | act | 900 | 812.5 | 31/50 | 0.62 | 0.72 |" in (out / "table.md").read_text()
    assert (out / "push_pull_act_eval.json").is_file()


def test_table_of_no_trained_run_is_written_empty(driver, tmp_path):
    assert driver.main(["table", "--runs", str(tmp_path / "none"), "--out", str(tmp_path / "out")]) == 0
    assert json.loads((tmp_path / "out" / "table.json").read_text()) == []
