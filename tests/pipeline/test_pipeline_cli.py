"""The ``agentworld`` command: start-up weight, run / status / catalog / ingest / extra subcommands."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from pipeline_testutil import REPO, subprocess_env, text_job

from asset_catalog.index import CatalogRecord, write_index
from pipeline import cli

HEAVY = ("pxr", "warp", "torch", "newton", "mujoco", "coacd", "ray", "trimesh")


def _py(code: str, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], env=subprocess_env(), capture_output=True, text=True,
                          cwd=cwd or REPO, timeout=120)


def test_import_pipeline_and_cli_loads_no_heavy_module():
    code = f"""
import sys, pipeline, pipeline.cli, pipeline.types
from pipeline import run_job, load_job, JobSpec, JobSummary, ItemContext, WorkItem, JobKind  # resolves lazy names
try:
    pipeline.cli.main(["--help"])
except SystemExit:
    pass
print(sorted(m for m in {HEAVY!r} if m in sys.modules))
"""
    r = _py(code)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip().splitlines()[-1] == "[]"
    assert "run" in r.stdout and "catalog" in r.stdout and "status" in r.stdout


def _cli(*args: str, cwd) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "pipeline.cli", *args], env=subprocess_env(), cwd=cwd,
                          capture_output=True, text=True, timeout=300)


def test_run_status_and_strict_exit_codes(tmp_path):
    job = text_job(tmp_path, n=4, config='bad = ["t02"]', direct=True)
    r = _cli("run", str(job), "--executor", "inline", "--no-progress", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "done" in r.stdout and "cached" in r.stdout and "failed" in r.stdout
    assert "t02" in r.stdout and "content is not acceptable" in r.stdout   # failure reason in the summary
    summary = json.loads((tmp_path / "out" / "t" / "reports" / "summary.json").read_text())
    assert summary["totals"] == {"done": 4, "cached": 0, "failed": 1}
    r = _cli("run", str(job), "--strict", "--no-progress", "--out", "out/t", cwd=tmp_path)
    assert r.returncode == 3
    summary = json.loads((tmp_path / "out" / "t" / "reports" / "summary.json").read_text())
    assert summary["totals"] == {"done": 0, "cached": 4, "failed": 1}
    r = _cli("status", "--out", "out/t", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "texts" in r.stdout and "merged" in r.stdout and "t02" in r.stdout and "last run" in r.stdout


def test_invalid_job_is_a_one_line_error(tmp_path):
    job = text_job(tmp_path, n=1, direct=True)
    job.write_text(job.read_text().replace("retries = 1", 'retries = "many"'))
    r = _cli("run", str(job), cwd=tmp_path)
    assert r.returncode == 1
    err = r.stderr.strip()
    assert err.startswith(f"agentworld: error: {job}: job.retries:") and "\n" not in err


def test_status_of_an_empty_dir(tmp_path):
    r = _cli("status", "--out", str(tmp_path), cwd=tmp_path)
    assert r.returncode == 1 and "no state database" in r.stderr


def test_ingest_short_form_builds_a_one_step_job(tmp_path):
    (tmp_path / "cat").mkdir()
    data = cli.ingest_job_data(tmp_path / "cat", None, out=tmp_path / "o")
    assert data == {"job": {"name": "ingest", "seed": 0, "out": str(tmp_path / "o")},
                    "step": [{"name": "assets", "kind": "ingest", "config": {"catalog": str(tmp_path / "cat")}}]}
    ann = tmp_path / "a.toml"
    assert cli.ingest_job_data(tmp_path / "cat", ann)["step"][0]["config"]["annotations"] == str(ann)
    r = _cli("ingest", str(tmp_path / "missing"), "--out", str(tmp_path / "o"), cwd=tmp_path)
    assert r.returncode == 1 and r.stderr.startswith("agentworld: error: agentworld ingest: step 'assets'")


def _records() -> list[CatalogRecord]:
    return [
        CatalogRecord(id="mug_01", category="mug", room_types=("kitchen",), placement="on_surface",
                      material="ceramic", interactable=True, usd_path="assets/mug_01/mug_01.usda",
                      dimensions=(0.1, 0.08, 0.1), mass=0.3, collider="convexDecomposition", n_colliders=6),
        CatalogRecord(id="sofa_01", category="sofa", room_types=("living_room",), placement="against_wall",
                      material="fabric", dimensions=(2.0, 0.9, 0.8), mass=40.0, collider="convexHull",
                      n_colliders=1),
        CatalogRecord(id="mug_bad", category="mug", room_types=("kitchen",), status="failed",
                      error="mugs/bad.obj: mesh has NaN vertices"),
    ]


def test_catalog_list(tmp_path):
    write_index(tmp_path / "w" / "catalog.sqlite", _records())
    r = _cli("catalog", "list", "--category", "mug", "--room", "kitchen", "--work-dir", "w", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "mug_01" in r.stdout and "sofa_01" not in r.stdout and "mug_bad" not in r.stdout
    r = _cli("catalog", "list", "--status", "all", "--json", "--work-dir", "w", cwd=tmp_path)
    ids = [json.loads(line)["id"] for line in r.stdout.splitlines()]
    assert ids == ["mug_01", "mug_bad", "sofa_01"]
    r = _cli("catalog", "list", "--work-dir", "nowhere", cwd=tmp_path)
    assert r.returncode == 1 and "no catalog index" in r.stderr


def test_extra_subcommands_are_listed_and_dispatched(monkeypatch, capsys):
    import stages.commands

    monkeypatch.setitem(stages.commands.COMMANDS, "echo-test", ("stagefns:echo_command", "print the arguments"))
    assert cli.main(["echo-test", "a", "b"]) == 2
    assert "echo: a b" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    out = capsys.readouterr().out
    assert "echo-test" in out and "print the arguments" in out


def test_help_describes_every_command_once(capsys):
    """Every command has a one-line description (not its Python location), and each is listed once:
    ``catalog build-default`` has no second spelling (the old ``catalog-build-default`` still runs)."""
    import stages.commands

    with pytest.raises(SystemExit) as e:
        cli.main(["--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert "(from " not in out and ":main" not in out and ":cli" not in out
    assert "catalog-build-default" not in out and "build-default" in out
    import re

    listed = out.split("positional arguments:")[1].split("options:")[0].splitlines()
    rows = [(i, m.group(1), m.group(2)) for i, ln in enumerate(listed)
            if (m := re.match(r"^    ([a-z][\w-]*)(?:\s{2,}(\S.*))?$", ln))]
    names = [name for _, name, _ in rows]
    assert sorted(names) == sorted(["run", "ingest", "catalog", "status", *stages.commands.COMMANDS])
    row_lines = {i for i, _, _ in rows}
    for i, name, desc in rows:    # the description on the same line or, for long names, the next
        if desc is None:
            assert i + 1 not in row_lines, f"{name} has no description"
            desc = listed[i + 1].strip()
        assert len(desc) > 10, name
    for ref, help_text in stages.commands.COMMANDS.values():
        assert ":" in ref and len(help_text) > 20
    with pytest.raises(SystemExit) as e:
        cli.main(["catalog-build-default", "--help"])
    assert e.value.code == 0 and "agentworld catalog build-default" in capsys.readouterr().out


def test_console_shows_progress_and_summary_and_job_log_keeps_chatter_once(tmp_path):
    """Items that print Warp's banner and module-load lines, warn, log through a library logger,
    print and write to fd 2: the console has none of it (only the summary), logs/job.log has each
    distinct line once (our own records every time)."""
    job = tmp_path / "chatty.toml"
    job.write_text('[job]\nname = "chatty"\nout = "out"\nexecutor = "local"\nworkers = 2\n\n'
                   '[[step]]\nname = "chat"\nkind = "chattyfns:CHATTY_KIND"\n[step.config]\nn = 4\n')
    r = _cli("run", str(job), "--no-progress", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    console = r.stdout + r.stderr
    for needle in ("Warp ", "Module ", "Warning", "warning", "third-party", "native write"):
        assert needle not in console, (needle, console)
    assert "chat" in r.stdout and "done" in r.stdout     # the summary table
    text = (tmp_path / "out" / "logs" / "job.log").read_text()
    lines = text.splitlines()

    def count(needle: str) -> int:
        return sum(needle in ln for ln in lines)

    assert count("initialized:") == 1 and count("Devices:") == 1      # Warp's banner, once
    assert count("Warp CUDA warning") <= 1                            # on a machine without a GPU
    modules = [ln.split("Module ", 1)[1].split(" load")[0] for ln in lines if "Module " in ln]
    assert modules and len(modules) == len(set(modules))              # each kernel module once
    assert count("ChattyWarning: a third-party warning") == 1
    assert count("a third-party logger warning") == 1                 # numbers do not count
    assert count("a third-party print from item") == 1
    assert count("a native write to stderr") == 1
    assert count("chatty item") == 4                                  # ours: every record
