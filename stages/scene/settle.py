"""Physics settle check of a composed scene in Newton (no robot).

The scene USD is loaded with ``newton.ModelBuilder.add_usd`` (the same loader the simulate stage
uses), simulated for ``seconds`` with ``SolverMuJoCo`` (MuJoCo's C engine on CPU, mujoco-warp on
CUDA; 4 ms steps as in ``stages.physics_checks``; multi-CCD contacts, see IMPRATIO), and every point of every dynamic body's colliders
is compared between the first and the last state: an instance whose colliders moved more than
``tolerance`` [m] (1 cm) fails the check. The report names the offenders so the caller can repair
the scene (drop them) or reject it.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict

log = logging.getLogger(__name__)

OBJECTS_PREFIX = "/World/Objects/"
# Contact stiffness [N/m] and damping [N s/m] of shapes without their own: the simulate stage's
# defaults (stages.simulate.world.SimConfig: MuJoCo time constant 5 ms). Newton's own default
# (2.5e3, 100) lets a 1 kg book sink ~2 cm into a table top in MuJoCo.
CONTACT_KE = 4.0e4
CONTACT_KD = 400.0
# MuJoCo's mesh-mesh collision gives one contact point per convex pair unless multi-CCD is on: a book
# on a table top then rocks on that point and walks ~1 cm in 2 s. With multiccd (up to 4 points)
# and impratio 10 (the simulate stage's value) resting objects stay within millimetres.
IMPRATIO = 10.0


class SettleReport(BaseModel):
    """passed: no instance moved more than tolerance; moved: instance -> largest collider point
    displacement [m] (every instance with dynamic bodies); offenders: instances over tolerance;
    nan: the simulation produced NaN; bodies, shapes: counts in the Newton model; seconds: simulated
    time [s]; wall_seconds: time it took [s]."""

    model_config = ConfigDict(frozen=True)

    passed: bool
    tolerance: float
    moved: dict[str, float]
    offenders: tuple[str, ...]
    nan: bool
    bodies: int
    shapes: int
    seconds: float
    wall_seconds: float


def _instance_of(label: str) -> str | None:
    if OBJECTS_PREFIX not in label:
        return None
    return label.split(OBJECTS_PREFIX, 1)[1].split("/", 1)[0]


def load_scene_builder(scene_usd: Path, *, contact_ke: float = CONTACT_KE, contact_kd: float = CONTACT_KD):
    """A ``newton.ModelBuilder`` holding the scene (layout colliders + every asset), via add_usd."""
    import newton
    from newton.solvers import SolverMuJoCo

    import usd_schemas  # noqa: F401  (schema plugin registered before USD's schema registry is built)

    builder = newton.ModelBuilder()
    builder.default_shape_cfg.ke = contact_ke
    builder.default_shape_cfg.kd = contact_kd
    SolverMuJoCo.register_custom_attributes(builder)
    builder.add_usd(str(scene_usd), load_visual_shapes=False, load_static_visual_shapes=False)
    return builder


def settle_check(scene_usd: Path, *, seconds: float = 2.0, tolerance: float = 0.01, device: str = "cpu",
                 dt: float = 1.0 / 250.0) -> SettleReport:
    """Load ``scene_usd`` in Newton, simulate ``seconds`` [s] with no robot, and report per instance
    how far its colliders moved (see module docstring)."""
    import newton
    import warp as wp

    from stages.physics_checks import _collider_points_in_bodies, _transform_points

    t0 = time.perf_counter()
    builder = load_scene_builder(Path(scene_usd))
    labels = list(builder.body_label)
    shapes = [(b, pts) for b, pts in _collider_points_in_bodies(builder) if b >= 0]
    with wp.ScopedDevice(device):
        model = builder.finalize(device=device)
        dev = wp.get_device(device)
        solver = newton.solvers.SolverMuJoCo(model, use_mujoco_cpu=dev.is_cpu, iterations=50, ls_iterations=20,
                                             integrator="implicitfast", cone="elliptic", impratio=IMPRATIO,
                                             use_mujoco_contacts=True, enable_multiccd=True)
        s0, s1, control = model.state(), model.state(), model.control()
        newton.eval_fk(model, model.joint_q, model.joint_qd, s0)
        q_start = s0.body_q.numpy().astype(np.float64).copy()
        for _ in range(max(1, round(seconds / dt))):
            s0.clear_forces()
            solver.step(s0, s1, control, None, dt)
            s0, s1 = s1, s0
        q_end = s0.body_q.numpy().astype(np.float64)
    nan = bool(not np.isfinite(q_end).all())
    moved: dict[str, float] = {}
    for b, pts in shapes:
        inst = _instance_of(labels[b]) if b < len(labels) else None
        if inst is None:
            continue
        d = float(np.linalg.norm(_transform_points(q_end[b], pts) - _transform_points(q_start[b], pts), axis=1).max())
        if not np.isfinite(d):
            d = float("inf")
        moved[inst] = max(moved.get(inst, 0.0), d)
    offenders = tuple(sorted(k for k, v in moved.items() if v > tolerance))
    rep = SettleReport(passed=not offenders and not nan, tolerance=tolerance, moved=moved, offenders=offenders,
                       nan=nan, bodies=model.body_count, shapes=model.shape_count, seconds=seconds,
                       wall_seconds=time.perf_counter() - t0)
    log.debug("settle %s: %s", scene_usd, rep)
    return rep
