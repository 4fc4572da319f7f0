"""Physical check of a layout in Newton: load the layout USD (``ModelBuilder.add_usd``), release a
sphere on the top step of a straight staircase with a push down the stairs, and record its path.

Newton's USD importer (``add_usd``) needs the ``newton-usd-schemas`` package; where it is not
installed, ``add_layout_to_builder`` falls back to reading the layout's colliders (``Cube`` prims with
``UsdPhysics.CollisionAPI``) with pxr and adding them as static boxes, so the check still runs.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stages.layout.floorplan import FloorPlan, StairModel


@dataclass(frozen=True, eq=False)
class SphereRun:
    """path: (T, 3) sphere centers [m] every ``dt`` seconds; start: release point [m];
    colliders: (K, 2, 3) static collider boxes (lo, hi) of the layout as loaded [m];
    loader: "add_usd" or "pxr" (see ``add_layout_to_builder``)."""

    path: np.ndarray
    start: np.ndarray
    dt: float
    radius: float
    colliders: np.ndarray
    loader: str


def stair_release_point(plan: FloorPlan, stair: StairModel, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """(center above the top tread [m], unit direction down the stairs) of a straight staircase."""
    if stair.shape != "straight":
        raise ValueError(f"{stair.id}: release point defined for straight staircases, got {stair.shape}")
    x0, y0, x1, y1 = stair.footprint[0]
    d = np.array([*stair.direction, 0.0])
    center = np.array([(x0 + x1) / 2, (y0 + y1) / 2, 0.0])
    length = abs((x1 - x0) * d[0]) + abs((y1 - y0) * d[1])
    top = center + d * (length / 2 - stair.run / 2)
    z = plan.floors[stair.floor_from].elevation + (stair.n_risers - 1) * stair.rise + radius + 0.02
    return np.array([top[0], top[1], z]), -d


def has_newton_usd_importer() -> bool:
    """Whether Newton's ``add_usd`` can run here (it needs ``newton-usd-schemas``)."""
    import importlib.util

    return importlib.util.find_spec("newton_usd_schemas") is not None


def add_layout_to_builder(builder, usd_path: Path) -> str:
    """Add the layout's static colliders to a ``newton.ModelBuilder``; returns "add_usd" or "pxr"
    (the loader used, see the module docstring)."""
    if has_newton_usd_importer():
        builder.add_usd(str(usd_path), load_visual_shapes=False)
        return "add_usd"
    import warp as wp
    from pxr import Usd, UsdGeom, UsdPhysics

    stage = Usd.Stage.Open(str(usd_path))
    errs = stage.GetCompositionErrors()
    if errs:
        raise ValueError(f"{usd_path}: composition errors: {errs[0]}")
    cache = UsdGeom.XformCache()
    for prim in stage.Traverse():
        if not (prim.IsA(UsdGeom.Cube) and prim.HasAPI(UsdPhysics.CollisionAPI)):
            continue
        m = np.asarray(cache.GetLocalToWorldTransform(prim), dtype=np.float64)
        size = UsdGeom.Cube(prim).GetSizeAttr().Get()
        half = np.linalg.norm(m[:3, :3], axis=1) * size / 2
        if not np.allclose(m[:3, :3], np.diag(np.diag(m[:3, :3])), atol=1e-9):
            raise ValueError(f"{usd_path}: {prim.GetPath()}: rotated collider boxes are not supported")
        builder.add_shape_box(-1, xform=wp.transform(wp.vec3(*map(float, m[3, :3])), wp.quat_identity()),
                              hx=float(half[0]), hy=float(half[1]), hz=float(half[2]), label=str(prim.GetPath()))
    return "pxr"


def _static_boxes(model) -> np.ndarray:
    """(K, 2, 3) world boxes of the static box shapes of a finalized model."""
    import newton

    types = model.shape_type.numpy()
    bodies = model.shape_body.numpy()
    xf = model.shape_transform.numpy()
    scale = model.shape_scale.numpy()
    out = []
    for k in np.nonzero((types == int(newton.GeoType.BOX)) & (bodies == -1))[0]:
        c, h = xf[k, :3], scale[k, :3]
        out.append((c - h, c + h))
    return np.asarray(out, dtype=np.float64).reshape(-1, 2, 3)


def roll_sphere_down_stairs(usd_path: Path, plan: FloorPlan, *, stair: int = 0, radius: float = 0.1,
                            push: float = 2.0, seconds: float = 3.0, fps: int = 100, substeps: int = 5,
                            device: str = "cpu") -> SphereRun:
    """Simulate a sphere (radius [m], push [m/s] down the stairs) released on the top step of
    ``plan.stairs[stair]`` (a ground plane at z = 0 stands for the ground outside the house);
    returns its path sampled at ``fps``."""
    import warp as wp

    import newton

    st = plan.stairs[stair]
    start, down = stair_release_point(plan, st, radius)
    b = newton.ModelBuilder()
    b.default_shape_cfg.mu = 0.6
    loader = add_layout_to_builder(b, usd_path)
    b.add_ground_plane()  # the ground outside the house, level with the ground floor
    body = b.add_body(xform=wp.transform(wp.vec3(*map(float, start)), wp.quat_identity()), label="ball")
    b.add_shape_sphere(body, radius=radius, cfg=newton.ModelBuilder.ShapeConfig(density=500.0, mu=0.6))
    model = b.finalize(device=device)
    solver = newton.solvers.SolverXPBD(model, iterations=8, angular_damping=0.05)
    s0, s1 = model.state(), model.state()
    control = model.control()
    qd = s0.body_qd.numpy()
    qd[body, :3] = down * push
    s0.body_qd.assign(qd)
    pipeline = newton.CollisionPipeline(model)
    contacts = pipeline.contacts()
    dt = 1.0 / fps / substeps
    path = [start.copy()]
    for _ in range(int(seconds * fps)):
        for _ in range(substeps):
            s0.clear_forces()
            pipeline.collide(s0, contacts)
            solver.step(s0, s1, control, contacts, dt)
            s0, s1 = s1, s0
        path.append(s0.body_q.numpy()[body, :3].astype(np.float64))
    return SphereRun(np.asarray(path), start, 1.0 / fps, radius, _static_boxes(model), loader)


def penetrations(run: SphereRun, tol: float = 0.03) -> list[tuple[int, int]]:
    """(sample, collider) pairs where the sphere center came closer than radius - tol to a box,
    i.e. passed into a wall, slab or step."""
    lo, hi = run.colliders[:, 0], run.colliders[:, 1]
    out = []
    for i, p in enumerate(run.path):
        d = np.maximum(np.maximum(lo - p, p - hi), 0.0)
        dist = np.linalg.norm(d, axis=1)
        inside = np.all((p > lo) & (p < hi), axis=1)
        for k in np.nonzero(inside | (dist < run.radius - tol))[0]:
            out.append((i, int(k)))
    return out
