"""Temporary siblings for atomic writes, and the removal of those a killed process left behind.

A folder (or file) ``final`` is written as ``<parent>/.tmp-<final name>-<pid>-<nonce>`` (pid: the writing
process, nonce: 8 hex digits) and renamed into place when complete. A process killed before the rename
(``kill -9``, power loss) leaves that temporary behind; its name says which process owned it.

:func:`remove_orphaned_temps` deletes the temporaries under a folder whose owning process is no longer
alive. The runner calls it on every start while it holds the work directory's lock, so a resumed run
cleans up after its killed predecessor; a temporary of a live process (this run's workers, or any other
live process) is never touched. A recycled pid only keeps an orphan longer, it never removes live work.
"""

from __future__ import annotations

import logging
import os
import re
import secrets
import shutil
from pathlib import Path

log = logging.getLogger(__name__)

TEMP_PREFIX = ".tmp-"
_TEMP_RE = re.compile(r"^\.tmp-(?P<name>.+)-(?P<pid>[0-9]+)-(?P<nonce>[0-9a-f]{8})$")


def temp_sibling(final: Path) -> Path:
    """The temporary name to write ``final`` under: ``.tmp-<name>-<pid>-<nonce>`` beside it."""
    final = Path(final)
    return final.with_name(f"{TEMP_PREFIX}{final.name}-{os.getpid()}-{secrets.token_hex(4)}")


def temp_owner(path: Path) -> tuple[str, int] | None:
    """(final name, owning pid) of a temporary made by :func:`temp_sibling`; None for any other name."""
    m = _TEMP_RE.match(Path(path).name)
    return (m["name"], int(m["pid"])) if m else None


def pid_alive(pid: int) -> bool:
    """Whether a process with this id exists on this machine (a zombie counts as dead)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True     # exists, owned by another user
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return True     # no /proc (not Linux): trust kill(0)
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def remove_orphaned_temps(root: Path, *, name: str | None = None, max_depth: int = 4) -> list[Path]:
    """Delete temporaries (see the module docstring) under ``root``, down to ``max_depth`` folder levels
    (1: ``root``'s own entries), whose owner is dead; only those of final ``name`` if given. The folder
    ``root`` itself and symbolic links are never followed out of. Returns what was deleted."""
    root = Path(root)
    removed: list[Path] = []
    level = [root]
    for _ in range(max_depth):
        nxt = []
        for folder in level:
            try:
                entries = sorted(os.scandir(folder), key=lambda e: e.name)
            except OSError:
                continue
            for e in entries:
                owner = temp_owner(Path(e.name))
                if owner is not None and (name is None or owner[0] == name):
                    if owner[1] != os.getpid() and not pid_alive(owner[1]):
                        _remove(Path(e.path))
                        removed.append(Path(e.path))
                    continue
                if e.is_dir(follow_symlinks=False):
                    nxt.append(Path(e.path))
        level = nxt
    for p in removed:
        log.warning("removed %s, left by process %d (no longer running)", p, temp_owner(p)[1])
    return removed


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)
