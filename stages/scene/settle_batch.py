"""Batched settle: many composed scenes in one Newton model, stepped together by MuJoCo-Warp
(``SolverMuJoCo(use_mujoco_cpu=False)``) on a GPU (or, slowly, on the CPU).

MuJoCo-Warp batches only identical worlds (same bodies and shapes), and no two populated scenes are
identical; so the scenes lie side by side in one Newton world on a grid ``SPACING`` [m] apart
(they cannot touch), one MuJoCo world whose bodies, contacts and constraints MuJoCo-Warp processes in
parallel; the bodies of scene k are a contiguous range of the model's bodies.

The per-scene CPU check (``stages.scene.rest`` + ``stages.scene.settle``) proves rest analytically
and simulates only what it cannot prove; this module simulates every instance of every scene, for a
GPU host that settles scenes in bulk. Building the model does not parse each scene's USD: each asset
package and each layout layer is parsed once with ``newton.ModelBuilder.add_usd`` (kept per
process), and a scene's world is assembled from them with ``add_builder`` at each instance's pose
(from the scene's ``scene.json``); instance labels are ``/World/Objects/<instance>/...`` as in the
scene, so reports name the same instances.

Criterion as in ``settle_check``: every collider point of every dynamic body of an instance is
compared between the first and the last state; an instance that moved more than ``tolerance``
[m] fails. Contact settings, time step and solver options are ``settle_check``'s.
"""

from __future__ import annotations

import json
import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stages.scene.settle import CONTACT_KD, CONTACT_KE, IMPRATIO, OBJECTS_PREFIX, _instance_of

log = logging.getLogger(__name__)

CONTACTS_PER_BODY = 24  # contact capacity per body (multi-CCD: up to 4 points per touching pair)
ROWS_PER_CONTACT = 6    # constraint rows per contact (elliptic cone, condim 3) plus joint/limit rows
SPACING = 40.0  # [m] between neighbouring scenes of a batch (a house is at most ~25 m across)
CAPACITY_STEP = 1024  # contact / constraint capacities are rounded up to a power of two times this:
# MuJoCo-Warp specialises (compiles) kernels on njmax, so models of similar size share their kernels
DOF_STEP = 32  # degrees of freedom are padded up to a multiple of this (kernels are specialised on nv)
PAD_PREFIX = "/Padding/"
_PARSED: dict[str, object] = {}  # usd path -> ModelBuilder of that package / layout (this process)
_HULLS: dict[tuple[int, bool], object] = {}  # (mesh content hash, certify) -> Newton's hull adjacency


@dataclass(frozen=True)
class BatchSettle:
    """Per scene: moved (instance -> largest collider point displacement [m]), offenders (over
    tolerance), passed; timings [s]: build (assembling the model), finalize, simulate."""

    scenes: tuple[Path, ...]
    moved: tuple[dict[str, float], ...]
    offenders: tuple[tuple[str, ...], ...]
    passed: tuple[bool, ...]
    bodies: int
    shapes: int
    simulated: float
    seconds: dict[str, float]


def _parsed(usd: Path):
    import newton
    from newton.solvers import SolverMuJoCo

    import usd_schemas  # noqa: F401

    key = str(Path(usd).resolve())
    if key not in _PARSED:
        b = newton.ModelBuilder()
        b.default_shape_cfg.ke = CONTACT_KE
        b.default_shape_cfg.kd = CONTACT_KD
        SolverMuJoCo.register_custom_attributes(b)
        b.add_usd(key, load_visual_shapes=False, load_static_visual_shapes=False)
        _PARSED[key] = b
    return _PARSED[key]


def _keep_hull_adjacency() -> None:
    """Newton's ``finalize`` derives each convex collider's hull adjacency (pure Python, a third of a
    one-house model's CPU time) once per finalize, keyed by the mesh's content hash; a process that
    finalizes chunk after chunk of houses built from the same packages keeps them here under the
    same key (the result depends only on the mesh's vertices and indices)."""
    from newton._src.sim import builder as nb

    f = getattr(nb, "_convex_hull_adjacency", None)
    if f is None or getattr(f, "_kept", False):
        return

    def kept(source, *, certify: bool = True):
        k = (hash(source), bool(certify))
        if k not in _HULLS:
            _HULLS[k] = f(source, certify=certify)
        return _HULLS[k]

    kept._kept = True
    nb._convex_hull_adjacency = kept


def scene_layout(scene_usd: Path) -> Path:
    """The layout layer the scene's /World/Layout references (absolute)."""
    from pxr import Sdf

    layer = Sdf.Layer.FindOrOpen(str(scene_usd))
    spec = layer.GetPrimAtPath("/World/Layout") if layer else None
    refs = list(spec.referenceList.GetAddedOrExplicitItems()) if spec else []
    if not refs:
        raise ValueError(f"{scene_usd}: /World/Layout references no layout layer")
    return (Path(scene_usd).parent / refs[0].assetPath).resolve()


def build_worlds(scenes: Sequence[Path]):
    """(a ``newton.ModelBuilder`` holding every scene (layout + every instance of its scene.json),
    scene k at ``offset(k)``, body index where each scene's bodies start (len(scenes) + 1,))."""
    import newton
    import warp as wp
    from newton.solvers import SolverMuJoCo

    main = newton.ModelBuilder()
    main.default_shape_cfg.ke = CONTACT_KE
    main.default_shape_cfg.kd = CONTACT_KD
    SolverMuJoCo.register_custom_attributes(main)
    side = max(1, math.ceil(math.sqrt(len(scenes))))
    starts: list[int] = []
    for k, scene in enumerate(scenes):
        info = json.loads((Path(scene).parent / "scene.json").read_text(encoding="utf-8"))
        ox, oy = offset(k, side)
        starts.append(main.body_count)
        main.add_builder(_parsed(scene_layout(scene)), xform=wp.transform(wp.vec3(ox, oy, 0.0), wp.quat_identity()),
                         label_prefix="/World/Layout")
        for inst in info["instances"]:
            x, y, z = inst["position"]
            half = float(inst["yaw"]) / 2
            xf = wp.transform(wp.vec3(x + ox, y + oy, z), wp.quat(0.0, 0.0, math.sin(half), math.cos(half)))
            main.add_builder(_parsed(Path(inst["usd"])), xform=xf, label_prefix=f"{OBJECTS_PREFIX}{inst['name']}")
    starts.append(main.body_count)
    return main, starts


def pad_dofs(builder, step: int = DOF_STEP) -> int:
    """Add bodies of one revolute degree of freedom each (no shapes, centre of mass on the vertical
    axis: gravity leaves them at rest) until the builder's degrees of freedom are a multiple of
    ``step``, so that chunks of different sizes share MuJoCo-Warp's nv-specialised kernels (each new
    nv is a kernel compile); the number of bodies added."""
    import warp as wp

    n = (-builder.joint_dof_count) % step if step > 0 else 0
    for k in range(n):
        b = builder.add_link(xform=wp.transform(wp.vec3(0.0, 0.0, -100.0 - k), wp.quat_identity()), mass=1.0,
                             inertia=wp.mat33(0.01, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0, 0.01),
                             label=f"{PAD_PREFIX}body_{k}")
        j = builder.add_joint_revolute(-1, b, parent_xform=wp.transform(wp.vec3(0.0, 0.0, -100.0 - k),
                                                                       wp.quat_identity()),
                                       axis=(0.0, 0.0, 1.0), label=f"{PAD_PREFIX}joint_{k}")
        builder.add_articulation([j], label=f"{PAD_PREFIX}articulation_{k}")
    return n


def offset(k: int, side: int) -> tuple[float, float]:
    """(x, y) offset [m] of scene k on a grid of ``side`` columns, centred on the origin."""
    r, c = divmod(k, side)
    return (c - (side - 1) / 2) * SPACING, (r - (side - 1) / 2) * SPACING


def capacity(n: int) -> int:
    """``n`` rounded up to ``CAPACITY_STEP`` times a power of two."""
    c = CAPACITY_STEP
    while c < n:
        c *= 2
    return c


def settle_batch(scenes: Sequence[Path], *, device: str = "cuda:0", seconds: float = 2.0, tolerance: float = 0.01,
                 dt: float = 1.0 / 250.0, progress: bool = True, cuda_graph: bool = False,
                 dof_step: int = DOF_STEP) -> BatchSettle:
    """Settle ``scenes`` together (side by side in one world) for ``seconds`` [s] on ``device`` and
    report per scene which instances moved more than ``tolerance`` [m] (see the module docstring).

    Cost grows faster than the number of scenes (MuJoCo-Warp's model upload enumerates every geom
    pair, the Newton solver factorises a dense nv x nv matrix per world): settle many scenes in
    chunks of a few (``stages.scene.settle_pool``). ``cuda_graph``: step through a captured CUDA
    graph of two steps (CUDA devices only; fewer launches from the CPU). ``dof_step``: see
    ``pad_dofs`` (0: no padding); ``bodies`` counts the scenes' bodies only."""
    import warp as wp
    from newton.solvers import SolverMuJoCo
    from tqdm import tqdm

    from stages.physics_checks import _collider_points_in_bodies

    secs: dict[str, float] = {}
    t = time.perf_counter()
    builder, starts = build_worlds(scenes)
    padding = pad_dofs(builder, dof_step)
    secs["build"] = time.perf_counter() - t
    labels = list(builder.body_label)
    body_world = np.searchsorted(np.asarray(starts), np.arange(builder.body_count), side="right") - 1
    pts: dict[int, list[np.ndarray]] = {}
    for b, p in _collider_points_in_bodies(builder):
        if b >= 0 and _instance_of(labels[b]) is not None:
            pts.setdefault(b, []).append(p)
    bodies = sorted(pts)
    points = [np.vstack(pts[b]) for b in bodies]
    _keep_hull_adjacency()
    with wp.ScopedDevice(device):
        t = time.perf_counter()
        model = builder.finalize(device=device)
        solver = SolverMuJoCo(model, use_mujoco_cpu=False, iterations=50, ls_iterations=20, integrator="implicitfast",
                              cone="elliptic", impratio=IMPRATIO, use_mujoco_contacts=True, enable_multiccd=True,
                              separate_worlds=False, nconmax=capacity(CONTACTS_PER_BODY * model.body_count + 64),
                              njmax=capacity(ROWS_PER_CONTACT * (CONTACTS_PER_BODY * model.body_count + 64)))
        s0, s1, control = model.state(), model.state(), model.control()
        secs["finalize"] = time.perf_counter() - t
        t = time.perf_counter()
        q0 = s0.body_q.numpy().astype(np.float64)
        steps = max(1, round(seconds / dt))
        graph = None
        if cuda_graph and wp.get_device(device).is_cuda and steps >= 2:
            solver.step(s0, s1, control, None, dt)  # the first step outside the capture (lazy allocations)
            s0, s1 = s1, s0
            steps_left = steps - 1
            with wp.ScopedCapture(device=device) as cap:
                solver.step(s0, s1, control, None, dt)
                solver.step(s1, s0, control, None, dt)
            graph = cap.graph
            for _ in range(steps_left // 2):  # the capture itself ran nothing
                wp.capture_launch(graph)
            if steps_left % 2:
                solver.step(s0, s1, control, None, dt)
                s0, s1 = s1, s0
        for _ in tqdm(range(0 if graph is not None else steps), desc="settle worlds", unit="step",
                      disable=not progress, leave=False):
            solver.step(s0, s1, control, None, dt)
            s0, s1 = s1, s0
        q1 = s0.body_q.numpy().astype(np.float64)
        secs["simulate"] = time.perf_counter() - t
    moved: list[dict[str, float]] = [{} for _ in scenes]
    for b, p in zip(bodies, points):
        d = float(np.linalg.norm(_apply(q1[b], p) - _apply(q0[b], p), axis=1).max())
        d = d if math.isfinite(d) else math.inf
        w, inst = int(body_world[b]), _instance_of(labels[b])
        moved[w][inst] = max(moved[w].get(inst, 0.0), d)
    offenders = tuple(tuple(sorted(k for k, v in m.items() if v > tolerance)) for m in moved)
    return BatchSettle(scenes=tuple(Path(s) for s in scenes), moved=tuple(moved), offenders=offenders,
                       passed=tuple(not o for o in offenders), bodies=model.body_count - padding,
                       shapes=model.shape_count, simulated=steps * dt, seconds={k: round(v, 3) for k, v in secs.items()})


def _apply(q: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Points p (K, 3) in a body frame -> world by the Newton transform q (7,) = (pos, quat xyzw)."""
    from scipy.spatial.transform import Rotation

    return p @ Rotation.from_quat(q[3:]).as_matrix().T + q[:3]
