"""Third-party chatter: what other libraries print and warn while a job runs goes to logs/job.log, once.

A job's console shows the progress bar, our own warnings (failed items, retries) and the summary.
Everything else (Warp's banner and "Module ... load on device 'cpu' took ... ms" lines, Newton's
``NewtonWarning``s, MuJoCo's version check, C libraries writing to stdout/stderr) is recorded in
``<out>/logs/job.log`` instead, each distinct message once:

- ``OwnRecords``: a filter for the console handler that passes only records of our packages
  (``OWN_LOGGERS``).
- ``DedupFilter``: a filter for job.log that passes the first record of each third-party message
  and drops repeats (from any worker). Numbers do not count: "took 3.04 ms" and "took 0.85 ms" are
  the same message.
- ``capture_process_output()``: in a worker process, Python warnings go to logging
  (``py.warnings``), and the process's stdout and stderr file descriptors go into pipes whose lines
  are logged as ``output.stdout`` (INFO) and ``output.stderr`` (WARNING) records, so C-level writes
  are caught as well as ``print``.

No pxr, warp or torch here.
"""

from __future__ import annotations

import logging
import os
import re
import sys
import threading

OWN_LOGGERS = ("pipeline", "stages", "usd_schemas", "asset_catalog", "agentworld", "__main__")
OUTPUT_LOGGER = "output"

_NUMBER = re.compile(r"\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def is_own(name: str) -> bool:
    """Whether a logger name belongs to our packages."""
    return any(name == own or name.startswith(own + ".") for own in OWN_LOGGERS)


class OwnRecords(logging.Filter):
    """Pass only records of our packages (console handler)."""

    def filter(self, record: logging.LogRecord) -> bool:
        return is_own(record.name)


class DedupFilter(logging.Filter):
    """Pass our records, and the first record of each third-party (logger, level, message with
    numbers blanked); count the repeats it drops (``dropped``)."""

    def __init__(self) -> None:
        super().__init__()
        self._seen: set[tuple[str, int, str]] = set()
        self._lock = threading.Lock()
        self.dropped = 0

    def filter(self, record: logging.LogRecord) -> bool:
        if is_own(record.name):
            return True
        try:
            text = record.getMessage()
        except Exception:  # a malformed third-party record: keep it, logging reports it
            return True
        key = (record.name, record.levelno, _NUMBER.sub("#", text))
        with self._lock:
            if key in self._seen:
                self.dropped += 1
                return False
            self._seen.add(key)
        return True


_captured = False


def capture_process_output() -> None:
    """Route this process's Python warnings into logging and its stdout/stderr file descriptors
    (fd 1 and 2) into logging records of ``output.stdout`` / ``output.stderr``, line by line (for
    worker processes, whose log records reach the main process's job.log). Idempotent."""
    global _captured
    if _captured:
        return
    _captured = True
    logging.captureWarnings(True)
    logging.raiseExceptions = False   # a failing handler must not write to stderr (a loop through the pipe)
    for fd, stream, level in ((1, "stdout", logging.INFO), (2, "stderr", logging.WARNING)):
        getattr(sys, stream).flush()
        read_fd, write_fd = os.pipe()
        os.dup2(write_fd, fd)
        os.close(write_fd)
        threading.Thread(target=_pump, args=(read_fd, logging.getLogger(f"{OUTPUT_LOGGER}.{stream}"), level),
                         name=f"capture-{stream}", daemon=True).start()
    sys.stdout.reconfigure(line_buffering=True)
    sys.stderr.reconfigure(line_buffering=True)


def _pump(read_fd: int, logger: logging.Logger, level: int) -> None:
    """Log each non-empty line read from ``read_fd`` until it closes."""
    buf = b""
    while True:
        try:
            chunk = os.read(read_fd, 65536)
        except OSError:
            break
        if not chunk:
            break
        buf += chunk
        *lines, buf = buf.split(b"\n")
        for line in lines:
            text = line.decode("utf-8", "replace").rstrip()
            if text.strip():
                logger.log(level, "%s", text)
    if buf.strip():
        logger.log(level, "%s", buf.decode("utf-8", "replace").rstrip())
