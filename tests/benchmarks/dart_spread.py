"""How far DART noise moves the recorded state off the noise-free path: two ``demos`` steps of one
job, the same tasks, kitchens and episode seeds, one without and one with ``action_noise``
(:mod:`stages.engine.action_noise`), compared episode by episode (by seed; episodes that succeeded
in both).

Per task: success counts of both steps (their reports), and over the matched episodes
- base path deviation [m]: each noisy frame's base (x, y) to the nearest point of the clean
  episode's base path (mean per episode, then median over episodes; and the largest);
- base at manipulation [m]: the base position at the first manipulation frame (mode 1), noisy
  minus clean;
- arm |q - target| [rad]: measured arm joints against the recorded (clean) targets, mean over
  manipulation frames, clean and noisy (the noise shows as the difference);
- ee |measured - target| [m]: the end-effector position against the recorded target's, likewise;
- frames: median episode length, clean and noisy.

Run (after a job with steps ``clean`` and ``dart`` ran into OUT with ``merge = false``)::

    .venv/bin/python tests/benchmarks/dart_spread.py OUT --clean clean --noisy dart [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

import numpy as np


def episodes(step_dir: Path) -> dict[tuple[str, int], dict[str, np.ndarray]]:
    """(task, seed) -> state (T, 17) and action (T, 19) of every written episode under ``step_dir``
    (the items' ``dataset_w*`` shards)."""
    import pandas as pd

    out = {}
    for shard in sorted(step_dir.glob("*/dataset_w*")):
        metas = sorted((shard / "meta" / "episodes").rglob("*.parquet"))
        meta = pd.concat([pd.read_parquet(p) for p in metas])
        data = pd.concat([pd.read_parquet(p) for p in sorted((shard / "data").rglob("*.parquet"))])
        for _, m in meta.iterrows():
            rows = data[data["episode_index"] == m["episode_index"]].sort_values("frame_index")
            out[(m["agentworld/task_kind"], int(m["agentworld/seed"]))] = {
                "state": np.stack(rows["observation.state"].to_numpy()).astype(float),
                "action": np.stack(rows["action"].to_numpy()).astype(float)}
    return out


def _path_distance(points: np.ndarray, path: np.ndarray) -> np.ndarray:
    """Distance of each point (N, 2) to the polyline ``path`` (M, 2) [m]."""
    a, b = path[:-1], path[1:]
    ab = b - a
    L = np.maximum((ab * ab).sum(1), 1e-12)
    t = np.clip(((points[:, None, :] - a[None]) * ab[None]).sum(2) / L[None], 0.0, 1.0)
    near = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(points[:, None, :] - near, axis=2).min(1)


def compare(clean: dict, noisy: dict) -> dict[str, dict]:
    """Per task: the measures of the module docstring over the episodes (task, seed) in both."""
    per: dict[str, dict[str, list]] = {}
    for key in sorted(set(clean) & set(noisy)):
        c, n = clean[key], noisy[key]
        r = per.setdefault(key[0], {k: [] for k in ("dev_mean", "dev_max", "base_at_manip", "arm_c", "arm_n",
                                                   "ee_c", "ee_n", "len_c", "len_n")})
        dev = _path_distance(n["state"][:, 14:16], c["state"][:, 14:16])
        r["dev_mean"].append(float(dev.mean()))
        r["dev_max"].append(float(dev.max()))
        first = [int(np.argmax(e["action"][:, 18] == 1)) for e in (c, n)]
        at = n["state"][first[1], 14:16] - c["state"][first[0], 14:16]
        r["base_at_manip"].append(float(np.linalg.norm(at)))
        for e, tag in ((c, "c"), (n, "n")):
            m = e["action"][:, 18] == 1
            r[f"arm_{tag}"].append(float(np.abs(e["state"][m, :7] - e["action"][m, :7]).mean()))
            ee = np.linalg.norm(e["state"][m, 7:10] - e["action"][m, 7:10], axis=1)
            r[f"ee_{tag}"].append(float(ee.mean()))
            r[f"len_{tag}"].append(len(e["state"]))
    out = {}
    for task, r in per.items():
        med = {k: statistics.median(v) for k, v in r.items()}
        out[task] = {"matched": len(r["dev_mean"]),
                     "base_path_dev_m": {"median_of_means": round(med["dev_mean"], 4),
                                         "median_of_max": round(med["dev_max"], 4),
                                         "max": round(max(r["dev_max"]), 4)},
                     "base_at_manipulation_m": {"median": round(med["base_at_manip"], 4),
                                                "max": round(max(r["base_at_manip"]), 4)},
                     "arm_q_minus_target_rad": {"clean": round(med["arm_c"], 4),
                                                "noisy": round(med["arm_n"], 4)},
                     "ee_minus_target_m": {"clean": round(med["ee_c"], 4), "noisy": round(med["ee_n"], 4)},
                     "median_frames": {"clean": med["len_c"], "noisy": med["len_n"]}}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", type=Path, help="the job's work dir")
    ap.add_argument("--clean", default="clean", help="the demos step without noise")
    ap.add_argument("--noisy", default="dart", help="the demos step with action_noise")
    ap.add_argument("--json", type=Path, help="write the result here too")
    a = ap.parse_args()
    res: dict = {"tasks": compare(episodes(a.out / a.clean), episodes(a.out / a.noisy))}
    for name in (a.clean, a.noisy):
        rep = json.loads((a.out / "reports" / f"{name}.json").read_text(encoding="utf-8"))
        res[name] = {t: {"successes": v["successes"], "attempts": v["attempts"], "failures": v["failures"]}
                     for t, v in rep["tasks"].items()}
    print(json.dumps(res, indent=1))
    if a.json:
        a.json.write_text(json.dumps(res, indent=1) + "\n", encoding="utf-8")


if __name__ == "__main__":
    main()
