"""One report from per-kitchen ``eval.json`` parts, and an evaluation time limit from the training data.

An evaluation split into one ``agentworld eval`` process per held-out kitchen (the device driver,
``stages/policy/scripts/gpu_policies.py eval``) writes one ``eval.json`` per kitchen;
:func:`merge_reports` sums them into the report one process over all kitchens would have written
(episodes, successes and failure reasons per task, per family and overall; every episode; the
held-out check; network calls), with each part's kitchen, wall time and result under ``parts``.

:func:`typical_seconds` reads a training dataset's episode lengths (``meta/episodes``, the scripted
expert's successful episodes) so that an evaluation can end a failing episode at a multiple of what
the expert needs instead of at the task's time limit.
"""

from __future__ import annotations

import json
import statistics
from collections import Counter
from pathlib import Path

TABLES = ("tasks", "families")


def _sum_tables(rows: list[dict]) -> dict:
    n, ok = sum(r["episodes"] for r in rows), sum(r["successes"] for r in rows)
    fails: Counter = Counter()
    for r in rows:
        fails.update(r.get("failures") or {})
    return {"episodes": n, "successes": ok, "success_rate": round(ok / n, 4) if n else None,
            "failures": dict(sorted(fails.items()))}


def merge_reports(parts: list[dict]) -> dict:
    """The report of all ``parts`` (``eval.json`` dicts of one checkpoint, one or more kitchens
    each): tables summed, episodes and kitchens concatenated in the parts' order, ``wall_seconds``
    the longest part's (they ran at once), ``parts`` one summary per part. Raises ``ValueError`` for
    no parts or parts of different checkpoints."""
    if not parts:
        raise ValueError("eval merge: no eval.json parts to merge")
    ckpts = sorted({str(p.get("checkpoint")) for p in parts})
    if len(ckpts) != 1:
        raise ValueError(f"eval merge: the parts evaluate different checkpoints {ckpts}")
    first = parts[0]
    out = {k: first.get(k) for k in ("checkpoint", "policy", "device", "worlds", "seeds")}
    out["scenes"] = [s for p in parts for s in p.get("scenes", [])]
    held = [p.get("held_out") or {} for p in parts]
    out["held_out"] = {**held[0], "seen_scenes": sorted({s for h in held for s in h.get("seen_scenes", [])}),
                       "checked": all(h.get("checked", False) for h in held)}
    for key in TABLES:
        names = list(dict.fromkeys(n for p in parts for n in p.get(key, {})))
        out[key] = {n: _sum_tables([p[key][n] for p in parts if n in p.get(key, {})]) for n in names}
    out["overall"] = _sum_tables([p["overall"] for p in parts])
    out["episodes"] = [e for p in parts for e in p.get("episodes", [])]
    out["runner"] = {k: sum((p.get("runner") or {}).get(k, 0) for p in parts) for k in ("model_calls", "chunks")}
    out["engine"] = [e for p in parts for e in p.get("engine", [])]
    out["wall_seconds"] = max(float(p.get("wall_seconds", 0.0)) for p in parts)
    out["parts"] = [{"scenes": p.get("scenes", []), "wall_seconds": p.get("wall_seconds"),
                     "episodes": p["overall"]["episodes"], "successes": p["overall"]["successes"]} for p in parts]
    return out


def merge_files(paths: list[Path], out: Path) -> dict:
    """:func:`merge_reports` of the ``eval.json`` files ``paths``, written to ``out``."""
    parts = []
    for p in paths:
        try:
            parts.append(json.loads(Path(p).read_text()))
        except (OSError, json.JSONDecodeError) as e:
            raise ValueError(f"eval merge: {p}: unreadable eval.json ({e})") from None
    report = merge_reports(parts)
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    Path(out).write_text(json.dumps(report, indent=2) + "\n")
    return report


def typical_seconds(dataset: Path, task: str) -> tuple[float, int] | None:
    """(median episode length [s], episodes) of ``task``'s episodes in a LeRobot dataset written by
    the project (lengths from ``meta/episodes``, fps from ``meta/info.json``); None when the dataset
    has no episode of ``task``."""
    from stages.dataset import read_episode_columns

    root = Path(dataset)
    info = root / "meta" / "info.json"
    if not info.is_file():
        return None
    fps = float(json.loads(info.read_text())["fps"])
    lengths = [int(r["length"]) for r in read_episode_columns(root) if r.get("task_kind") == task]
    if not lengths:
        return None
    return statistics.median(lengths) / fps, len(lengths)
