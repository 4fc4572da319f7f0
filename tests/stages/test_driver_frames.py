"""The Driver's steps end on the episode's frame grid (issue 12: one program round per frame).

A batched engine advances all worlds by the fewest steps any world asked for; a request that ends
between two frame steps splits the frame into several engine steps (one round of every due
world's program each). At 500 steps/s and 30 fps a frame is 16 or 17 steps, so ``step(1/30)``
(17 steps) drifted off the grid after the first frame.
"""

from __future__ import annotations

from types import SimpleNamespace

from stages.demos.driver import Driver


class _Sim:
    """A clock with the Sim's step interface (what Driver.step touches)."""

    def __init__(self, dt: float) -> None:
        self.settings = SimpleNamespace(dt=dt)
        self.steps = 0

    def step(self, n: int) -> None:
        assert n >= 1
        self.steps += n


def _driver(dt: float = 0.002, fps: int = 30) -> Driver:
    return Driver(_Sim(dt), None, None, None, SimpleNamespace(fps=fps), None)


def _frame_steps(S: int, f: int, n: int) -> set[int]:
    return {-(-k * S // f) for k in range(n)}


def test_frame_by_frame_steps_stay_on_the_frame_grid():
    d = _driver()
    grid = _frame_steps(500, 30, 400)
    ends = []
    for _ in range(90):
        d.step(d.frame_dt)
        ends.append(d.sim.steps)
    assert set(ends) <= grid
    assert ends[-1] == 1500  # 90 frames = 3 s at 500 steps/s: no frame skipped, none lost


def test_any_request_ends_on_the_first_frame_step_not_short_of_it():
    d = _driver()
    grid = sorted(_frame_steps(500, 30, 400))
    for seconds in (0.002, 0.1, 0.2, 0.25, 0.3, 1 / 30, 0.0333, 1.0, 0.5):
        t0 = d.sim.steps
        took = d.step(seconds)
        end = d.sim.steps
        assert end in grid and end > t0
        assert end - t0 > seconds / 0.002 - 1  # less than one step short of the request
        before = max(s for s in grid if s < end)  # the frame step before it would be short
        assert before <= t0 or before - t0 <= seconds / 0.002 - 1
        assert abs(took - (end - t0) * 0.002) < 1e-12


def test_steps_unchanged_when_dt_does_not_divide_a_second():
    d = _driver(dt=0.003)
    d.step(0.1)
    assert d.sim.steps == 33
