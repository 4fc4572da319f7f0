"""Helpers of the runner's tests: a folder of text files, job files, output-tree hashing."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path


HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]

WORDS = "alpha beta gamma delta epsilon zeta eta theta iota kappa lambda mu nu xi omicron pi rho".split()


def write_texts(folder: Path, n: int) -> list[str]:
    """n text files t00.txt ... with varied content; returns their item ids."""
    folder.mkdir(parents=True, exist_ok=True)
    ids = []
    for i in range(n):
        words = [WORDS[(i * 7 + k * 3) % len(WORDS)] for k in range(5 + 3 * i)]
        (folder / f"t{i:02d}.txt").write_text(" ".join(words) + "\n", encoding="utf-8")
        ids.append(f"t{i:02d}")
    return ids


def write_job(path: Path, body: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(body, encoding="utf-8")
    return path


def text_job(root: Path, *, n: int = 6, out: str = "out/t", workers: int = 2, retries: int = 1, seed: int = 7,
             executor: str = "local", config: str = "", merge: bool = True, direct: bool = False) -> Path:
    """A job file ``<root>/jobs/t.toml`` over ``<root>/data`` (n text files) with a texts step and
    (optionally) a merge step. direct=True names the kinds as "stagefns:..." (no registry needed)."""
    if not (root / "data").exists():
        write_texts(root / "data", n)
    texts_kind = "stagefns:TEXT_KIND" if direct else "texts"
    merge_kind = "stagefns:MERGE_KIND" if direct else "merge"
    body = f"""
[job]
name = "t"
seed = {seed}
out = "{out}"
executor = "{executor}"
workers = {workers}
retries = {retries}

[[step]]
name = "texts"
kind = "{texts_kind}"
[step.config]
folder = "data"
{config}
"""
    if merge:
        body += f'\n[[step]]\nname = "merged"\nkind = "{merge_kind}"\n'
    return write_job(root / "jobs" / "t.toml", body)


def tree_hashes(root: Path, steps: tuple[str, ...] = ("texts", "merged")) -> dict[str, str]:
    """{relative path: sha256} of every file under the given step folders of a work dir."""
    out = {}
    for step in steps:
        base = root / step
        if not base.exists():
            continue
        for f in sorted(base.rglob("*")):
            if f.is_file():
                out[f.relative_to(root).as_posix()] = hashlib.sha256(f.read_bytes()).hexdigest()
    return out


def subprocess_env() -> dict[str, str]:
    """Environment for a child python that must import pipeline and stagefns."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), str(HERE), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    return env
