"""Physics settle check of a composed scene in Newton (no robot).

The scene USD is loaded with ``newton.ModelBuilder.add_usd`` (the same loader the simulate stage
uses) into ``SolverMuJoCo`` (4 ms steps as in ``stages.physics_checks``; multi-CCD contacts, see
IMPRATIO), and the MuJoCo model Newton built is stepped on MuJoCo's C engine (CPU) for ``seconds``;
every point of every dynamic body's colliders is compared between the first and the last state: an
instance whose colliders moved more than ``tolerance`` [m] (1 cm) fails the check. The report names
the offenders so the caller can repair the scene (drop them) or reject it.

Speed: MuJoCo is stepped directly (``mujoco.mj_step``, no per-step Newton state round trip), and
the simulation may stop before ``seconds`` once every body is still (``StillExit``): the
verdict is the full run's, as long as no body that has been still for 0.3 s starts moving again.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Collection
from dataclasses import dataclass
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
    nan: the simulation produced NaN; bodies, shapes: counts in the Newton model; seconds: the
    settle time asked for [s]; simulated: the time actually simulated [s] (less than ``seconds``
    when the early exit found every body still, see ``settle_check``); wall_seconds: time it took [s]."""

    model_config = ConfigDict(frozen=True)

    passed: bool
    tolerance: float
    moved: dict[str, float]
    offenders: tuple[str, ...]
    nan: bool
    bodies: int
    shapes: int
    seconds: float
    simulated: float
    wall_seconds: float


def _instance_of(label: str) -> str | None:
    if OBJECTS_PREFIX not in label:
        return None
    return label.split(OBJECTS_PREFIX, 1)[1].split("/", 1)[0]


def load_scene_builder(scene_usd: Path, *, contact_ke: float = CONTACT_KE, contact_kd: float = CONTACT_KD,
                       instances: Collection[str] | None = None):
    """A ``newton.ModelBuilder`` holding the scene (layout colliders + every asset), via add_usd;
    ``instances``: only these instances of /World/Objects (and the layout), None: all."""
    import newton
    from newton.solvers import SolverMuJoCo

    import usd_schemas  # noqa: F401  (schema plugin registered before USD's schema registry is built)

    builder = newton.ModelBuilder()
    builder.default_shape_cfg.ke = contact_ke
    builder.default_shape_cfg.kd = contact_kd
    SolverMuJoCo.register_custom_attributes(builder)
    source: object = str(scene_usd)
    if instances is not None:
        from pxr import Usd

        keep = ["/World/Layout", "/World/PhysicsScene", *(f"{OBJECTS_PREFIX}{n}" for n in sorted(instances))]
        source = Usd.Stage.OpenMasked(str(scene_usd), Usd.StagePopulationMask(keep))
    builder.add_usd(source, load_visual_shapes=False, load_static_visual_shapes=False)
    return builder


@dataclass(frozen=True)
class StillExit:
    """Early exit of the settle check once every body is still, without weakening the criterion:
    after at least ``min_seconds`` [s] of simulation, when over each of the last ``chunks`` checks
    (one every ``every`` [s]) no collider point moved more than ``step`` [m], and even if every
    body kept that pace to the end its total displacement would stay within ``margin`` x the
    tolerance. A body that creeps, slides or starts to tip moves more than ``step`` per check and
    keeps the simulation going to the full time."""

    every: float = 0.1
    min_seconds: float = 0.6
    chunks: int = 3
    step: float = 1.0e-4
    margin: float = 0.8


class _Tracker:
    """Collider points of the dynamic bodies, in their MuJoCo body frames, and their displacement
    from the start pose [m], read from MuJoCo's data (body poses xpos, xmat)."""

    def __init__(self, builder, solver):
        from stages.physics_checks import _collider_points_in_bodies

        labels = list(builder.body_label)
        to_newton = solver.mjc_body_to_newton.numpy()[0]
        mjc_of = {int(b): i for i, b in enumerate(to_newton) if b >= 0}
        pts: dict[int, list[np.ndarray]] = {}
        for b, p in _collider_points_in_bodies(builder):
            if b >= 0 and b in mjc_of and _instance_of(labels[b]) is not None:
                pts.setdefault(b, []).append(p)
        self.bodies = sorted(pts)
        self.inst = [_instance_of(labels[b]) for b in self.bodies]
        self.mjc = np.array([mjc_of[b] for b in self.bodies], dtype=np.int64)
        self.points = [np.vstack(pts[b]) for b in self.bodies]

    def world(self, data) -> list[np.ndarray]:
        pos = np.asarray(data.xpos)[self.mjc]
        rot = np.asarray(data.xmat)[self.mjc].reshape(-1, 3, 3)
        return [p @ r.T + t for p, r, t in zip(self.points, rot, pos)]

    @staticmethod
    def moved(a: list[np.ndarray], b: list[np.ndarray]) -> np.ndarray:
        """Per body, largest point displacement between two world-point sets [m] (inf if not finite)."""
        d = np.array([float(np.linalg.norm(x - y, axis=1).max()) for x, y in zip(a, b)])
        return np.where(np.isfinite(d), d, np.inf)


def settle_check(scene_usd: Path, *, seconds: float = 2.0, tolerance: float = 0.01, device: str = "cpu",
                 dt: float = 1.0 / 250.0, early_exit: StillExit | None = StillExit(),
                 instances: Collection[str] | None = None) -> SettleReport:
    """Load ``scene_usd`` in Newton, simulate ``seconds`` [s] with no robot, and report per instance
    how far its colliders moved (see module docstring). On CPU the MuJoCo model Newton built is
    stepped directly (no per-step Newton state round trip), checking every ``early_exit.every``
    seconds; ``early_exit=None`` always simulates the full time. ``instances``: simulate only these
    instances (with the layout; see ``stages.scene.rest.to_simulate``), None: all."""
    import mujoco
    import newton
    import warp as wp

    t0 = time.perf_counter()
    builder = load_scene_builder(Path(scene_usd), instances=instances)
    with wp.ScopedDevice(device):
        model = builder.finalize(device=device)
        solver = newton.solvers.SolverMuJoCo(model, use_mujoco_cpu=wp.get_device(device).is_cpu, iterations=50,
                                             ls_iterations=20, integrator="implicitfast", cone="elliptic",
                                             impratio=IMPRATIO, use_mujoco_contacts=True, enable_multiccd=True)
        if not solver.use_mujoco_cpu:
            raise ValueError(f"{scene_usd}: the settle check steps MuJoCo's CPU engine; device {device!r} is not a CPU")
        m, d = solver.mj_model, solver.mj_data
        m.opt.timestep = dt
        mujoco.mj_forward(m, d)
        track = _Tracker(builder, solver)
        start = prev = track.world(d)
        total = max(1, round(seconds / dt))
        chunk = max(1, round((early_exit.every if early_exit else seconds) / dt))
        recent: list[float] = []
        done, nan = 0, False
        while done < total:
            k = min(chunk, total - done)
            mujoco.mj_step(m, d, nstep=k)
            done += k
            cur = track.world(d)
            if not (np.isfinite(d.qpos).all() and all(np.isfinite(c).all() for c in cur)):
                nan = True
                break
            if early_exit and done < total:
                recent.append(float(track.moved(cur, prev).max(initial=0.0)))
                prev = cur
                so_far = float(track.moved(cur, start).max(initial=0.0))
                pace = max(recent[-early_exit.chunks:])
                left = (total - done) / chunk
                if (done * dt >= early_exit.min_seconds and len(recent) >= early_exit.chunks
                        and pace <= early_exit.step and so_far + pace * left <= early_exit.margin * tolerance):
                    break
        end = track.world(d)
    moved: dict[str, float] = {}
    for inst, dist in zip(track.inst, track.moved(end, start)):
        moved[inst] = max(moved.get(inst, 0.0), float(dist))
    offenders = tuple(sorted(k for k, v in moved.items() if v > tolerance))
    rep = SettleReport(passed=not offenders and not nan, tolerance=tolerance, moved=moved, offenders=offenders,
                       nan=nan, bodies=model.body_count, shapes=model.shape_count, seconds=seconds,
                       simulated=round(done * dt, 6), wall_seconds=time.perf_counter() - t0)
    log.debug("settle %s: %s", scene_usd, rep)
    return rep
