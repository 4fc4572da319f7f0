"""Holding worlds still in one batched simulation while their programs think.

A world whose program is still planning when its request falls due is *held*: the engine keeps
stepping every other world, and after each physics step puts the held world's state back exactly
as it was when the hold began (joint coordinates and velocities, body poses and twists, MuJoCo's
acceleration warm-start and actuator activations). The world's clock, episode step counter and
pending request stop; its frames are not captured. The engine releases it only after a whole
number of synchronisation periods (``P`` steps, see :mod:`stages.engine.engine`), so its frames
keep falling on the global frame steps. A held world's episode is therefore identical to the one
it would have had unheld: holding changes only when, in wall time, its steps run.

The batched layout needs this restore (MuJoCo-Warp steps all worlds of a model together); the
per-world layout simply skips a held world's model.

::

    hold = WorldHold(sim)        # registers a post-step callback on the Sim
    hold.hold([3])               # saves world 3 now; every later step restores it
    sim.step(10)                 # world 3 unchanged; the others advance
    hold.release([3])
"""

from __future__ import annotations

import numpy as np

_KERNEL = None


def _copy_masked_kernel():
    global _KERNEL
    if _KERNEL is None:
        import warp as wp

        @wp.kernel
        def copy_masked(dst: wp.array[wp.float32], src: wp.array[wp.float32], elem_world: wp.array[wp.int32],
                        mask: wp.array[wp.int32]):
            i = wp.tid()
            w = elem_world[i]
            if w >= 0 and mask[w] != 0:
                dst[i] = src[i]

        _KERNEL = copy_masked
    return _KERNEL


def _flat(a, floats_per_elem: int):
    """A float32 view (N * floats_per_elem,) of the contiguous warp array ``a`` (no copy)."""
    import warp as wp

    return wp.array(ptr=a.ptr, dtype=wp.float32, shape=(a.size * floats_per_elem,), device=a.device)


class WorldHold:
    """Per-world hold of one batched :class:`~stages.simulate.world.Sim` (MuJoCo-Warp solver):
    :meth:`hold` saves the worlds' state, a post-step callback restores every held world after
    each physics step, :meth:`release` lets them run again."""

    def __init__(self, sim) -> None:
        import warp as wp

        self.sim = sim
        n, dev = sim.world_count, sim.model.device
        self.device = dev
        self.held_np = np.zeros(n, np.int32)
        self._held = wp.zeros(n, dtype=wp.int32, device=dev)
        self._new = wp.zeros(n, dtype=wp.int32, device=dev)
        m = sim.model
        body_world = m.body_world.numpy().astype(np.int32)
        # (name, floats per element, per-float world index) of every per-world field restored
        fields = [("joint_q", 1, np.arange(m.joint_coord_count, dtype=np.int32) // sim.coords_per_world),
                  ("joint_qd", 1, np.arange(m.joint_dof_count, dtype=np.int32) // sim.dofs_per_world),
                  ("body_q", 7, np.repeat(body_world, 7)), ("body_qd", 6, np.repeat(body_world, 6))]
        d = getattr(sim.solver, "mjw_data", None)
        if d is None:
            raise ValueError("engine: holding worlds needs the MuJoCo-Warp solver (the batched layout)")
        self._solver_fields = []
        for name in ("qacc_warmstart", "act"):
            a = getattr(d, name)
            if a.size:
                per = a.shape[1]
                self._solver_fields.append((name, np.arange(a.size, dtype=np.int32) // per))
        self._maps = {name: wp.array(wmap, dtype=wp.int32, device=dev) for name, _, wmap in fields}
        self._maps.update({name: wp.array(wmap, dtype=wp.int32, device=dev) for name, wmap in self._solver_fields})
        self._per = {name: per for name, per, _ in fields}
        self._saved = {name: wp.zeros(len(wmap), dtype=wp.float32, device=dev) for name, _, wmap in fields}
        self._saved.update({name: wp.zeros(len(wmap), dtype=wp.float32, device=dev)
                            for name, wmap in self._solver_fields})
        self._views: dict[tuple[int, str], object] = {}
        # holds and releases are applied on the device before the next step: an upload now would
        # wait for a render in flight (a copy from pageable memory waits for the stream)
        self._to_save = np.zeros(n, np.int32)
        self._dirty = False
        sim.pre_step.append(self._pre_step)
        sim.post_step.append(self._post_step)

    @property
    def any_held(self) -> bool:
        return bool(self.held_np.any())

    def _live(self, name: str):
        """The live float32 view of field ``name`` (the current ``state_0``'s, or the solver's)."""
        if name in self._per:
            a = getattr(self.sim.state_0, name)
            per = self._per[name]
        else:
            a = getattr(self.sim.solver.mjw_data, name)
            per = 1
        key = (a.ptr, name)
        v = self._views.get(key)
        if v is None:
            v = self._views[key] = _flat(a, per)
        return v

    def _copy(self, to_saved: bool, mask) -> None:
        import warp as wp

        k = _copy_masked_kernel()
        for name, saved in self._saved.items():
            live = self._live(name)
            dst, src = (saved, live) if to_saved else (live, saved)
            wp.launch(k, dim=saved.shape[0], inputs=[dst, src, self._maps[name], mask], device=self.device)

    def hold(self, worlds) -> None:
        """Save ``worlds`` (local indices) as they are now and keep them so from now on (the
        copy is taken before the next step: only a step changes a held world's state)."""
        worlds = [int(w) for w in worlds if not self.held_np[int(w)]]
        if not worlds:
            return
        self._to_save[worlds] = 1
        self.held_np[worlds] = 1
        self._dirty = True

    def release(self, worlds) -> None:
        """Let ``worlds`` (local indices) step again from where they were held."""
        worlds = [int(w) for w in worlds]
        if not worlds:
            return
        self.held_np[worlds] = 0
        self._dirty = True

    def _pre_step(self, sim) -> None:
        if not self._dirty:
            return
        if self._to_save.any():
            self._new.assign(self._to_save)
            self._copy(True, self._new)
            self._to_save[:] = 0
        self._held.assign(self.held_np)
        self._dirty = False

    def _post_step(self, sim) -> None:
        if self.held_np.any():
            self._copy(False, self._held)
