"""The Ray executor on a real local Ray cluster gives the same outputs as the process pool."""

from __future__ import annotations

import time

import pytest
from pipeline_testutil import text_job, tree_hashes

from pipeline import load_results, run_job

ray = pytest.importorskip("ray")


def test_ray_local_cluster_matches_process_pool(tmp_path, registry, monkeypatch):
    monkeypatch.setenv("RAY_USAGE_STATS_ENABLED", "0")
    job = text_job(tmp_path, n=6, config='bad = ["t04"]')
    pool = run_job(job, out=tmp_path / "pool", executor="local", workers=2, registry=registry, progress=False)
    t0 = time.perf_counter()
    # starts a local cluster with num_cpus=workers (no dashboard) and shuts it down afterwards
    rs = run_job(job, out=tmp_path / "ray", executor="ray", workers=2, registry=registry, progress=False)
    elapsed = time.perf_counter() - t0
    assert not ray.is_initialized()
    assert (rs.done, rs.failed) == (pool.done, pool.failed) == (6, 1)
    assert rs.executor == "ray" and rs.workers == 2
    assert [(f.item_id, f.reason) for f in rs.step("texts").failures] == \
        [(f.item_id, f.reason) for f in pool.step("texts").failures]
    hp, hr = tree_hashes(tmp_path / "pool"), tree_hashes(tmp_path / "ray")
    assert len(hp) == 11 and hp == hr
    assert load_results(tmp_path / "ray", "texts") == load_results(tmp_path / "pool", "texts")
    assert elapsed < 60, f"Ray run took {elapsed:.1f} s"


_CLUSTER = """
import signal, sys, time, ray
ray.init(num_cpus=2, include_dashboard=False)
print(ray.get_runtime_context().gcs_address, flush=True)
signal.signal(signal.SIGTERM, lambda *a: (ray.shutdown(), sys.exit(0)))
while True:
    time.sleep(0.2)
"""


@pytest.mark.slow
def test_cli_connects_to_a_given_cluster(tmp_path):
    """``agentworld run --executor ray --ray-address ADDR``: connect to a running cluster (started by
    another process) and leave it running. Ray >= 2.59 authenticates with a token, read when ray is
    imported: both processes get the same RAY_AUTH_TOKEN in their environment."""
    import secrets
    import subprocess
    import sys

    from pipeline_testutil import subprocess_env

    env = {**subprocess_env(), "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(16)}
    proc = subprocess.Popen([sys.executable, "-c", _CLUSTER], stdout=subprocess.PIPE, text=True, env=env)
    try:
        address = proc.stdout.readline().strip()
        assert address, "the cluster process printed no address"
        job = text_job(tmp_path, n=3, merge=False, direct=True)
        run = subprocess.run([sys.executable, "-m", "pipeline.cli", "run", str(job), "--executor", "ray",
                              "--ray-address", address, "--no-progress"], env=env, capture_output=True,
                             text=True, timeout=300)
        assert run.returncode == 0, run.stderr[-3000:]
        log = (tmp_path / "out" / "t" / "logs" / "job.log").read_text()
        assert f"connecting to the Ray cluster at {address}" in log
        assert proc.poll() is None                      # the cluster is still up
        assert len(tree_hashes(tmp_path / "out" / "t")) == 6
    finally:
        proc.terminate()
        proc.wait(timeout=60)
