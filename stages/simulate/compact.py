"""Recording-ready images rendered on the device (RGB bytes, depth in millimetres), read back
asynchronously so that the host can work while the GPU renders.

:func:`launch_compact` enqueues the render of every camera in every world of a
:class:`~stages.simulate.sensors.CameraRig`, the conversion kernel and the copies into pinned host
buffers, and returns at once with a :class:`CompactRender`; its :meth:`CompactRender.wait` blocks
until the images are on the host. On CUDA the render runs on a stream of its own from a copy of
the body poses taken at the launch (in the simulation stream's order), so physics steps and state
reads may follow the launch at once; the next launch of the same rig must wait for this one.

On the CPU the render runs in the caller's thread before the launch returns, or, for a rig with
``background`` set, from a copy of the body poses taken at the launch (the same images: of the
state the renderer reads only the rigid bodies' poses, ``body_q``; our scenes have no particles),
each camera in a thread of the rig's own with a Newton sensor of its own, so that the cameras render
beside each other and beside the physics steps that follow the launch (the kernels release the
GIL; a CPU kernel runs on one core, so one thread for all cameras left the render of a frame on
one core). The first render of a rig runs in the caller's thread (it loads the kernels); a launch
waits for the rig's render in flight.
"""

from __future__ import annotations

import numpy as np


# CUDA: render on a stream of its own (True) or on the simulation's stream. Both give the same
# images (tests/benchmarks/bench_render.py checks it); on the H100 at 256 worlds the own stream hid
# the render wait (0.02 -> 0.01 s per frame) but the engine's frame assembly was slower in that run
# (611 vs 721 timesteps/s, two runs on different machines): bench_engine --ab-render-stream decides.
OWN_STREAM = False


class CompactRender:
    """A render in flight: :meth:`wait` returns, by camera name, RGB (W, H, Wd, 3) uint8 and depth
    (W, H, Wd) uint16 [mm] (0 where no surface, at most 65,535). On CUDA the arrays are views of
    pinned buffers that the rig's next launch overwrites: copy what you keep."""

    def __init__(self, out: dict[str, tuple[np.ndarray, np.ndarray]] | None, event, futures=None) -> None:
        self._out = out
        self._event = event
        self._futures = futures  # a background CPU render: {camera: concurrent.futures.Future}

    @property
    def done(self) -> bool:
        """The images are ready (CUDA: only once waited for; a background CPU render: finished)."""
        if self._futures is not None:
            return all(f.done() for f in self._futures.values())
        return self._event is None

    def wait(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        if self._futures is not None:
            self._out, self._futures = {k: f.result() for k, f in self._futures.items()}, None
        if self._event is not None:
            import warp as wp

            wp.synchronize_event(self._event)
            self._event = None
        return self._out


def launch_compact(rig) -> CompactRender:
    """Enqueue one render of every camera of ``rig`` (needs RGB and depth) for ``rig.sim.state_0``
    with its device-side conversion and read-back; on the CPU the render runs now."""
    import warp as wp

    if not (rig.rgb and rig.depth):
        raise ValueError("render_compact needs RGB and depth images")
    model, state = rig.sim.model, rig.sim.state_0
    cuda = str(model.device).startswith("cuda")
    # the camera poses are read from the host before anything is enqueued (a read waits for the stream)
    tfs = {cam.name: rig._transforms(cam)[0] for cam in rig.cameras}
    if not cuda and getattr(rig, "background", False):
        return _launch_background(rig, state, tfs)
    if not cuda or not OWN_STREAM:
        out = _render(rig, state, tfs, cuda)
        event = wp.get_device(model.device).stream.record_event() if cuda else None
        return CompactRender(out, event)
    # CUDA: the render reads its own copy of the body poses on its own stream, so that the physics
    # steps and state reads enqueued after the launch on the simulation's stream need not wait for it
    main = wp.get_stream(model.device)
    render_stream = rig.__dict__.get("_render_stream")
    if render_stream is None:
        render_stream = rig._render_stream = wp.Stream(model.device)
        rig._render_state = model.state()
    rstate = rig._render_state
    wp.copy(rstate.body_q, state.body_q)
    render_stream.wait_event(main.record_event())
    with wp.ScopedStream(render_stream):
        out = _render(rig, rstate, tfs, cuda)
        event = render_stream.record_event()
    return CompactRender(out, event)


def _launch_background(rig, state, tfs) -> CompactRender:
    """A CPU render from a copy of ``state``'s body poses, each camera in a thread of the rig's own
    with a sensor of its own (see the module doc)."""
    import warp as wp

    d = rig.__dict__
    pool = d.get("_bg_pool")
    if pool is None:  # the first render here: the kernels load in the caller's thread
        from concurrent.futures import ThreadPoolExecutor

        out = _render(rig, state, tfs, False)
        d["_bg_sensors"] = sensors = {cam.name: rig._sensor if k == 0 else rig.new_sensor()
                                      for k, cam in enumerate(rig.cameras)}
        for cam in rig.cameras[1:]:  # each sensor compiles or loads its render kernel once, here
            _render_camera(rig, sensors[cam.name], state, tfs[cam.name], cam, False)
        d["_bg_pool"] = ThreadPoolExecutor(max_workers=len(rig.cameras), thread_name_prefix="render")
        d["_bg_state"] = rig.sim.model.state()
        return CompactRender(out, None)
    prev = d.get("_bg_inflight")
    if prev is not None:
        prev.wait()  # its copy of the poses is about to be overwritten
    rstate = d["_bg_state"]
    wp.copy(rstate.body_q, state.body_q)
    rig.sim.model.bvh_refit_shapes(rstate)
    sensors = d["_bg_sensors"]
    futures = {cam.name: pool.submit(_render_camera, rig, sensors[cam.name], rstate, tfs[cam.name], cam,
                                     False) for cam in rig.cameras}
    r = d["_bg_inflight"] = CompactRender(None, None, futures)
    return r


def _render(rig, state, tfs, cuda: bool) -> dict:
    """Enqueue the renders, the conversion and (CUDA) the copies to pinned buffers on the current
    stream; the arrays by camera name (see :class:`CompactRender`)."""
    rig.sim.model.bvh_refit_shapes(state)
    return {cam.name: _render_camera(rig, rig._sensor, state, tfs[cam.name], cam, cuda)
            for cam in rig.cameras}


def _render_camera(rig, sensor, state, tf, cam, cuda: bool) -> tuple[np.ndarray, np.ndarray]:
    """One camera of :func:`_render` with ``sensor`` (shape BVH refitted for ``state``): RGB
    (W, H, Wd, 3) uint8 and depth (W, H, Wd) uint16 [mm]."""
    import warp as wp

    model = rig.sim.model
    nw = rig.sim.world_count
    img = rig._images[cam.name]
    sensor.update(state, tf, rig._rays[cam.name], color_image=img["color"], forward_depth_image=img["depth"],
                  shape_index_image=img["shape"], world_indices=rig._world_ids)
    n = nw * cam.height * cam.width
    bufs = rig.__dict__.setdefault("_compact", {})
    if cam.name not in bufs:
        bufs[cam.name] = (wp.zeros(3 * n, dtype=wp.uint8, device=model.device),
                          wp.zeros(n, dtype=wp.uint16, device=model.device))
    rgb, mm = bufs[cam.name]
    wp.launch(_compact_kernel(), dim=n, device=model.device,
              inputs=[img["color"].flatten(), img["depth"].flatten(), rgb, mm])
    if cuda:
        pinned = rig.__dict__.setdefault("_pinned", {})
        host = pinned.get(cam.name)
        if host is None:
            host = pinned[cam.name] = tuple(wp.empty_like(a, device="cpu", pinned=True) for a in (rgb, mm))
        for h, a in zip(host, (rgb, mm), strict=True):
            wp.copy(h, a)
        r, d = (h.numpy() for h in host)
    else:  # .numpy() is a view of the buffer the next render overwrites: copy it
        r, d = (a.numpy().copy() for a in (rgb, mm))
    return r.reshape(nw, cam.height, cam.width, 3), d.reshape(nw, cam.height, cam.width)


_COMPACT = None


def _compact_kernel():
    """Packed RGBA words -> RGB bytes; depth [m] -> uint16 [mm] as ``depth_m_to_mm`` does it
    (float64, round half to even, non-finite or <= 0 -> 0, clipped at 65,535)."""
    global _COMPACT
    if _COMPACT is None:
        import warp as wp

        @wp.kernel
        def compact(color: wp.array[wp.uint32], depth: wp.array[wp.float32], rgb: wp.array[wp.uint8],
                    mm: wp.array[wp.uint16]):
            i = wp.tid()
            p = color[i]
            rgb[3 * i] = wp.uint8(p & wp.uint32(255))
            rgb[3 * i + 1] = wp.uint8((p >> wp.uint32(8)) & wp.uint32(255))
            rgb[3 * i + 2] = wp.uint8((p >> wp.uint32(16)) & wp.uint32(255))
            d = wp.float64(depth[i])
            v = wp.float64(0.0)
            if wp.isfinite(d) and d > wp.float64(0.0):
                v = wp.min(wp.rint(d * wp.float64(1000.0)), wp.float64(65535.0))
            mm[i] = wp.uint16(v)

        _COMPACT = compact
    return _COMPACT
