"""``agentworld status``: what a work directory's state database says (works after a crash too)."""

from __future__ import annotations

import sqlite3
import sys
import time
from pathlib import Path

from pipeline._src.report import read_summary
from pipeline._src.runner import STATE_DB


def step_counts(work_dir: Path) -> list[tuple[str, dict[str, int], list[tuple[str, str]]]]:
    """Per step (in first-seen order): {status: count} and [(item_id, error)] of failed items."""
    con = sqlite3.connect(f"file:{Path(work_dir) / STATE_DB}?mode=ro", uri=True)
    try:
        rows = con.execute("SELECT step, status, COUNT(*), MIN(rowid) FROM items GROUP BY step, status "
                           "ORDER BY MIN(rowid)").fetchall()
        fails = con.execute("SELECT step, item_id, error FROM items WHERE status='failed' "
                            "ORDER BY step, item_id").fetchall()
    finally:
        con.close()
    steps: dict[str, dict[str, int]] = {}
    for step, status, n, _ in rows:
        steps.setdefault(step, {})[status] = n
    return [(s, c, [(i, e) for st, i, e in fails if st == s]) for s, c in steps.items()]


def print_status(work_dir: Path, max_failures: int = 50) -> int:
    """Print the item counts per step, the failures and the last run's summary line; exit status."""
    from rich.table import Table
    from rich.text import Text

    from pipeline._src.report import stdout_console

    console = stdout_console()
    db = Path(work_dir) / STATE_DB
    if not db.is_file():
        print(f"agentworld: error: {db}: no state database (nothing has run in {work_dir})", file=sys.stderr)
        return 1
    steps = step_counts(work_dir)
    t = Table(title=Text(f"work dir {Path(work_dir).resolve()}"), title_justify="left")
    for col in ("step", "done", "failed", "interrupted"):
        t.add_column(col, justify="left" if col == "step" else "right")
    for name, counts, _ in steps:
        t.add_row(Text(name), str(counts.get("done", 0)), str(counts.get("failed", 0)),
                  str(counts.get("running", 0)))
    console.print(t)
    failures = [(s, i, e) for s, _, f in steps for i, e in f]
    if failures:
        ft = Table(title=f"{len(failures)} failed item(s)", title_justify="left")
        for col in ("step", "item", "reason"):
            ft.add_column(col, overflow="fold")
        for s, i, e in failures[:max_failures]:
            ft.add_row(Text(s), Text(i), Text(e))
        console.print(ft)
    summary = read_summary(Path(work_dir))
    if summary is not None:
        written = time.ctime((Path(work_dir) / "reports" / "summary.json").stat().st_mtime)
        console.print(Text(f"last run: job {summary.job!r} {summary.status} in {summary.seconds:.2f} s "
                           f"(done {summary.done}, cached {summary.cached}, failed {summary.failed}); "
                           f"summary written {written}"))
    return 0
