"""Peaks of watched scene joints per world (a momentary event: a pressed button), tracked on the
device before every physics step; :class:`LocalPeaks` is the world programs' side of them."""

from __future__ import annotations

import numpy as np

from stages.simulate.launch_cache import LaunchCache


class LocalPeaks:
    """Peaks of world programs running in the engine's process: the banks' device arrays."""

    def __init__(self, engine) -> None:
        self.engine = engine

    def start(self, w: int) -> None:
        b, i = self.engine._where[w]
        b.peaks.start(i)

    def stop(self, w: int) -> None:
        b, i = self.engine._where[w]
        b.peaks.stop(i)

    def read(self, w: int) -> dict[str, float]:
        b, i = self.engine._where[w]
        return b.peaks.read(i)


class Peaks:
    """The largest value [m or rad] each watched scene joint reached during a world's episode,
    tracked on the device before every physics step (a momentary event: a pressed button)."""

    def __init__(self, sim, paths, scene_coord: dict[str, int]) -> None:
        import warp as wp

        self.paths = [p for p in paths if p in scene_coord]
        self.sim = sim
        n, dev = sim.world_count, sim.model.device
        self._coords = wp.array(np.array([scene_coord[p] for p in self.paths] or [0], np.int32), device=dev)
        self._peak = wp.full((n, max(1, len(self.paths))), -1e9, dtype=wp.float32, device=dev)
        self._active_np = np.zeros(n, np.int32)
        self._active = wp.zeros(n, dtype=wp.int32, device=dev)
        self._dirty = False
        self._host: np.ndarray | None = None  # host copy of _peak, read at most once per step
        # replayed from recorded launches (one per state buffer: they alternate)
        self._launch = LaunchCache(_peaks_kernel(), (n, max(1, len(self.paths))), dev)
        sim.pre_step.append(self._pre_step)

    def start(self, w: int) -> None:
        self._active_np[w] = 1
        self._dirty = True
        self._peak[w].fill_(-1e9)
        self._host = None

    def stop(self, w: int) -> None:
        self._active_np[w] = 0
        self._dirty = True

    def host(self) -> np.ndarray:
        """(W, P) peaks [m or rad] on the host, read once after each physics step."""
        if self._host is None:
            self._host = self._peak.numpy()
        return self._host

    def read(self, w: int) -> dict[str, float]:
        row = self.host()[w]
        return {p: float(row[i]) for i, p in enumerate(self.paths)}

    def _pre_step(self, sim) -> None:
        if not self.paths:
            return
        self._host = None
        if self._dirty:
            self._active.assign(self._active_np)
            self._dirty = False
        self._launch.launch([sim.state_0.joint_q, self._coords, self._active, sim.coords_per_world, self._peak])


_PEAKS_KERNEL = None


def _peaks_kernel():
    global _PEAKS_KERNEL
    if _PEAKS_KERNEL is None:
        import warp as wp

        @wp.kernel
        def track_peaks(joint_q: wp.array[wp.float32], coords: wp.array[wp.int32], active: wp.array[wp.int32],
                        coords_per_world: int, peak: wp.array2d[wp.float32]):
            w, j = wp.tid()
            if active[w] == 0:
                return
            v = joint_q[w * coords_per_world + coords[j]]
            if v > peak[w, j]:
                peak[w, j] = v

        _PEAKS_KERNEL = track_peaks
    return _PEAKS_KERNEL
