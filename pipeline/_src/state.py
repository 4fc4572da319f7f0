"""The work directory's state database ``<out>/state.sqlite`` (SQLite, WAL; one writer: the main process).

Tables:

- ``items``: one row per (step, item_id): cache key, status (``running`` while it is being computed,
  ``done``, ``failed``), how the last run ended for it (``outcome``: done / cached / failed), error
  (one line) and traceback, attempts, timestamps [s since epoch], duration_s (compute time in the
  worker) [s], the result as JSON and its type (``"module:QualName"``), the run that last touched it;
- ``runs``: one row per run of the job, with its summary JSON when it finished;
- ``file_hashes``: sha256 of input files, keyed by (path, size, mtime_ns), so that a re-run does not
  read unchanged inputs again.

The write-ahead rule that makes ``kill -9`` safe: an item is marked ``running`` (which invalidates
an earlier ``done``) before its outputs are moved into place, and ``done`` only after the move.
"""

from __future__ import annotations

import sqlite3
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

SCHEMA_VERSION = 1


class StateVersionError(RuntimeError):
    """The work dir's state database was written by an incompatible runner version."""


_SCHEMA = """
CREATE TABLE IF NOT EXISTS items (
    step TEXT NOT NULL,
    item_id TEXT NOT NULL,
    key TEXT NOT NULL,
    fn TEXT NOT NULL DEFAULT '',
    status TEXT NOT NULL,
    outcome TEXT NOT NULL DEFAULT '',
    error TEXT NOT NULL DEFAULT '',
    error_kind TEXT NOT NULL DEFAULT '',
    traceback TEXT NOT NULL DEFAULT '',
    attempts INTEGER NOT NULL DEFAULT 0,
    started_at REAL,
    finished_at REAL,
    duration_s REAL,
    result_json TEXT,
    result_type TEXT NOT NULL DEFAULT '',
    run_id INTEGER,
    PRIMARY KEY (step, item_id)
);
CREATE TABLE IF NOT EXISTS runs (
    run_id INTEGER PRIMARY KEY AUTOINCREMENT,
    job_name TEXT NOT NULL,
    started_at REAL NOT NULL,
    finished_at REAL,
    status TEXT NOT NULL,
    summary_json TEXT
);
CREATE TABLE IF NOT EXISTS file_hashes (
    path TEXT PRIMARY KEY,
    size INTEGER NOT NULL,
    mtime_ns INTEGER NOT NULL,
    sha256 TEXT NOT NULL
);
"""


@dataclass(frozen=True)
class ItemRow:
    """What the database remembers of one item."""

    step: str
    item_id: str
    key: str
    status: str
    outcome: str
    error: str
    error_kind: str
    attempts: int
    duration_s: float | None
    result_json: str | None
    result_type: str


class StateDB:
    """Open (and create) the state database of a work directory. Use as a context manager."""

    def __init__(self, path: Path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._con = sqlite3.connect(self.path, timeout=30.0, isolation_level=None)
        version = self._con.execute("PRAGMA user_version").fetchone()[0]
        if version not in (0, SCHEMA_VERSION):
            self._con.close()
            raise StateVersionError(f"{self.path}: state database has schema version {version}, this runner "
                                    f"uses {SCHEMA_VERSION}; use another --out or delete the work dir")
        self._con.execute("PRAGMA journal_mode=WAL")
        self._con.execute("PRAGMA synchronous=NORMAL")
        self._con.executescript(_SCHEMA)
        self._con.execute(f"PRAGMA user_version={SCHEMA_VERSION}")

    def close(self) -> None:
        self._con.close()

    def __enter__(self) -> "StateDB":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- runs ---------------------------------------------------------------------------------------

    def begin_run(self, job_name: str) -> int:
        cur = self._con.execute("INSERT INTO runs (job_name, started_at, status) VALUES (?, ?, 'running')",
                                (job_name, time.time()))
        return int(cur.lastrowid)

    def end_run(self, run_id: int, status: str, summary_json: str) -> None:
        self._con.execute("UPDATE runs SET finished_at=?, status=?, summary_json=? WHERE run_id=?",
                          (time.time(), status, summary_json, run_id))

    def last_run(self) -> tuple[int, str, float, float | None, str, str | None] | None:
        """(run_id, job_name, started_at, finished_at, status, summary_json) of the latest run."""
        return self._con.execute("SELECT run_id, job_name, started_at, finished_at, status, summary_json "
                                 "FROM runs ORDER BY run_id DESC LIMIT 1").fetchone()

    # -- items --------------------------------------------------------------------------------------

    def items(self, step: str | None = None) -> dict[tuple[str, str], ItemRow]:
        """All rows (of one step), keyed by (step, item_id)."""
        sql = ("SELECT step, item_id, key, status, outcome, error, error_kind, attempts, duration_s, "
               "result_json, result_type FROM items")
        rows = self._con.execute(sql + (" WHERE step=?" if step else ""), (step,) if step else ())
        return {(r[0], r[1]): ItemRow(*r) for r in rows}

    def mark_running(self, step: str, entries: Iterable[tuple[str, str, str]], run_id: int) -> None:
        """Mark (item_id, key, fn) entries as running, in one transaction (before any output moves)."""
        now = time.time()
        with self.transaction():
            self._con.executemany(
                "INSERT INTO items (step, item_id, key, fn, status, outcome, error, traceback, attempts, "
                "started_at, run_id) VALUES (?, ?, ?, ?, 'running', '', '', '', 0, ?, ?) "
                "ON CONFLICT(step, item_id) DO UPDATE SET key=excluded.key, fn=excluded.fn, "
                "status='running', outcome='', error='', error_kind='', traceback='', attempts=0, "
                "started_at=excluded.started_at, finished_at=NULL, run_id=excluded.run_id",
                [(step, iid, key, fn, now, run_id) for iid, key, fn in entries])

    def mark_done(self, step: str, item_id: str, *, key: str, attempts: int, duration_s: float,
                  result_json: str, result_type: str, run_id: int) -> None:
        self._con.execute(
            "UPDATE items SET key=?, status='done', outcome='done', error='', error_kind='', traceback='', "
            "attempts=?, finished_at=?, duration_s=?, result_json=?, result_type=?, run_id=? "
            "WHERE step=? AND item_id=?",
            (key, attempts, time.time(), duration_s, result_json, result_type, run_id, step, item_id))

    def mark_cached(self, step: str, item_ids: Iterable[str], run_id: int) -> None:
        """Record that these items' stored outcome (done, or a failed ItemError) was reused by run_id."""
        with self.transaction():
            self._con.executemany("UPDATE items SET outcome=CASE status WHEN 'done' THEN 'cached' "
                                  "ELSE 'failed_cached' END, run_id=? WHERE step=? AND item_id=?",
                                  [(run_id, step, iid) for iid in item_ids])

    def mark_failed(self, step: str, item_id: str, *, key: str, fn: str, error: str, error_kind: str,
                    traceback: str = "", attempts: int = 0, duration_s: float | None = None,
                    run_id: int) -> None:
        """error_kind: "item" (ItemError: reused while the key is unchanged), "exception" (retried by
        the next run), "planned" (rejected while planning) or "input" (unusable inputs/dependency)."""
        now = time.time()
        self._con.execute(
            "INSERT INTO items (step, item_id, key, fn, status, outcome, error, error_kind, traceback, "
            "attempts, started_at, finished_at, duration_s, result_json, result_type, run_id) "
            "VALUES (?, ?, ?, ?, 'failed', 'failed', ?, ?, ?, ?, ?, ?, ?, NULL, '', ?) "
            "ON CONFLICT(step, item_id) DO UPDATE SET key=excluded.key, fn=excluded.fn, status='failed', "
            "outcome='failed', error=excluded.error, error_kind=excluded.error_kind, "
            "traceback=excluded.traceback, attempts=excluded.attempts, finished_at=excluded.finished_at, "
            "duration_s=excluded.duration_s, result_json=NULL, result_type='', run_id=excluded.run_id",
            (step, item_id, key, fn, error, error_kind, traceback, attempts, now, now, duration_s, run_id))

    # -- input file hashes --------------------------------------------------------------------------

    def known_hash(self, path: str, size: int, mtime_ns: int) -> str | None:
        row = self._con.execute("SELECT sha256 FROM file_hashes WHERE path=? AND size=? AND mtime_ns=?",
                                (path, size, mtime_ns)).fetchone()
        return row[0] if row else None

    def remember_hash(self, path: str, size: int, mtime_ns: int, sha: str) -> None:
        self._con.execute("INSERT OR REPLACE INTO file_hashes (path, size, mtime_ns, sha256) "
                          "VALUES (?, ?, ?, ?)", (path, size, mtime_ns, sha))

    def transaction(self) -> "_Tx":
        """A context manager grouping writes into one transaction (BEGIN IMMEDIATE ... COMMIT)."""
        return _Tx(self._con)


class _Tx:
    def __init__(self, con: sqlite3.Connection):
        self._con = con

    def __enter__(self) -> None:
        self._con.execute("BEGIN IMMEDIATE")

    def __exit__(self, exc_type: object, *rest: object) -> None:
        self._con.execute("COMMIT" if exc_type is None else "ROLLBACK")
