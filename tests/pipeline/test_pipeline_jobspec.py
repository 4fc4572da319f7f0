"""Job file validation: every problem names the file and the key."""

from __future__ import annotations

from pathlib import Path

import pytest
from pipeline_testutil import text_job, write_job, write_texts

from pipeline import JobError, build_job, load_job


def _body(job: str = "", config: str = "", kind: str = "texts") -> str:
    return f"""
[job]
name = "t"
{job}
[[step]]
name = "texts"
kind = "{kind}"
[step.config]
folder = "data"
{config}
"""


def test_valid_job_resolves_paths_against_repo_root(tmp_path, registry):
    path = text_job(tmp_path, config='flaky_dir = "scratch/flaky"')
    job = load_job(path, registry=registry)
    assert job.base_dir == tmp_path.resolve()          # jobs/ -> its parent
    assert job.out == (tmp_path / "out" / "t").resolve()
    assert [s.name for s in job.steps] == ["texts", "merged"]
    cfg = job.steps[0].config
    assert cfg.folder == tmp_path.resolve() / "data"
    assert cfg.flaky_dir == tmp_path.resolve() / "scratch" / "flaky"   # must_exist=False: not checked
    assert (job.seed, job.workers, job.retries, job.executor) == (7, 2, 1, "local")


def test_job_outside_jobs_folder_resolves_against_its_own_folder(tmp_path, registry):
    write_texts(tmp_path / "elsewhere" / "data", 2)
    path = write_job(tmp_path / "elsewhere" / "j.toml", _body())
    job = load_job(path, registry=registry)
    assert job.base_dir == (tmp_path / "elsewhere").resolve()
    assert job.steps[0].config.folder == (tmp_path / "elsewhere" / "data").resolve()
    assert job.out == (tmp_path / "elsewhere" / "out" / "t").resolve()   # default out = out/<name>


def _error(tmp_path: Path, body: str, registry) -> str:
    write_texts(tmp_path / "data", 1)
    path = write_job(tmp_path / "jobs" / "bad.toml", body)
    with pytest.raises(JobError) as e:
        load_job(path, registry=registry)
    msg = str(e.value)
    assert msg.startswith(str(path)), msg
    assert "\n" not in msg
    return msg


def test_unknown_key_in_job_table(tmp_path, registry):
    msg = _error(tmp_path, _body(job="wrokers = 2"), registry)
    assert "job.wrokers: unknown key" in msg


def test_unknown_key_in_step_config(tmp_path, registry):
    msg = _error(tmp_path, _body(config='colour = "red"'), registry)
    assert "step 'texts' config.colour: unknown key" in msg


def test_wrong_type(tmp_path, registry):
    msg = _error(tmp_path, _body(job='workers = "two"'), registry)
    assert "job.workers:" in msg and "integer" in msg and "'two'" in msg
    msg = _error(tmp_path, _body(config='sleep_s = "slow"'), registry)
    assert "step 'texts' config.sleep_s:" in msg and "number" in msg


def test_missing_path(tmp_path, registry):
    body = _body().replace('folder = "data"', 'folder = "no/such/folder"')
    msg = _error(tmp_path, body, registry)
    assert "step 'texts' config.folder: path does not exist:" in msg
    assert str(tmp_path / "no" / "such" / "folder") in msg


def test_missing_required_keys_and_all_problems_in_one_message(tmp_path, registry):
    msg = _error(tmp_path, '[job]\nseed = -1\nexecutor = "dask"\n', registry)
    assert "job.name: missing required key" in msg
    assert "job.seed:" in msg and "job.executor:" in msg and "step: missing required key" in msg


def test_unknown_kind_and_duplicate_step(tmp_path, registry):
    body = _body(kind="nope") + '\n[[step]]\nname = "texts"\nkind = "merge"\n'
    msg = _error(tmp_path, body, registry)
    assert "unknown job kind 'nope'" in msg and "known: merge, texts, trivial" in msg
    assert "step[1].name: duplicate step name 'texts'" in msg


def test_reserved_step_name(tmp_path, registry):
    msg = _error(tmp_path, _body().replace('name = "texts"', 'name = "reports"'), registry)
    assert "'reports' is reserved" in msg


def test_direct_kind_reference(tmp_path):
    job = load_job(text_job(tmp_path, direct=True), registry={})
    assert job.steps[0].kind == "stagefns:TEXT_KIND"


def test_not_toml_and_missing_file(tmp_path, registry):
    msg = _error(tmp_path, "[job\nname=", registry)
    assert "not valid TOML" in msg
    with pytest.raises(JobError, match="job file not found"):
        load_job(tmp_path / "jobs" / "absent.toml", registry=registry)


def test_build_job_in_memory(tmp_path, registry):
    write_texts(tmp_path / "data", 1)
    job = build_job({"job": {"name": "x"}, "step": [{"name": "s", "kind": "texts", "config": {"folder": "data"}}]},
                    source="<test>", base_dir=tmp_path, registry=registry)
    assert job.job_file is None and job.steps[0].config.folder == (tmp_path / "data").resolve()
    with pytest.raises(JobError, match=r"^<test>: step 's' config.folder: path does not exist"):
        build_job({"job": {"name": "x"}, "step": [{"name": "s", "kind": "texts", "config": {"folder": "zz"}}]},
                  source="<test>", base_dir=tmp_path, registry=registry)
