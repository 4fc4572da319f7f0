"""Per-pair success table of one or more ``record-table`` runs (:mod:`stages.demos.table_record`),
with the issue's bar: at least ``MIN_RATE`` of a pair's episodes succeed.

Command (``agentworld record-table-summary``)::

    agentworld record-table-summary OUT1 [OUT2 ...] [--json FILE] [--min-rate 0.8] [--check]

reads each ``OUTk/report.json`` (or a report file named directly), sums every pair's attempts,
successes and failure reasons over the runs (e.g. three runs of 10 episodes with seeds 0, 1, 2 of
one pair on the GPU host's cores), prints one line per pair and writes the summary as JSON
(``--json``). An episode seed that two reports both hold for one pair (the same run given twice,
or two runs with the same ``--seed``) is an error: it would count one episode twice. ``--check``:
exit status 1 when a pair is below the bar.

``record-table`` prints the same table at its end and writes it as ``OUT/summary.json``.
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path

MIN_RATE = 0.8  # the bar: at least this share of a pair's episodes succeed


def summarize_runs(runs, *, min_rate: float = MIN_RATE) -> dict:
    """The per-pair summary of ``runs`` ((name, record-table report) pairs, or a dict of them; a
    report as :func:`stages.demos.table_record.record_all` returns it):
    attempts, successes, success_rate, failures by reason, wall seconds per episode, whether the
    pair meets ``min_rate`` and each run's share. Raises ValueError naming the runs when one pair's
    episode seed occurs in two of them."""
    pairs: dict[str, dict] = {}
    seen: dict[tuple[str, int], str] = {}
    dup = []
    for name, rep in runs.items() if isinstance(runs, dict) else runs:
        if not isinstance(rep, dict) or not isinstance(rep.get("pairs"), dict):
            raise ValueError(f"{name}: not a record-table report (no 'pairs')")
        for pair, r in rep["pairs"].items():
            try:
                eps = r.get("episodes", [])
                for e in eps:
                    key = (pair, int(e["seed"]))
                    if key in seen:
                        dup.append(f"{pair} episode seed {key[1]} in {seen[key]} and {name}")
                    seen.setdefault(key, name)
                attempts, wins = int(r["attempts"]), int(r["successes"])
            except (KeyError, TypeError, ValueError) as e:
                raise ValueError(f"{name}: pair {pair}'s report is malformed ({type(e).__name__}: {e})") from None
            p = pairs.setdefault(pair, {"attempts": 0, "successes": 0, "failures": Counter(), "wall": 0.0,
                                        "runs": []})
            p["attempts"] += attempts
            p["successes"] += wins
            p["failures"].update(r.get("failures", {}))
            p["wall"] += sum(float(e.get("wall_seconds", 0.0)) for e in eps)
            p["runs"].append({"run": name, "seed": rep.get("seed"), "attempts": attempts, "successes": wins})
    if dup:
        raise ValueError("record-table-summary: episodes counted twice: " + "; ".join(dup[:3])
                         + (f" (and {len(dup) - 3} more)" if len(dup) > 3 else ""))
    out = {}
    for pair, p in pairs.items():
        n = p["attempts"]
        rate = p["successes"] / n if n else 0.0
        out[pair] = {"attempts": n, "successes": p["successes"], "success_rate": round(rate, 3),
                     "meets_bar": bool(n) and rate >= min_rate, "failures": dict(sorted(p["failures"].items())),
                     "wall_seconds_per_episode": round(p["wall"] / n, 2) if n else None, "runs": p["runs"]}
    return {"min_rate": min_rate, "all_meet_bar": bool(out) and all(p["meets_bar"] for p in out.values()),
            "pairs": out}


def summary_table(summary: dict) -> str:
    """One line per pair: successes / attempts, rate, whether it meets the bar, failure reasons,
    wall seconds per episode."""
    bar = f"{summary['min_rate']:.0%}"
    lines = []
    for pair, r in summary["pairs"].items():
        fails = ", ".join(f"{k} {v}" for k, v in r["failures"].items()) or "-"
        lines.append(f"{pair:26s} {r['successes']:3d}/{r['attempts']:<3d} {r['success_rate']:6.1%} "
                     f"{'ok' if r['meets_bar'] else 'BELOW ' + bar:10s} failures: {fails:30s} "
                     f"{r['wall_seconds_per_episode']} s wall per episode ({len(r['runs'])} run(s))")
    verdict = "every pair" if summary["all_meet_bar"] else "NOT every pair"
    lines.append(f"{verdict} at {bar} or more")
    return "\n".join(lines)


def read_report(path: Path) -> dict:
    """A record-table report from ``path`` (a run's OUT folder or its report.json)."""
    path = Path(path)
    f = path / "report.json" if path.is_dir() else path
    try:
        return json.loads(f.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"{f}: no record-table report") from None
    except json.JSONDecodeError as e:
        raise ValueError(f"{f}: not JSON ({e})") from None


def write_json(path: Path, data: dict) -> Path:
    """Write ``data`` to ``path`` atomically (a temporary name, then renamed)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(data, indent=1))
    tmp.replace(path)
    return path


def cli(argv: list[str]) -> int:
    """``agentworld record-table-summary``: see the module docstring."""
    p = argparse.ArgumentParser(prog="agentworld record-table-summary", description=__doc__.splitlines()[0])
    p.add_argument("runs", type=Path, nargs="+", help="record-table OUT folders (or their report.json)")
    p.add_argument("--json", type=Path, default=None, help="write the summary here")
    p.add_argument("--min-rate", type=float, default=MIN_RATE)
    p.add_argument("--check", action="store_true", help="exit status 1 when a pair is below --min-rate")
    a = p.parse_args(argv)
    if not 0.0 < a.min_rate <= 1.0:
        print(f"error: --min-rate must be in (0, 1], got {a.min_rate}")
        return 2
    try:
        summary = summarize_runs([(str(r), read_report(r)) for r in a.runs], min_rate=a.min_rate)
    except (ValueError, FileNotFoundError) as e:
        print(f"error: {e}")
        return 2
    print(summary_table(summary))
    if a.json:
        print(f"summary: {write_json(a.json, summary)}")
    return 1 if a.check and not summary["all_meet_bar"] else 0


if __name__ == "__main__":
    import sys

    sys.exit(cli(sys.argv[1:]))
