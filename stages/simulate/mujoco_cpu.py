"""Newton's MuJoCo CPU step with its per-step Python overhead taken out: the same kernels on the
same inputs, launched from recorded launches into buffers allocated once.

Newton's ``SolverMuJoCo.step`` on the MuJoCo C library (one world, ``use_mujoco_cpu``) spends more
time around ``mj_step`` than in it: every step allocates its control, force and coordinate buffers,
packs the arguments of eight kernel launches and converts arrays through numpy (measured on the
teleop kitchen, 64 DoF, ~430 contacts, on the shared 2-core machine: 17 steps 43 ms of CPU, of which
``mj_step`` 15 ms). :class:`MujocoCpuStep` does what that step does, in the same order, with the
same Newton kernels (so the states are the same, bit for bit:
``tests/stages/test_mujoco_cpu_step.py``), but launches each kernel from a ``wp.Launch`` recorded
once per state buffer (the two states alternate) and fills buffers allocated once.

It covers the configuration our simulations use (actuated joints, joint and body forces, mocap
roots, kinematic welds; no body accelerations or solver observables); :func:`fast_cpu_step`
returns None for anything else, and :class:`~stages.simulate.world.Sim` then calls Newton's step.
It reads private attributes of Newton 1.8's ``SolverMuJoCo``: a Newton upgrade that renames them
falls back to Newton's step (logged once), and the test above catches one that changes their meaning.
"""

from __future__ import annotations

import logging

import numpy as np

log = logging.getLogger(__name__)


def fast_cpu_step(sim) -> MujocoCpuStep | None:
    """A :class:`MujocoCpuStep` for ``sim`` (a :class:`~stages.simulate.world.Sim`), or None where
    Newton's own step must run (not MuJoCo C, or a feature this step does not mirror)."""
    solver = sim.solver
    if sim.pipeline is not None or not getattr(solver, "use_mujoco_cpu", False):
        return None
    try:
        why = _unsupported(sim)
        if why:
            log.info("simulate: Newton's MuJoCo CPU step kept (%s)", why)
            return None
        return MujocoCpuStep(sim)
    except (AttributeError, ImportError, TypeError) as e:  # a Newton whose internals differ
        log.warning("simulate: the fast MuJoCo CPU step is off (Newton internals differ: %r)", e)
        return None


def cpu_stepper(sim) -> MujocoCpuStep | None:
    """``sim``'s fast step, recorded for its current state and control buffers (again after one
    was replaced), or None (``sim._cpu_step`` becomes False: Newton's step from then on)."""
    f = sim._cpu_step
    if f is not None and f is not False and f.covers(sim):
        return f
    f = fast_cpu_step(sim) if sim.solver_settings.fast_cpu_step and f is not False else None
    sim._cpu_step = False if f is None else f
    return f


def _unsupported(sim) -> str:
    s, m = sim.solver, sim.model
    if s._update_data_interval != 1:
        return f"update_data_interval {s._update_data_interval}"
    if s.mjc_actuator_ctrl_source is None or s.mjc_actuator_to_newton_idx is None:
        return "no actuator mapping"
    if getattr(getattr(sim.control, "mujoco", None), "ctrl", None) is not None:
        return "direct MuJoCo controls"
    if sim.control.joint_f is None:
        return "no joint forces"
    for st in (sim.state_0, sim.state_1):
        if st.body_qdd is not None or st.body_parent_f is not None or st.body_f is None:
            return "body accelerations or parent forces requested, or no body forces"
        if getattr(getattr(st, "mujoco", None), "qfrc_actuator", None) is not None:
            return "actuator forces requested"
        if st.particle_count:
            return "particles"
    if m.world_count != 1 or s.mj_q_start.shape[0] < m.joint_count:
        return "not a single-world model"
    from newton._src.sim.articulation import _fk_prefers_tiled

    if _fk_prefers_tiled(m) or m.articulation_count == 0:
        return "forward kinematics layout"
    return ""


def _arrays(sim) -> frozenset:
    """The identities of the buffers the recorded launches read and write."""
    c = sim.control
    ids = [id(c), id(c.joint_target_q), id(c.joint_target_qd), id(c.joint_f)]
    for st in (sim.state_0, sim.state_1):
        ids += [id(st), id(st.joint_q), id(st.joint_qd), id(st.body_q), id(st.body_qd), id(st.body_f)]
    return frozenset(ids)


class MujocoCpuStep:
    """One MuJoCo CPU step of ``sim`` from ``state_0`` into ``state_1`` as Newton's
    ``clear_forces`` + ``SolverMuJoCo.step`` do it (see the module docstring)."""

    def __init__(self, sim) -> None:
        import newton
        import warp as wp
        from newton._src.sim.articulation import eval_articulation_fk
        from newton._src.solvers.mujoco import solver_mujoco as sm

        self.sim = sim
        self._arrays = _arrays(sim)
        s, m, c = sim.solver, sim.model, sim.control
        self.mj_model, self.mj_data, self._mujoco = s.mj_model, s.mj_data, s._mujoco
        dev = m.device
        d = self.mj_data
        nu = s.mjc_actuator_ctrl_source.shape[0]
        jpw = m.joint_count  # one world
        dof_ref = getattr(getattr(m, "mujoco", None), "dof_ref", None)
        nq, nv = len(d.qpos), len(d.qvel)
        # buffers Newton allocates at every step, allocated once (zeroed where Newton zeroes them)
        self.ctrl = wp.zeros((1, len(d.ctrl)), dtype=wp.float32, device=dev)
        self.qfrc = wp.zeros((1, len(d.qfrc_applied)), dtype=wp.float32, device=dev)
        self.xfrc = wp.zeros((1, len(d.xfrc_applied)), dtype=wp.spatial_vector, device=dev)
        self.qpos_out = wp.empty((1, nq), dtype=wp.float32, device=dev)
        self.qvel_out = wp.empty((1, nv), dtype=wp.float32, device=dev)
        self.qpos_in = wp.empty((1, nq), dtype=wp.float32, device=dev)
        self.qvel_in = wp.empty((1, nv), dtype=wp.float32, device=dev)
        self._np = {k: getattr(self, k).numpy() for k in ("ctrl", "qfrc", "xfrc", "qpos_out", "qvel_out",
                                                          "qpos_in", "qvel_in")}
        nbody = s.mjc_body_to_newton.shape[1]
        mjw = getattr(s, "mjw_data", None)
        mocap = s._jnt_mocap if mjw is not None else None  # Newton-driven mocap roots: copied to MjData
        self._mocap = None if mocap is None else (mjw.mocap_pos.numpy(), mjw.mocap_quat.numpy())
        self._cmds = {}
        for st_in, st_out in ((sim.state_0, sim.state_1), (sim.state_1, sim.state_0)):
            rec = dict(device=dev, record_cmd=True)
            self._cmds[id(st_in)] = ([
                wp.launch(sm.apply_mjc_control_kernel, dim=(1, nu), inputs=[
                    s.mjc_actuator_ctrl_source, s.mjc_actuator_to_newton_idx,
                    s.mjc_actuator_to_newton_target_q_idx,
                    s.mjc_actuator_to_target_q_axis_idx, s.mjc_actuator_to_newton_ball_jnt, m.joint_X_c,
                    c.joint_target_q, c.joint_target_qd, st_in.joint_q, None, dof_ref,
                    c.joint_target_q.shape[0], m.joint_coord_count, m.joint_dof_count, 0, jpw],
                    outputs=[self.ctrl], **rec),
                wp.launch(sm.apply_mjc_qfrc_kernel, dim=(1, jpw), inputs=[
                    c.joint_f, st_in.joint_q, m.joint_type, m.joint_child, m.body_flags, m.joint_q_start,
                    m.joint_qd_start, m.joint_dof_dim, m.joint_X_c, jpw, s.mj_qd_start],
                    outputs=[self.qfrc], **rec),
                wp.launch(sm.apply_mjc_body_f_kernel, dim=(1, nbody), inputs=[
                    s.mjc_body_to_newton, m.body_flags, st_in.body_f, m.body_mass, m.body_world, m.gravity,
                    s.mjw_model.body_gravcomp], outputs=[self.xfrc], **rec),
                wp.launch(sm.apply_mjc_free_joint_f_to_body_f_kernel, dim=(1, nbody), inputs=[
                    s.mjc_body_to_newton, m.body_flags, s.body_free_qd_start, c.joint_f],
                    outputs=[self.xfrc], **rec),
                wp.launch(sm.convert_warp_coords_to_mj_kernel, dim=(1, jpw), inputs=[
                    st_in.joint_q, st_in.joint_qd, None, jpw, m.joint_type, m.joint_q_start, m.joint_qd_start,
                    m.joint_dof_dim, m.joint_child, m.joint_X_p, m.joint_X_c, m.joint_axis, m.body_com,
                    dof_ref,
                    s.mj_q_start, s.mj_qd_start, mocap, True],
                    outputs=[self.qpos_out, self.qvel_out, None if mocap is None else mjw.mocap_pos,
                             None if mocap is None else mjw.mocap_quat, None], **rec),
            ], [
                wp.launch(sm.convert_mj_coords_to_warp_kernel, dim=(1, jpw), inputs=[
                    self.qpos_in, self.qvel_in, jpw, m.joint_type, m.joint_q_start, m.joint_qd_start,
                    m.joint_dof_dim, m.joint_child, m.joint_X_p, m.joint_X_c, m.body_com, dof_ref,
                    m.body_flags,
                    st_in.joint_q, st_in.joint_qd, s.mj_q_start, s.mj_qd_start],
                    outputs=[st_out.joint_q, st_out.joint_qd], **rec),
                wp.launch(eval_articulation_fk, dim=m.articulation_count, inputs=[
                    m.articulation_start, m.articulation_end, m._fk_joint_order, m.articulation_count,
                    None, None,
                    m.joint_articulation, st_out.joint_q, st_out.joint_qd, m.joint_q_start, m.joint_qd_start,
                    m.joint_type, m.joint_parent, m.joint_child, m.joint_X_p, m.joint_X_c, m.joint_axis,
                    m.joint_dof_dim, m.body_com, m.body_flags, int(newton.BodyFlags.ALL), None],
                    outputs=[st_out.body_q, st_out.body_qd],
                    block_dim=16 if m.max_joints_per_articulation <= 4 else 8, **rec),
            ], st_out)

    def covers(self, sim) -> bool:
        """Recorded for ``sim``'s current state, control and their arrays (False once one of
        them was replaced)."""
        return self._arrays == _arrays(sim)

    def step(self, state_in, state_out, dt: float) -> None:
        """``clear_forces`` on ``state_in``, then one MuJoCo step of ``dt`` [s] into ``state_out``
        (the solver's step counter advances as Newton's does)."""
        push, pull, out = self._cmds[id(state_in)]
        if out is not state_out:
            raise RuntimeError("simulate: the fast MuJoCo CPU step was recorded for other state buffers")
        b, d = self._np, self.mj_data
        state_in.body_f.zero_()
        b["ctrl"].fill(0.0)
        b["qfrc"].fill(0.0)
        b["xfrc"].fill(0.0)
        for cmd in push:
            cmd.launch()
        d.xfrc_applied[:] = b["xfrc"][0]
        d.ctrl[:] = b["ctrl"][0]
        d.qfrc_applied[:] = b["qfrc"][0]
        d.qpos[:] = b["qpos_out"][0]
        d.qvel[:] = b["qvel_out"][0]
        if self._mocap is not None:
            d.mocap_pos[:] = self._mocap[0][0]
            d.mocap_quat[:] = self._mocap[1][0]
        self.sim.solver._update_kinematic_weld_references()  # MuJoCo C: numpy, only where welds are active
        self.mj_model.opt.timestep = dt
        self._mujoco.mj_step(self.mj_model, d)
        b["qpos_in"][0] = d.qpos
        b["qvel_in"][0] = d.qvel
        for cmd in pull:
            cmd.launch()
        self.sim.solver._step += 1


__all__ = ["MujocoCpuStep", "cpu_stepper", "fast_cpu_step"]
