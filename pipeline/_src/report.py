"""The end-of-job summary: what each step did, written to ``<out>/reports/summary.json`` and shown as a
table."""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

SUMMARY_RELPATH = Path("reports") / "summary.json"


@dataclass(frozen=True)
class Failure:
    """One failed item: its id and one-line reason."""

    item_id: str
    reason: str


@dataclass(frozen=True)
class StepSummary:
    """Counts of one step: done (computed this run), cached (reused), failed (of which failed_cached
    were ItemError failures reused from an earlier run, inputs unchanged); seconds: wall time [s] of
    the step including planning and finalize; compute_s: summed worker time of computed items [s]."""

    name: str
    kind: str
    planned: int
    done: int
    cached: int
    failed: int
    seconds: float
    failed_cached: int = 0
    compute_s: float = 0.0
    failures: tuple[Failure, ...] = ()

    @property
    def succeeded(self) -> int:
        return self.done + self.cached


@dataclass(frozen=True)
class JobSummary:
    """The result of ``run_job``: per-step summaries, total wall time [s], where outputs are.

    status: "ok" (every item succeeded), "failed_items" (some items failed), or "error" (the job
    stopped, e.g. a finalize raised; ``error`` says why)."""

    job: str
    out: str
    executor: str
    workers: int
    seconds: float
    steps: tuple[StepSummary, ...] = ()
    status: str = "ok"
    error: str = ""
    run_id: int = 0
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def done(self) -> int:
        return sum(s.done for s in self.steps)

    @property
    def cached(self) -> int:
        return sum(s.cached for s in self.steps)

    @property
    def failed(self) -> int:
        return sum(s.failed for s in self.steps)

    def step(self, name: str) -> StepSummary:
        for s in self.steps:
            if s.name == name:
                return s
        raise KeyError(name)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["totals"] = {"done": self.done, "cached": self.cached, "failed": self.failed}
        return d

    @staticmethod
    def from_dict(d: dict[str, Any]) -> "JobSummary":
        steps = tuple(StepSummary(**{**s, "failures": tuple(Failure(**f) for f in s.get("failures", ()))})
                      for s in d.get("steps", ()))
        keep = {k: v for k, v in d.items() if k not in ("steps", "totals")}
        return JobSummary(**keep, steps=steps)

    def write(self, work_dir: Path) -> Path:
        """Write ``<work_dir>/reports/summary.json`` atomically; returns its path."""
        path = Path(work_dir) / SUMMARY_RELPATH
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        tmp.write_text(json.dumps(self.to_dict(), indent=2) + "\n", encoding="utf-8")
        os.replace(tmp, path)
        return path


def read_summary(work_dir: Path) -> JobSummary | None:
    """The summary of the last finished run in ``work_dir`` (None if there is none)."""
    path = Path(work_dir) / SUMMARY_RELPATH
    if not path.is_file():
        return None
    return JobSummary.from_dict(json.loads(path.read_text(encoding="utf-8")))


def stdout_console() -> Any:
    """A rich console on stdout; 160 columns wide when stdout is not a terminal (pipes, logs, tests)."""
    from rich.console import Console

    console = Console()
    return console if console.is_terminal else Console(width=160)


def render_summary(summary: JobSummary, console: Any = None, max_failures: int = 50) -> None:
    """Print the summary as a rich table (per step: done / cached / failed, then each failure)."""
    from rich.table import Table
    from rich.text import Text

    console = console or stdout_console()
    title = (f"job {summary.job!r}: {summary.status} in {summary.seconds:.2f} s "
             f"({summary.executor}, {summary.workers} workers) -> {summary.out}")
    table = Table(title=Text(title), title_justify="left")
    for col, just in (("step", "left"), ("kind", "left"), ("done", "right"), ("cached", "right"),
                      ("failed", "right"), ("time [s]", "right")):
        table.add_column(Text(col), justify=just)  # type: ignore[arg-type]
    for s in summary.steps:
        table.add_row(Text(s.name), Text(s.kind), str(s.done), str(s.cached),
                      f"[red]{s.failed}[/red]" if s.failed else "0", f"{s.seconds:.2f}")
    table.add_row("total", "", str(summary.done), str(summary.cached), str(summary.failed),
                  f"{summary.seconds:.2f}", style="bold")
    console.print(table)
    failures = [(s.name, f) for s in summary.steps for f in s.failures]
    if failures:
        ft = Table(title=f"{len(failures)} failed item(s)", title_justify="left")
        ft.add_column("step")
        ft.add_column("item")
        ft.add_column("reason", overflow="fold")
        for step, f in failures[:max_failures]:
            ft.add_row(Text(step), Text(f.item_id), Text(f.reason))
        console.print(ft)
        if len(failures) > max_failures:
            console.print(f"... and {len(failures) - max_failures} more (see reports/summary.json)")
    if summary.error:
        console.print(Text("error: " + summary.error, style="red"))
