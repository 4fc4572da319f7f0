"""The fast MuJoCo CPU step (:mod:`stages.simulate.mujoco_cpu`) gives the same states as Newton's
``SolverMuJoCo.step``, bit for bit, on the teleop kitchen (base driving and turning, arm and
gripper targets moving, contacts), and costs less CPU (issue 15: the teleop page's frame rate)."""

from __future__ import annotations

import time

import numpy as np


def _snapshot(sim):
    """Everything a step reads or writes: the MuJoCo data, both Newton states, the control."""
    import mujoco

    d = mujoco.MjData(sim.solver.mj_model)
    mujoco.mj_copyData(d, sim.solver.mj_model, sim.solver.mj_data)
    keys = ("joint_q", "joint_qd", "body_q", "body_qd", "body_f")
    states = [{k: getattr(st, k).numpy().copy() for k in keys} for st in (sim.state_0, sim.state_1)]
    names = ("joint_target_q", "joint_target_qd", "joint_f")
    ctl = {k: getattr(sim.control, k).numpy().copy() for k in names}
    return d, (sim.state_0, sim.state_1), states, ctl, (sim.solver._step, sim.steps, sim.time)


def _restore(sim, snap) -> None:
    import mujoco

    d, order, states, ctl, counters = snap
    mujoco.mj_copyData(sim.solver.mj_data, sim.solver.mj_model, d)
    sim.state_0, sim.state_1 = order
    for st, saved in zip(order, states, strict=True):
        for k, v in saved.items():
            getattr(st, k).assign(v)
    for k, v in ctl.items():
        getattr(sim.control, k).assign(v)
    sim.solver._step, sim.steps, sim.time = counters


def _drive(sim, ctl, fast: bool, steps: int = 60):
    """``steps`` steps driving the base and moving the arm from the same targets; the states
    after each step and the CPU time of the steps [s]."""
    sim._cpu_step = None if fast else False
    arm = [sim.robot.coord[n] for n in sim.desc.arm_joints]
    ctl._targets[:] = sim.control.joint_target_q.numpy()
    out, cpu = [], 0.0
    for i in range(steps):
        ctl._cmd_np[0] = (0.4, 0.1 * np.sin(i / 7), 0.6)
        ctl._targets[arm] += 0.004
        ctl.mark_dirty()
        t = time.thread_time()
        sim.step(1)
        cpu += time.thread_time() - t
        out.append(np.concatenate([sim.state_0.joint_q.numpy(), sim.state_0.joint_qd.numpy(),
                                   sim.state_0.body_q.numpy().ravel(), sim.state_0.body_qd.numpy().ravel(),
                                   sim.solver.mj_data.qpos, sim.solver.mj_data.qvel]))
    return np.stack(out), cpu


def test_fast_cpu_step_matches_newtons_step(teleop_world, tmp_path):
    from stages.engine import BatchEngine, EngineConfig
    from stages.simulate.mujoco_cpu import MujocoCpuStep

    eng = BatchEngine(teleop_world, panda_root=None, work_dir=tmp_path,
                      config=EngineConfig(worlds=1, record_images=False), seed=5)
    bank = eng.banks[0]
    sim, ctl = bank.sim, bank.ctl
    sim.step(20)  # settle a little (either path), then the same start for both
    snap = _snapshot(sim)
    ref, ref_cpu = _drive(sim, ctl, fast=False)
    assert sim._cpu_step is False
    _restore(sim, snap)
    got, fast_cpu = _drive(sim, ctl, fast=True)
    assert isinstance(sim._cpu_step, MujocoCpuStep)
    assert sim.solver.mj_data.ncon > 0  # the steps had contacts
    assert not np.allclose(ref[0], ref[-1])  # the robot moved
    np.testing.assert_array_equal(got, ref)
    # a state replaced under the Sim (not only swapped) gets launches recorded for it
    first, fresh = sim._cpu_step, sim.model.state()
    fresh.assign(sim.state_0)
    sim.state_0 = fresh
    sim.step(2)
    assert sim._cpu_step is not first and sim._cpu_step.covers(sim)
    assert np.isfinite(sim.state_0.joint_q.numpy()).all()
    print(f"\n60 steps: Newton's step {ref_cpu * 1e3:.1f} ms CPU, fast step {fast_cpu * 1e3:.1f} ms")
