"""The teleop session's CPU rendering in the background (``EngineConfig.background_render``: each
frame renders in a thread of its own while the next frame's physics steps run, and is delivered as
soon as it is rendered) records the same frames, images and states, as rendering in the engine's
thread, and it renders beside the physics, each camera in a thread of its own (issue 15: the page's
frame rate on the CPU)."""

from __future__ import annotations

import threading

import numpy as np


def _episode(world, tmp, background: bool, frames: int = 12):
    """One engine episode of ``frames`` frames driven forward and turning; its recorded frames and
    the names of the threads that rendered them."""
    from stages.demos.sampling import sample_instance
    from stages.engine import BatchEngine, EngineConfig

    cfg = EngineConfig(worlds=1, width=64, height=48, background_render=background)
    engine = BatchEngine(world, panda_root=None, work_dir=tmp, config=cfg, seed=5)
    rig = engine.banks[0].rig
    threads: list[str] = []
    render = rig.render_compact_async

    def traced():  # which thread renders (the launch returns before a background render is done)
        from stages.simulate import compact

        inner = compact._render_camera

        def _render_camera(*a):
            threads.append(threading.current_thread().name)
            return inner(*a)

        compact._render_camera = _render_camera
        try:
            return render()
        finally:
            compact._render_camera = inner

    rig.render_compact_async = traced
    got, queue = [], [sample_instance("pick_place_bowl", world, 3)]

    def act(inst, drv):
        S, f = engine.steps_per_second, cfg.fps
        for i in range(1, frames + 1):
            drv.base((0.4, 0.0, 0.6 if i > frames // 2 else 0.0))
            drv.sim.step(max(1, -(-i * S // f) - drv.sim.steps))

    engine.run(lambda w: queue.pop() if queue else None, begin=lambda w, t: got.append, act=act)
    return got, threads


def test_background_render_records_the_same_frames(teleop_world, tmp_path):
    ref, ref_threads = _episode(teleop_world, tmp_path / "a", background=False)
    bg, bg_threads = _episode(teleop_world, tmp_path / "b", background=True)
    assert len(ref) == len(bg) >= 12
    assert ref_threads and not any(t.startswith("render") for t in ref_threads)
    assert len({t for t in bg_threads if t.startswith("render")}) >= 2, bg_threads  # cameras in parallel
    for a, b in zip(ref, bg, strict=True):
        np.testing.assert_array_equal(a.state(), b.state())
        np.testing.assert_array_equal(a.action(), b.action())
        assert set(a.rgb) == set(b.rgb) == {"wrist", "head", "third_person"}
        for cam in a.rgb:
            np.testing.assert_array_equal(a.rgb[cam], b.rgb[cam])
            np.testing.assert_array_equal(a.depth_mm[cam], b.depth_mm[cam])
    # the robot moved: the frames differ from each other
    assert not np.array_equal(bg[0].rgb["third_person"], bg[-1].rgb["third_person"])
