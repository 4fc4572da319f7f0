"""Progress display: one rich progress bar per step with done / cached / failed counters."""

from __future__ import annotations

from typing import Any


class StepProgress:
    """Counters of one step; draws on a rich Progress when one is attached."""

    def __init__(self, progress: Any, name: str, total: int) -> None:
        self.counts = {"done": 0, "cached": 0, "failed": 0}
        self._progress = progress
        self._name = name
        self._task = progress.add_task(self._label(), total=total) if progress is not None else None

    def _label(self) -> str:
        c = self.counts
        failed = f"[red]failed {c['failed']}[/red]" if c["failed"] else "failed 0"
        from rich.markup import escape

        return f"{escape(self._name)}  done {c['done']}  cached {c['cached']}  {failed}"

    def advance(self, what: str) -> None:
        self.counts[what] += 1
        if self._task is not None:
            self._progress.update(self._task, advance=1, description=self._label())

    def finish(self) -> None:
        if self._task is not None:
            self._progress.update(self._task, description=self._label())


class JobProgress:
    """A context manager owning the rich Progress (or nothing when disabled)."""

    def __init__(self, enabled: bool, console: Any) -> None:
        self._progress = None
        if enabled:
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

            self._progress = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                                      TimeElapsedColumn(), console=console)

    def add_step(self, name: str, total: int) -> StepProgress:
        return StepProgress(self._progress, name, total)

    def __enter__(self) -> "JobProgress":
        if self._progress is not None:
            self._progress.start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self._progress is not None:
            self._progress.stop()


def make_progress(enabled: bool | None, console: Any = None) -> JobProgress:
    """A JobProgress; enabled=None shows it only when the console is a terminal."""
    if enabled is False:
        return JobProgress(False, None)
    from rich.console import Console

    console = console or Console(stderr=True)
    return JobProgress(console.is_terminal if enabled is None else True, console)
