"""Saving a simulated scene with its robot as USD.

:class:`UsdRecorder` writes the whole simulated model, the scene's objects and the robot, as a
time-sampled USD (Newton's ``ViewerUSD``: one Xform per shape instance, transforms sampled per
frame), so an episode can be replayed in any USD viewer. The scene's own USD stays the source of
truth for the furnished room; the recording is what happened in it, robot included.
"""

from __future__ import annotations

import logging
from pathlib import Path

log = logging.getLogger(__name__)


class UsdRecorder:
    """Context manager: ``with UsdRecorder(sim, path, fps=30) as rec: ... rec.frame()``.

    ``frame()`` logs ``sim.state_0`` at ``sim.time``; frames closer than 1/fps to the previous
    one are skipped. The file is written to a temporary name and renamed on exit."""

    def __init__(self, sim, path: Path, *, fps: int = 30, max_frames: int | None = None) -> None:
        self.sim = sim
        self.path = Path(path)
        self.fps = fps
        self.max_frames = max_frames
        self._viewer = None
        self._last = -1.0
        self.frames = 0

    def __enter__(self) -> UsdRecorder:
        from newton.viewer import ViewerUSD

        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._tmp = self.path.with_name(self.path.stem + ".tmp" + self.path.suffix)
        self._viewer = ViewerUSD(str(self._tmp), fps=self.fps, num_frames=self.max_frames)
        self._viewer.set_model(self.sim.model)
        return self

    def frame(self) -> None:
        t = self.sim.time
        if self._last >= 0 and t - self._last < 1.0 / self.fps - 1e-9:
            return
        v = self._viewer
        v.begin_frame(t)
        v.log_state(self.sim.state_0)
        v.end_frame()
        self._last = t
        self.frames += 1

    def __exit__(self, exc_type, exc, tb) -> None:
        self._viewer.close()
        self._viewer = None
        if exc_type is None:
            self._tmp.replace(self.path)
            log.info("recorded %d frames to %s", self.frames, self.path)
        else:
            self._tmp.unlink(missing_ok=True)
