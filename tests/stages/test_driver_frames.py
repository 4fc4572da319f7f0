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


def test_any_request_ends_on_the_frame_step_nearest_to_it():
    d = _driver()
    grid = sorted(_frame_steps(500, 30, 400))
    for seconds in (0.002, 0.1, 0.2, 0.25, 0.3, 1 / 30, 0.0333, 0.034, 0.04, 0.05, 1.0, 0.5):
        t0 = d.sim.steps
        took = d.step(seconds)
        end = d.sim.steps
        assert end in grid and end > t0
        want = t0 + seconds / 0.002
        after = [s for s in grid if s > t0]
        assert abs(end - want) <= min(abs(s - want) for s in after) + 1e-9, (seconds, t0, end)
        assert abs(took - (end - t0) * 0.002) < 1e-12


def test_a_request_of_one_frame_in_whole_steps_takes_one_frame():
    """``_base_shift`` commands last ``round(frame_dt / dt)`` = 17 steps (0.034 s): one frame each,
    16 or 17 steps, never 33 (every other command took two frames: the retreat from an oven door
    ran half as fast at every other frame and the leaf dropped onto the hand; open_oven failed with
    grasp_missed in the main job's kitchen)."""
    d = _driver()
    d.step(0.1)
    took = []
    for _ in range(30):
        n = d.step_count(0.034)
        d.step(0.034)
        took.append(n)
    assert set(took) <= {16, 17}, took
    assert d.sim.steps == 50 + 500  # 30 frames = 1 s: on the grid, none skipped


def test_steps_unchanged_when_dt_does_not_divide_a_second():
    d = _driver(dt=0.003)
    d.step(0.1)
    assert d.sim.steps == 33
