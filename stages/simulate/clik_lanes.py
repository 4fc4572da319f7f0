"""Many independent CLIK solves run in lockstep ("lanes"), each with the same iterates, bit for
bit, as :meth:`stages.simulate.control.Clik.solve` computes alone.

A *job* is a generator that yields solve requests ``(target, q0, max_iters, pos_tol, rot_tol)``
(target 4x4 in the robot root frame, q0 a Pinocchio configuration (nq,)), is sent each request's
:class:`IkResult`, and returns its value (:func:`solve_job`: one solve with restarts; the planners
chain solves, e.g. ``stages.demos.part_planning``'s reach). :func:`lockstep` runs up to ``width``
jobs at a time: per iteration every running solve gets its kinematics, SE(3) log error and
Jacobian from Pinocchio (one after another, on the Clik's one ``data``), and the damped
least-squares algebra of all of them is one batched numpy call each (``matmul`` on stacks of the
same column-major matrices a lone solve multiplies, and ``np.linalg.solve``'s gufunc: the same
BLAS / LAPACK routine per matrix as the lone solve; ``tests/stages/test_expert_fast.py`` checks
the results against the plain loop). A finished solve hands its result to its job, whose next
request takes the freed lane in the next iteration.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numpy.linalg import _umath_linalg

from stages.simulate.cooperative import checkpoint

# np.linalg.solve's gufunc for one right-hand side: the same LAPACK call without the wrapper's
# checks (the damped J J^T + lambda I it solves is positive definite)
_solve1 = _umath_linalg.solve1


#: :func:`lockstep` starts a job at most this many widths after the first not yet done
LOOKAHEAD = 2


@dataclass(frozen=True)
class IkResult:
    """q: full Pinocchio configuration (nq,); success: within tolerance; position_error [m];
    rotation_error [rad]; iterations."""

    q: np.ndarray
    success: bool
    position_error: float
    rotation_error: float
    iterations: int


def solve_job(ik, target, q0, *, max_iters: int = 300, pos_tol: float = 1e-4, rot_tol: float = 1e-3,
              restarts: int = 0, rng=None):
    """A job (see the module doc) computing ``ik.solve(target, q0, ...)``: the solve from q0,
    then up to ``restarts`` solves from random arm configurations drawn from ``rng`` (a
    generator, or a callable returning one, called only when a restart is needed) while none
    succeeded; returns the best :class:`IkResult`."""
    best = yield (target, q0, max_iters, pos_tol, rot_tol)
    idx = ik.v_idx[: len(ik.desc.arm_joints)]
    for _ in range(restarts if not best.success else 0):
        if rng is None:
            raise ValueError("restarts need an rng")
        if callable(rng):
            rng = rng()
        q = np.asarray(q0, float).copy()
        q[idx] = rng.uniform(ik.lower[idx], ik.upper[idx])
        res = yield (target, q, max_iters, pos_tol, rot_tol)
        if res.position_error + 0.1 * res.rotation_error < best.position_error + 0.1 * best.rotation_error:
            best = res
        if best.success:
            break
    return best


def run_job(ik, job):
    """The value of one job, its solves run one after another by ``ik._solve`` (a lone job gains
    nothing from lanes)."""
    result = None
    while True:
        try:
            target, q0, max_iters, pos_tol, rot_tol = job.send(result)
        except StopIteration as e:
            return e.value
        result = ik._solve(target, q0, max_iters, pos_tol, rot_tol)


class _Lane:
    __slots__ = ("k", "job", "goal", "q", "best", "best_it", "it", "max_iters", "pos_tol", "rot_tol")

    def __init__(self, ik, k: int, job, req) -> None:
        target, q0, self.max_iters, self.pos_tol, self.rot_tol = req
        self.k, self.job = k, job
        self.goal = ik._pin.SE3(np.asarray(target, float))
        self.q = np.clip(np.asarray(q0, float).copy(), ik.lower, ik.upper)
        self.best, self.best_it, self.it = math.inf, 0, 0


def lockstep(ik, jobs, width=32):
    """Run the ``jobs`` (an iterable of job generators, taken as lanes free up) ``width`` at a
    time (``width``: a number, or a function of how many values were yielded so far, so that a
    caller that may stop early can start narrow; a job starts at most LOOKAHEAD ``width`` after the
    first whose value is not yielded yet); yields ``(index, value)`` in the jobs' order as soon
    as each and all before it are done (the caller may stop early; jobs not started are never
    taken). The wall time is added to ``ik.seconds`` where the Clik counts its solve time there."""
    jobs = enumerate(jobs)
    lanes: list[_Lane] = []
    done: dict[int, object] = {}
    nxt, started, more = 0, 0, True
    timed = hasattr(ik, "seconds")

    def advance(k: int, job, result) -> None:
        try:
            req = job.send(result)
        except StopIteration as e:
            done[k] = e.value
        else:
            lanes.append(_Lane(ik, k, job, req))

    while True:
        checkpoint()  # between iterations (no lane is mid-kinematics): another world may run here
        t0 = time.perf_counter()
        w = width(nxt) if callable(width) else width
        while more and len(lanes) < w and started < nxt + LOOKAHEAD * w:
            try:
                k, job = next(jobs)
            except StopIteration:
                more = False
            else:
                started += 1
                advance(k, job, None)
        if lanes:
            finished = _iterate(ik, lanes)
            lanes = [ln for ln in lanes if ln not in finished]
            for ln, res in finished.items():
                advance(ln.k, ln.job, res)
        if timed:
            ik.seconds += time.perf_counter() - t0
        while nxt in done:
            yield nxt, done.pop(nxt)
            nxt += 1
        if not lanes and not more and not done:
            return


def _iterate(ik, lanes: list[_Lane]) -> dict:
    """One iteration of ``Clik._solve`` for every lane; returns {lane: IkResult} of those that
    finished (converged, stalled, or out of iterations). The norms are ``np.vecdot`` of the rows
    (the ``dot`` a lone solve takes of each)."""
    pin = ik._pin
    model, data, frame, cols = ik.model, ik.data, ik.frame, ik._cols
    upd, getj, local, sqrt = pin.updateFramePlacement, pin.getFrameJacobian, pin.LOCAL, math.sqrt
    finished: dict = {}
    buf = np.empty((len(lanes), len(ik.v_idx), 6))  # J^T per lane: J is the column-major (6, n) view
    jac = buf.transpose(0, 2, 1)
    err = np.empty((len(lanes), 6))
    live = []
    for ln in lanes:
        if ln.it >= ln.max_iters:  # out of iterations: the kinematics of the last iterate
            pin.forwardKinematics(model, data, ln.q)
            finished[ln] = _result(ik, ln, upd(model, data, frame))
            continue
        ln.it += 1
        pin.computeJointJacobians(model, data, ln.q)
        k = len(live)
        err[k] = pin.log6(upd(model, data, frame).actInv(ln.goal)).vector
        jac[k] = getj(model, data, frame, local)[:, cols]
        live.append(ln)
    if not live:
        return finished
    k = len(live)
    buf, err = buf[:k], err[:k]
    pes = np.sqrt(np.vecdot(err[:, :3], err[:, :3])).tolist()
    res = np.sqrt(np.vecdot(err[:, 3:], err[:, 3:])).tolist()
    moving, rows = [], []
    for j, (ln, pe, re) in enumerate(zip(live, pes, res, strict=True)):
        if pe < ln.pos_tol and re < ln.rot_tol:
            finished[ln] = None
            continue
        # stalled (a joint limit, an unreachable target): no 0.1% progress in STALL_ITERS
        e = pe + 0.1 * re
        if e < ln.best * (1.0 - 1e-3):
            ln.best, ln.best_it = e, ln.it
        elif ik.stall_iters and ln.it - ln.best_it >= ik.stall_iters:
            finished[ln] = None
            continue
        moving.append(ln)
        rows.append(j)
    for ln in [ln for ln, r in finished.items() if r is None]:  # the kinematics of its last iterate again
        pin.forwardKinematics(model, data, ln.q)
        finished[ln] = _result(ik, ln, upd(model, data, frame))
    if not moving:
        return finished
    if len(moving) < k:
        buf, err = buf[rows], err[rows]
    k = len(moving)
    jac = buf.transpose(0, 2, 1)
    x = _solve1(jac @ buf + ik._damp, err, signature="dd->d")
    dv = np.matmul(buf, x[:, :, None])[:, :, 0]
    n = np.sqrt(np.vecdot(dv, dv))
    over = n > ik.max_step
    if over.any():
        dv[over] *= (ik.max_step / n[over])[:, None]
    if ik._additive:
        v = np.zeros((k, model.nv))
        v[:, cols] = dv
        q = np.minimum(np.maximum(np.stack([ln.q for ln in moving]) + v, ik.lower), ik.upper)
        for ln, row in zip(moving, q, strict=True):
            ln.q = row
    else:
        for ln, row in zip(moving, dv, strict=True):
            v = np.zeros(model.nv)
            v[cols] = row
            ln.q = np.minimum(np.maximum(pin.integrate(model, ln.q, v), ik.lower), ik.upper)
    return finished


def _result(ik, ln: _Lane, m) -> IkResult:
    """The result of a lane's solve with end-effector placement ``m`` (its last iterate's)."""
    g, sqrt = ln.goal, math.sqrt
    dp = m.translation - g.translation
    pe = sqrt(dp.dot(dp))
    r = ik._pin.log3(m.rotation.T @ g.rotation)
    re = sqrt(r.dot(r))
    return IkResult(q=ln.q, success=pe < max(ln.pos_tol, 1e-3) and re < max(ln.rot_tol, 1e-2),
                    position_error=pe, rotation_error=re, iterations=ln.it)


def solve_lanes(ik, targets, q0s, *, max_iters: int = 300, pos_tol: float = 1e-4, rot_tol: float = 1e-3,
                restarts: int = 0, rngs=None, width: int = 32) -> list[IkResult]:
    """``[ik.solve(t, q0, ..., rng=r) for t, q0, r in zip(targets, q0s, rngs)]`` in lockstep;
    ``rngs``: one generator per solve (for ``restarts``)."""
    jobs = (solve_job(ik, t, q0, max_iters=max_iters, pos_tol=pos_tol, rot_tol=rot_tol, restarts=restarts,
                      rng=None if rngs is None else rngs[i])
            for i, (t, q0) in enumerate(zip(targets, q0s, strict=True)))
    return [v for _, v in lockstep(ik, jobs, width)]
