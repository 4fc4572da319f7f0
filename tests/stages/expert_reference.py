"""The scripted experts' planning and IK as they were before issue 12's speed-ups, kept verbatim
(as functions of the same objects) as references for the fast paths: ``tests/stages/
test_expert_fast.py`` checks that the fast paths give the same results on real task instances, and
``tests/benchmarks/bench_expert_cpu.py`` times both in one process.

``ik``: a :class:`stages.simulate.control.Clik`; ``d``: a :class:`stages.demos.driver.Driver`.
"""

from __future__ import annotations

import math

import numpy as np

from stages.demos.driver import ExpertFailure
from stages.demos.part_grasps import door_pitch, drawer_pitch, gesture, grips
from stages.demos.part_planning import BASE_SLACK, EDGE_SIDE, LIMIT_MARGIN, _swing_bases
from stages.demos.parts import ArticulatedPart


def clik_solve(ik, target, q0, *, max_iters=300, pos_tol=1e-4, rot_tol=1e-3, restarts=0, rng=None):
    """``Clik.solve`` before issue 12 (an :class:`~stages.simulate.control.IkResult`)."""
    best = _clik_solve1(ik, target, q0, max_iters, pos_tol, rot_tol)
    for _ in range(restarts if not best.success else 0):
        if rng is None:
            raise ValueError("restarts need an rng")
        q = np.asarray(q0, float).copy()
        idx = ik.v_idx[: len(ik.desc.arm_joints)]
        q[idx] = rng.uniform(ik.lower[idx], ik.upper[idx])
        res = _clik_solve1(ik, target, q, max_iters, pos_tol, rot_tol)
        if res.position_error + 0.1 * res.rotation_error < best.position_error + 0.1 * best.rotation_error:
            best = res
        if best.success:
            break
    return best


def _clik_solve1(ik, target, q0, max_iters, pos_tol, rot_tol):
    from stages.simulate.control import IkResult

    pin = ik._pin
    goal = pin.SE3(np.asarray(target, float))
    q = np.clip(np.asarray(q0, float).copy(), ik.lower, ik.upper)
    err = np.zeros(6)
    it = 0
    best, best_it = np.inf, 0
    for it in range(1, max_iters + 1):  # noqa: B007 (the count is reported)
        pin.framesForwardKinematics(ik.model, ik.data, q)
        cur = ik.data.oMf[ik.frame]
        err = pin.log6(cur.actInv(goal)).vector
        pe, re = np.linalg.norm(err[:3]), np.linalg.norm(err[3:])
        if pe < pos_tol and re < rot_tol:
            break
        e = pe + 0.1 * re
        if e < best * (1.0 - 1e-3):
            best, best_it = e, it
        elif ik.stall_iters and it - best_it >= ik.stall_iters:
            break
        pin.computeJointJacobians(ik.model, ik.data, q)
        jac = pin.getFrameJacobian(ik.model, ik.data, ik.frame, pin.LOCAL)[:, ik.v_idx]
        jjt = jac @ jac.T + ik.damping * np.eye(6)
        dv = jac.T @ np.linalg.solve(jjt, err)
        n = np.linalg.norm(dv)
        if n > ik.max_step:
            dv *= ik.max_step / n
        v = np.zeros(ik.model.nv)
        v[ik.v_idx] = dv
        q = np.clip(pin.integrate(ik.model, q, v), ik.lower, ik.upper)
    pin.framesForwardKinematics(ik.model, ik.data, q)
    m = ik.data.oMf[ik.frame]
    pe = float(np.linalg.norm(m.translation - goal.translation))
    re = float(np.linalg.norm(pin.log3(m.rotation.T @ goal.rotation)))
    return IkResult(q=q, success=pe < max(pos_tol, 1e-3) and re < max(rot_tol, 1e-2), position_error=pe,
                    rotation_error=re, iterations=it)


def base_q(d, base):
    """``part_planning._base_q`` before issue 12."""
    q = d.ik.with_arm(d.ik.from_sim(d.sim), d.ctl.arm_targets())
    x0, y0, yaw0 = d.sim.spawn
    c, s = math.cos(yaw0), math.sin(yaw0)
    dx, dy = base[0] - x0, base[1] - y0
    local = (c * dx + s * dy, -s * dx + c * dy, base[2] - yaw0)
    for name, v in zip(d.sim.desc.base_joints, local, strict=True):
        q[d.ik.q_idx[name]] = v
    return q


def _at_limit(d, q, margin=LIMIT_MARGIN):
    idx = [d.ik.q_idx[n] for n in d.sim.desc.arm_joints]
    return bool(np.any(q[idx] < d.ik.lower[idx] + margin) or np.any(q[idx] > d.ik.upper[idx] - margin))


def reach(d, base, targets, *, tol=0.004):
    """``part_planning.reach`` before issue 12 (with the old ``Clik.solve``)."""
    from stages.simulate.control import Clik

    q = base_q(d, base)
    out = []
    for k, t in enumerate(targets):
        res = clik_solve(d.ik, Clik.world_to_root(d.sim.spawn, t), q, max_iters=300,
                         restarts=6 if k == 0 else 0, rng=np.random.default_rng(k))
        if res.position_error > tol or res.rotation_error > math.radians(2.0) or _at_limit(d, res.q):
            break
        q = res.q
        out.append(d.ik.arm_q(q))
    return out


def _robust(d, base, part: ArticulatedPart, targets) -> bool:
    away = np.asarray(base[:2]) - np.asarray(part.handle[:2])
    away = away / max(np.linalg.norm(away), 1e-9) * BASE_SLACK
    shifted = (base[0] + float(away[0]), base[1] + float(away[1]), base[2])
    return len(reach(d, shifted, targets, tol=0.006)) == len(targets)


def plan_stage(d, part: ArticulatedPart, grid, q0, qs, mode="grasp", max_checks=70):
    """``part_planning.plan_stage`` before issue 12."""
    z = float(part.handle_at(q0)[2])
    vertical = abs(float(np.asarray(part.axis)[2])) > 0.7
    p0 = door_pitch(z) if vertical else drawer_pitch(z)
    best = (None, 0.0, -1, [], 0.0)
    checks = 0
    bases = _swing_bases(part, grid, q0, qs)
    if mode == "edge":
        bar = np.asarray(part.bar_axis, float)[:2]
        bases.sort(key=lambda b: abs(abs(float(np.dot(np.asarray(b[:2]) - part.handle[:2], bar))) - EDGE_SIDE))
        max_checks = 3 * max_checks
    for base in bases:
        for pitch, along in grips(part, base, p0, vertical, edge=mode == "edge"):
            approach, arc = gesture(part, q0, qs, pitch, mode, along)
            sols = reach(d, base, approach + arc)
            n = len(sols) - len(approach)
            checks += 1
            if n > best[2] and _robust(d, base, part, approach + arc[:max(n, 0)]):
                best = (base, pitch, n, sols, along)
                if n == len(qs):
                    return best
            if checks >= max_checks:
                break
        if checks >= max_checks:
            break
    if best[0] is None or best[2] < 0:
        raise ExpertFailure("no_base_pose", f"{part.joint_path}: no base pose of {checks} reaches the handle")
    return best
