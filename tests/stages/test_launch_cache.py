"""Per-step kernels replayed from recorded launches (:mod:`stages.simulate.launch_cache`): the same
results as ``wp.launch``, and no argument packing per physics step (the teleop frame's overhead)."""

from __future__ import annotations

import numpy as np


def _kernel():
    import warp as wp

    @wp.kernel
    def axpy(x: wp.array[wp.float32], y: wp.array[wp.float32], a: float):
        i = wp.tid()
        y[i] = y[i] + a * x[i]

    return axpy


def test_recorded_launches_give_wp_launch_results():
    import warp as wp

    from stages.simulate.launch_cache import LaunchCache

    k = _kernel()
    rng = np.random.default_rng(0)
    xs = [wp.array(rng.normal(size=5).astype(np.float32), device="cpu") for _ in range(2)]
    y_ref = wp.zeros(5, dtype=wp.float32, device="cpu")
    y = wp.zeros(5, dtype=wp.float32, device="cpu")
    cache = LaunchCache(k, 5, "cpu")
    for step in range(6):
        x = xs[step % 2]  # alternating buffers, as a Sim's two states
        x.assign(rng.normal(size=5).astype(np.float32))  # new contents each step: read at launch
        a = 0.5 if step < 4 else 2.0  # a scalar that changes: a new recording
        wp.launch(k, dim=5, inputs=[x, y_ref, a], device="cpu")
        cache.launch([x, y, a])
        np.testing.assert_array_equal(y.numpy(), y_ref.numpy())
    assert cache.recorded == 4  # two buffers x two scalar values


def test_sim_steps_launch_no_per_step_kernels_from_python(teleop_world, tmp_path, monkeypatch):
    """The base-velocity drive and the watched joints' peaks run before every physics step; after
    the first steps (one recording per state buffer) they are replays, not ``wp.launch`` calls."""
    import warp as wp

    from stages.engine import BatchEngine, EngineConfig

    eng = BatchEngine(teleop_world, panda_root=None, work_dir=tmp_path,
                      config=EngineConfig(worlds=1, record_images=False), seed=5)
    sim = eng.banks[0].sim
    bank = eng.banks[0]
    bank.ctl.set_base_velocity(0.3, 0.0, 0.5)
    sim.step(2)  # one recording per state buffer
    calls = []
    real = wp.launch
    monkeypatch.setattr(wp, "launch", lambda *a, **k: (calls.append(getattr(a[0], "key", a[0])), real(*a, **k))[1])
    yaw = sim.robot.coord["base_yaw"]
    q0 = sim.state_0.joint_q.numpy()[yaw]
    sim.step(17)  # one teleop frame
    assert calls == [], calls
    assert sim.state_0.joint_q.numpy()[yaw] - q0 > 0.005  # the replayed drive turns the base [rad]
    assert bank.ctl._launch.recorded == 2 and bank.peaks.paths and bank.peaks._launch.recorded == 2
