"""Upper-body closed-loop inverse kinematics per arm, batched over worlds (numpy + Pinocchio).

Each iteration, for every world and arm still short of its target:

- the error ``e`` is the SE(3) log of (current end-effector pose)^-1 (target), in the
  end-effector frame (6,); an arm with ``orientation = false`` tracks position only:
  ``e = R^T (p_target - p)`` (3,) with the Jacobian's linear rows;
- damped least squares on the arm's joints only: ``dq = J+ e + (I - J+ J) k (q_posture - q)``,
  ``J+ = J^T (J J^T + lambda I)^-1``: the secondary task pulls the arm towards its posture (the
  spec's default pose) in the null space of the end-effector task;
- joint limits: weighted least norm (a joint slows down as it nears a limit it moves towards);
  joints at a limit whose step points outwards drop out of J for that step (they would only be
  clipped back); every iterate is clipped to the limits; the step norm is capped.

Every other joint (legs, waist, the other arm, fingers) keeps its value in ``q0``: with a legged
base, the locomotion policy holds the legs and the waist, and the arms are solved in the pelvis
(root-link) frame. Targets and results are in the root-link frame (:mod:`stages.embodiment.kinematics`).
Solves that end in a local minimum may restart from random in-limit arm configurations.

The linear algebra is batched over worlds with numpy; forward kinematics and Jacobians are one
Pinocchio call per world and iteration (about 20 us for a 29-joint humanoid).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from stages.embodiment.kinematics import Kinematics
from stages.embodiment.spec import EmbodimentError, EmbodimentSpec


@dataclass(frozen=True, kw_only=True)
class ClikConfig:
    """damping: lambda of the damped least squares [m^2 ~ rad^2]; max_step: largest joint step per
    iteration (norm over the arm) [rad]; posture_gain: fraction of the posture error removed per
    iteration in the null space [-]; pos_tol [m] / rot_tol [rad]: convergence; max_iters;
    restarts: further solves from random arm configurations for arms that did not converge;
    limit_weight: factor on |dH/dq| in the joint-limit weights (0: plain damped least squares).

    Measured on the G1 (tests/stages/test_embodiment_clik.py's sampling, 10 seeds x 24 worlds x 2
    arms, targets from random joint configurations 10 % inside the limits, start at the default
    pose): 16 restarts reach 479/480 within 1 mm / 0.01 rad (the last within 1.4 mm), all within
    1 cm / 5 deg; 8 restarts 473/480; plain clipping instead of the limit weights 476/480 with 8."""

    damping: float = 1e-4
    max_step: float = 0.3
    posture_gain: float = 0.05
    pos_tol: float = 1e-3
    rot_tol: float = 1e-2
    max_iters: int = 200
    restarts: int = 0
    limit_weight: float = 1.0


@dataclass(frozen=True)
class ClikResult:
    """q (W, nq): solved configurations; position_error (W, A) [m] and rotation_error (W, A) [rad]
    (0 where the arm does not track orientation), arms in the order solved (``arms``);
    success (W, A): within the tolerances; iterations: of the last solve."""

    q: np.ndarray
    arms: tuple[str, ...]
    position_error: np.ndarray
    rotation_error: np.ndarray
    success: np.ndarray
    iterations: int


@dataclass(frozen=True)
class _Arm:
    name: str
    frame: int
    q_idx: np.ndarray     # (n,) configuration indices of the arm joints
    v_idx: np.ndarray     # (n,) velocity indices
    lower: np.ndarray
    upper: np.ndarray
    orientation: bool


class UpperBodyClik:
    """CLIK of a spec's arms on its Pinocchio model (``stages.embodiment.kinematics.build_model``)."""

    def __init__(self, spec: EmbodimentSpec, model, config: ClikConfig | None = None) -> None:
        import pinocchio as pin

        self._pin = pin
        self.spec, self.model, self.config = spec, model, config or ClikConfig()
        self.kin = Kinematics(spec, model)
        self.data = model.createData()
        self.arms: dict[str, _Arm] = {}
        for a in spec.arms:
            ids = [model.getJointId(n) for n in a.joints]
            bad = [n for n, j in zip(a.joints, ids, strict=True)
                   if j >= model.njoints or model.joints[j].nq != 1 or model.joints[j].nv != 1]
            if bad or not model.existFrame(a.ee_frame):
                raise EmbodimentError(f"{spec.name}: arm {a.name!r}: joints {bad} missing or not 1-DoF, "
                                      f"or no frame {a.ee_frame!r}")
            qi = np.array([model.joints[j].idx_q for j in ids])
            self.arms[a.name] = _Arm(a.name, model.getFrameId(a.ee_frame), qi,
                                     np.array([model.joints[j].idx_v for j in ids]),
                                     model.lowerPositionLimit[qi].copy(), model.upperPositionLimit[qi].copy(),
                                     a.orientation)

    def default_q(self) -> np.ndarray:
        return self.kin.default_q()

    def ee_pose(self, q: np.ndarray, arm: str) -> np.ndarray:
        return self.kin.ee_pose(q, arm)

    # -- solving --------------------------------------------------------------------------------
    def solve(self, targets: Mapping[str, np.ndarray], q0: np.ndarray | None = None, *,
              posture: np.ndarray | None = None, rng: np.random.Generator | None = None) -> ClikResult:
        """Move each arm named in ``targets`` (arm -> target poses (W, 4, 4), or (4, 4) for one
        world, root-link frame) from ``q0`` ((W, nq) or (nq,); default: the spec's default pose).
        ``posture`` (nq,) or (W, nq): the null-space target (default: the default pose).
        ``rng``: for ``config.restarts``."""
        names = tuple(targets)
        unknown = [n for n in names if n not in self.arms]
        if unknown:
            raise EmbodimentError(f"{self.spec.name}: no arms {unknown} (arms: {list(self.arms)})")
        goals = {n: np.asarray(t, float).reshape(-1, 4, 4) for n, t in targets.items()}
        nw = max(len(g) for g in goals.values())
        goals = {n: np.broadcast_to(g, (nw, 4, 4)) for n, g in goals.items()}
        q = np.broadcast_to(self.default_q() if q0 is None else np.asarray(q0, float), (nw, self.model.nq)).copy()
        post = np.broadcast_to(self.default_q() if posture is None else np.asarray(posture, float),
                               (nw, self.model.nq))
        q, pe, re, it = self._iterate(q, goals, post, np.ones((nw, len(names)), bool))
        for _ in range(self.config.restarts):
            failed = ~self._ok(pe, re)
            if not failed.any():
                break
            if rng is None:
                raise ValueError("ClikConfig.restarts needs an rng")
            q1 = q.copy()
            for k, n in enumerate(names):
                arm = self.arms[n]
                rows = np.flatnonzero(failed[:, k])
                q1[np.ix_(rows, arm.q_idx)] = rng.uniform(arm.lower, arm.upper, (len(rows), len(arm.q_idx)))
            q2, pe2, re2, it = self._iterate(q1, goals, post, failed)
            better = (pe2 + 0.1 * re2 < pe + 0.1 * re) & failed
            for k, n in enumerate(names):
                rows = np.flatnonzero(better[:, k])
                q[np.ix_(rows, self.arms[n].q_idx)] = q2[np.ix_(rows, self.arms[n].q_idx)]
            pe, re = np.where(better, pe2, pe), np.where(better, re2, re)
        return ClikResult(q=q, arms=names, position_error=pe, rotation_error=re, success=self._ok(pe, re),
                          iterations=it)

    def _ok(self, pe: np.ndarray, re: np.ndarray) -> np.ndarray:
        return (pe < self.config.pos_tol) & (re < self.config.rot_tol)

    def _errors(self, q: np.ndarray, goals, names, active: np.ndarray, jacobians: bool):
        """Per world and arm: position and rotation errors (W, A), task errors and Jacobians."""
        pin, model, data = self._pin, self.model, self.data
        nw = len(q)
        pe, re = np.zeros((nw, len(names))), np.zeros((nw, len(names)))
        err = {n: np.zeros((nw, 6 if self.arms[n].orientation else 3)) for n in names}
        jac = {n: np.zeros((nw, err[n].shape[1], len(self.arms[n].v_idx))) for n in names}
        root_id = self.kin.root
        for w in np.flatnonzero(active.any(axis=1)):
            if jacobians:
                pin.computeJointJacobians(model, data, q[w])
            else:
                pin.forwardKinematics(model, data, q[w])
            pin.updateFramePlacements(model, data)
            root = data.oMf[root_id]
            for k, n in enumerate(names):
                arm = self.arms[n]
                cur = root.actInv(data.oMf[arm.frame])
                goal = pin.SE3(goals[n][w][:3, :3], goals[n][w][:3, 3])
                dp = goal.translation - cur.translation
                pe[w, k] = np.linalg.norm(dp)
                if arm.orientation:
                    re[w, k] = np.linalg.norm(pin.log3(cur.rotation.T @ goal.rotation))
                    err[n][w] = pin.log6(cur.actInv(goal)).vector
                else:
                    err[n][w] = cur.rotation.T @ dp
                if jacobians and active[w, k]:
                    j6 = pin.getFrameJacobian(model, data, arm.frame, pin.LOCAL)[:, arm.v_idx]
                    jac[n][w] = j6 if arm.orientation else j6[:3]
        return pe, re, err, jac

    def _iterate(self, q: np.ndarray, goals, post: np.ndarray, active: np.ndarray):
        cfg = self.config
        names = tuple(goals)
        active = active.copy()
        it = 0
        for it in range(1, cfg.max_iters + 1):  # noqa: B007 (the count is reported)
            pe, re, err, jac = self._errors(q, goals, names, active, jacobians=True)
            active &= ~self._ok(pe, re)
            if not active.any():
                break
            for k, n in enumerate(names):
                rows = np.flatnonzero(active[:, k])
                if len(rows):
                    arm = self.arms[n]
                    qa = q[np.ix_(rows, arm.q_idx)]
                    q[np.ix_(rows, arm.q_idx)] = self._step(arm, qa, jac[n][rows], err[n][rows],
                                                            post[np.ix_(rows, arm.q_idx)])
        pe, re, _, _ = self._errors(q, goals, names, np.ones_like(active), jacobians=False)
        return q, pe, re, it

    def _step(self, arm: _Arm, qa: np.ndarray, jac: np.ndarray, err: np.ndarray, post: np.ndarray) -> np.ndarray:
        """One damped-least-squares step for R worlds: qa (R, n), jac (R, m, n), err (R, m).

        Weighted least norm (Chan and Dubey 1995): a joint moving towards its nearer limit is
        weighted by 1 + |dH/dq| with H = sum (u - l)^2 / (4 (u - q)(q - l)), so it slows down as
        it approaches the limit instead of sticking there; a joint at a limit that the step pushes
        outwards is dropped from the step."""
        cfg = self.config
        n = qa.shape[1]
        lo, hi = arm.lower, arm.upper
        grad = (hi - lo) ** 2 * (2 * qa - hi - lo) / (4 * np.maximum((hi - qa) * (qa - lo), 1e-12) ** 2)
        scale = np.ones_like(qa)     # 1 / sqrt(weight); 0: the joint does not move this step
        dq = np.zeros_like(qa)
        for _ in range(3):
            j = jac * scale[:, None, :]
            a = j @ np.swapaxes(j, 1, 2) + cfg.damping * np.eye(j.shape[1])
            jp = scale[:, :, None] * (np.swapaxes(j, 1, 2) @ np.linalg.inv(a))   # (R, n, m)
            null = np.eye(n) - jp @ jac                                          # (R, n, n)
            dq = (jp @ err[..., None])[..., 0] + cfg.posture_gain * (null @ (post - qa)[..., None])[..., 0]
            dq *= scale > 0
            towards = np.sign(dq) == np.sign(grad)
            pushing = ((qa <= lo + 1e-9) & (dq < 0)) | ((qa >= hi - 1e-9) & (dq > 0))
            new = np.where(pushing, 0.0, np.where(towards, 1.0 / np.sqrt(1.0 + cfg.limit_weight * np.abs(grad)), scale))
            if np.allclose(new, scale):
                break
            scale = np.minimum(scale, new)
        norm = np.linalg.norm(dq, axis=1, keepdims=True)
        dq *= np.minimum(1.0, cfg.max_step / np.maximum(norm, 1e-12))
        return np.clip(qa + dq, lo, hi)


def sample_reachable_targets(clik: UpperBodyClik, arm: str, count: int, rng: np.random.Generator, *,
                             q0: np.ndarray | None = None, margin: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """``count`` reachable end-effector poses of ``arm`` (count, 4, 4), root-link frame: forward
    kinematics of arm configurations drawn uniformly inside the joint limits shrunk by ``margin``
    (fraction of each range) on each side, other joints at ``q0`` (default pose). Returns the poses
    and the sampled configurations (count, nq)."""
    a = clik.arms[arm]
    base = clik.default_q() if q0 is None else np.asarray(q0, float)
    span = a.upper - a.lower
    q = np.repeat(base[None], count, axis=0)
    q[:, a.q_idx] = rng.uniform(a.lower + margin * span, a.upper - margin * span, (count, len(a.q_idx)))
    return clik.ee_pose(q, arm), q

