"""Lockstep scheduling of per-world programs over one batched simulation.

Each world runs a *program* (a scripted expert, a teleop replay, a policy driver) as a coroutine of
its own (a greenlet: its own stack, switched to and from in the engine's thread, a few
microseconds a switch where a thread's hand-over through the OS took tens to hundreds); a program
never steps the simulation itself. It asks for ``n`` physics steps (:meth:`Lockstep.wait_steps`)
or for the next synchronisation point (:meth:`Lockstep.wait_sync`) and blocks; the engine
advances every world together and resumes each program when its request is met. Exactly one
program runs at a time (the engine hands control to one program and goes on when it blocks again),
always in world order, so a world's program sees the same states and issues the same commands
whatever the other worlds do: a world's episode equals a single-world run of the same seed.

Programs only touch their own world's buffers (commands, targets) between requests, and their
planning (A*, IK solves at waypoints, grasp choice) happens then: off the per-step loop, which is
the engine's batched array work.

::

    ls = Lockstep(world_count=4)
    ls.start(w, fn)                       # fn() runs as world w's program, calls ls.wait_steps(w, n)
    while ls.alive():
        ls.resume_ready()                 # every world whose request is met runs until it blocks
        k = ls.min_pending()              # the engine steps k physics steps for all worlds
        ...; ls.advance(k)
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import greenlet

from stages.simulate.cooperative import set_hook


class WorldStopped(BaseException):
    """Raised inside a world's program when the engine shuts down (not an Exception: programs'
    ``except Exception`` blocks do not swallow it)."""


@dataclass(eq=False)
class _Slot:
    glet: greenlet.greenlet | None = None  # the program's coroutine
    caller: greenlet.greenlet | None = None  # who resumed it (where it switches back to)
    pending: int = 0  # physics steps still to run before the program resumes
    sync: bool = False  # waiting for the next synchronisation point
    done: bool = True
    error: BaseException | None = None
    stop: bool = False
    busy: bool = False  # parked at a checkpoint, mid-computation (``yield_check``)
    resumed_at: float = 0.0  # perf_counter() of the last resume


class Lockstep:
    """World programs as cooperatively scheduled coroutines (see the module docstring), run in
    the thread that starts and resumes them. ``yield_check(world, seconds)``: asked at every
    checkpoint of a program (:func:`stages.simulate.cooperative.checkpoint`) with the wall time
    since its resume; True parks the program there, mid-computation (:attr:`_Slot.busy`), and
    :meth:`_resume` returns as if it had blocked: its scheduler may run other worlds first, then
    resume it where it stopped (None: programs never park at checkpoints)."""

    def __init__(self, world_count: int, yield_check: Callable[[int, float], bool] | None = None) -> None:
        self.slots = [_Slot() for _ in range(world_count)]
        self._current: int | None = None
        self.yield_check = yield_check
        self.yields = 0  # programs parked at checkpoints

    # -- program side ---------------------------------------------------------------------
    def current_world(self) -> int | None:
        """The world whose program is running now (None: the engine's own code)."""
        return self._current

    def wait_steps(self, world: int, n: int) -> None:
        """Block world ``world``'s program until ``n`` >= 1 physics steps have run."""
        s = self.slots[world]
        s.pending = max(1, int(n))
        self._park(s)

    def wait_sync(self, world: int) -> None:
        """Block until the engine reaches its next synchronisation point (and has run its
        synchronisation work, e.g. this world's reset)."""
        s = self.slots[world]
        s.sync = True
        self._park(s)

    def _checkpoint(self) -> None:
        w = self._current
        if w is None or greenlet.getcurrent() is not self.slots[w].glet:
            return  # not inside one of these programs
        s = self.slots[w]
        if self.yield_check(w, time.perf_counter() - s.resumed_at):
            self.yields += 1
            s.busy = True
            self._park(s)
            s.busy = False

    def _park(self, s: _Slot) -> None:
        s.caller.switch()
        if s.stop:
            raise WorldStopped()

    # -- engine side ----------------------------------------------------------------------
    def start(self, world: int, fn) -> None:
        """Run ``fn()`` as world ``world``'s program; it runs when first resumed."""
        s = self.slots[world]
        if not s.done:
            raise RuntimeError(f"world {world}: a program is already running")
        s.done, s.error, s.pending, s.sync, s.stop, s.busy = False, None, 0, False, False, False
        if self.yield_check is not None:
            set_hook(self._checkpoint)

        def main() -> None:
            try:
                if not s.stop:
                    fn()
            except WorldStopped:
                pass
            except BaseException as e:  # noqa: BLE001 (handed to the engine, re-raised there)
                s.error = e
            finally:
                s.done = True

        s.glet = greenlet.greenlet(main)

    def _switch(self, w: int) -> None:
        """Run world ``w``'s program until it blocks, parks or ends."""
        s = self.slots[w]
        s.resumed_at = time.perf_counter()
        s.caller = cur = greenlet.getcurrent()
        if s.glet.parent is not cur:
            s.glet.parent = cur  # an ended program returns here too
        prev, self._current = self._current, w
        try:
            s.glet.switch()
        finally:
            self._current = prev

    def _resume(self, w: int) -> None:
        s = self.slots[w]
        self._switch(w)
        if s.error is not None:
            err, s.error = s.error, None
            raise RuntimeError(f"world {w}: its program failed: {err!r}") from err

    def ready(self, skip=None) -> list[int]:
        """Live worlds with no pending steps and no sync wait (``skip[w]`` true: left out)."""
        return [w for w, s in enumerate(self.slots)
                if not s.done and s.pending == 0 and not s.sync and (skip is None or not skip[w])]

    def resume_ready(self, skip=None) -> int:
        """Resume, in world order, every live world with no pending steps and no sync wait
        (``skip[w]`` true: a held world, left as it is); each runs until it blocks again or ends.
        Returns how many were resumed."""
        ws = self.ready(skip)
        for w in ws:
            self._resume(w)
        return len(ws)

    def running(self, world: int) -> bool:
        """Whether world ``world``'s program is running now (never, seen from the engine: programs
        run one at a time while the engine waits)."""
        return False

    def waiting_sync(self) -> list[int]:
        return [w for w, s in enumerate(self.slots) if not s.done and s.sync]

    def release_sync(self, worlds) -> None:
        """Clear the sync wait of ``worlds`` (the engine has done their synchronisation work);
        they resume at the next :meth:`resume_ready`."""
        for w in worlds:
            self.slots[w].sync = False

    def min_pending(self, skip=None) -> int | None:
        """Fewest pending steps over live worlds that wait for steps (None if none does;
        ``skip[w]`` true: held, left out)."""
        p = [s.pending for w, s in enumerate(self.slots)
             if not s.done and not s.sync and s.pending > 0 and (skip is None or not skip[w])]
        return min(p) if p else None

    def advance(self, k: int, skip=None) -> None:
        """``k`` physics steps ran for every world (but held ones, ``skip[w]`` true): count them
        off the pending requests."""
        for w, s in enumerate(self.slots):
            if not s.done and s.pending > 0 and (skip is None or not skip[w]):
                s.pending = max(0, s.pending - k)

    def pending(self, world: int) -> int:
        return self.slots[world].pending

    def set_pending(self, world: int, n: int) -> None:
        self.slots[world].pending = n

    def alive(self) -> bool:
        return any(not s.done for s in self.slots)

    def is_done(self, world: int) -> bool:
        return self.slots[world].done

    def shutdown(self) -> None:
        """Stop every live program (raises :class:`WorldStopped` inside it) and let it end."""
        for w, s in enumerate(self.slots):
            if not s.done and s.glet is not None:
                s.stop = True
                self._switch(w)
        if self.yield_check is not None:
            set_hook(None)
