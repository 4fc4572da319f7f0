"""Rollout videos: the policy's camera images of an episode side by side, H.264 mp4 (PyAV)."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np


class RolloutVideo:
    """Frames ``{camera: RGB (H, W, 3) uint8}`` of ``cameras`` tiled left to right (padded to even
    sizes) into ``path`` at ``fps``; :meth:`close` finishes the file and returns its path."""

    def __init__(self, path: Path, *, fps: int, cameras: tuple[str, ...], crf: int = 23) -> None:
        self.path, self.fps, self.cameras, self.crf = Path(path), int(fps), tuple(cameras), crf
        self.frames = 0
        self._container = None
        self._stream = None

    def _open(self, h: int, w: int) -> None:
        import av

        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._container = av.open(str(self.path), "w")
        s = self._container.add_stream("h264", self.fps, options={"crf": str(self.crf), "preset": "ultrafast"})
        s.pix_fmt, s.width, s.height = "yuv420p", w, h
        s.time_base = Fraction(1, self.fps)
        self._stream = s

    def add(self, rgb: dict[str, np.ndarray]) -> None:
        import av

        tile = np.concatenate([rgb[c] for c in self.cameras], axis=1)
        h, w = tile.shape[0] + tile.shape[0] % 2, tile.shape[1] + tile.shape[1] % 2
        if (h, w) != tile.shape[:2]:
            tile = np.pad(tile, ((0, h - tile.shape[0]), (0, w - tile.shape[1]), (0, 0)))
        if self._container is None:
            self._open(h, w)
        frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(tile), format="rgb24")
        frame.pts = self.frames
        self.frames += 1
        for packet in self._stream.encode(frame):
            self._container.mux(packet)

    def close(self) -> Path | None:
        """Finish the file; its path (None when no frame came)."""
        if self._container is None:
            return None
        for packet in self._stream.encode():
            self._container.mux(packet)
        self._container.close()
        self._container = None
        return self.path
