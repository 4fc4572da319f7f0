"""Batched settle: many composed scenes in one Newton model, stepped together by MuJoCo-Warp
(``SolverMuJoCo(use_mujoco_cpu=False)``) on a GPU (or, slowly, on the CPU).

Each scene is one world of the model (``build_separate_worlds``): MuJoCo-Warp steps all worlds of a
model with one launch per kernel, and a world's cost (geom pairs, the dense nv x nv factorisation)
stays that of one house. Its worlds must share one structure (same bodies, joints and joint types
in the same order, same non-mesh shapes per body; mesh shapes may differ per world, Newton pads
those slots), which no two populated houses do: each world's instances are grouped by package
structure and the world is padded to the chunk's largest count of each, by copies that do not
collide, far below the floor. ``build_worlds`` instead lays scenes side by side in one world on a
grid ``SPACING`` [m] apart (cost growing faster than the number of scenes). Either way the bodies
of scene k are a contiguous range of the model's bodies.

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

CONTACTS_PER_BODY = 24  # contacts per body the constraint rows are sized for (multi-CCD: up to 4 points a pair)
CONTACT_SLOTS_PER_BODY = 64  # contact capacity per body: MuJoCo's first collision of a house finds
# ~70 per body (most beyond the margin; MuJoCo-Warp keeps ~40), and Newton raises a smaller
# nconmax to that count with a warning (a capacity then different for every chunk)
ROWS_PER_CONTACT = 6    # constraint rows per contact (elliptic cone, condim 3) plus joint/limit rows
SPACING = 40.0  # [m] between neighbouring scenes of a batch (a house is at most ~25 m across)
CAPACITY_STEP = 1024  # contact / constraint capacities are rounded up to a power of two times this:
# MuJoCo-Warp specialises (compiles) kernels on njmax, so models of similar size share their kernels
DOF_STEP = 32  # degrees of freedom are padded up to a multiple of this (kernels are specialised on nv)
PAD_PREFIX = "/Padding/"
PAD_FAR = 1000.0  # [m] below the floor: where padding of a world lies (see ``build_separate_worlds``)
MESH_TYPES = (8, 10)  # newton.GeoType.MESH, CONVEX_MESH: the shapes MuJoCo-Warp's worlds may differ in
_BOX = 7  # newton.GeoType.BOX
_FIXED = 3  # newton.JointType.FIXED
_COLLIDE = 1 << 1  # newton.ShapeFlags.COLLIDE_SHAPES
_PARSED: dict[str, object] = {}  # usd path -> ModelBuilder of that package / layout (this process)
_HULLS: dict[tuple[int, bool], object] = {}  # (mesh content hash, certify) -> Newton's hull adjacency


@dataclass(frozen=True)
class BatchSettle:
    """Per scene: moved (instance -> largest collider point displacement [m]), offenders (over
    tolerance), passed; bodies and shapes of the scenes (padding not counted); timings [s]: build
    (assembling the model), finalize, simulate (and capture, when stepped by a CUDA graph)."""

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


def _placed(scene: Path, ox: float = 0.0, oy: float = 0.0) -> list[tuple[str, object, object]]:
    """(label prefix, parsed package builder, pose) of the scene's layout and each instance of its
    scene.json, shifted by (ox, oy) [m]."""
    import warp as wp

    info = json.loads((Path(scene).parent / "scene.json").read_text(encoding="utf-8"))
    out = [("/World/Layout", _parsed(scene_layout(scene)), wp.transform(wp.vec3(ox, oy, 0.0), wp.quat_identity()))]
    for inst in info["instances"]:
        x, y, z = inst["position"]
        half = float(inst["yaw"]) / 2
        xf = wp.transform(wp.vec3(x + ox, y + oy, z), wp.quat(0.0, 0.0, math.sin(half), math.cos(half)))
        out.append((f"{OBJECTS_PREFIX}{inst['name']}", _parsed(Path(inst["usd"])), xf))
    return out


def _main_builder():
    import newton
    from newton.solvers import SolverMuJoCo

    main = newton.ModelBuilder()
    main.default_shape_cfg.ke = CONTACT_KE
    main.default_shape_cfg.kd = CONTACT_KD
    SolverMuJoCo.register_custom_attributes(main)
    return main


def build_worlds(scenes: Sequence[Path]):
    """(a ``newton.ModelBuilder`` holding every scene (layout + every instance of its scene.json)
    side by side in one world, scene k at ``offset(k)``, body index where each scene's bodies start
    (len(scenes) + 1,))."""
    main = _main_builder()
    side = max(1, math.ceil(math.sqrt(len(scenes))))
    starts: list[int] = []
    for k, scene in enumerate(scenes):
        starts.append(main.body_count)
        for prefix, b, xf in _placed(scene, *offset(k, side)):
            main.add_builder(b, xform=xf, label_prefix=prefix)
    starts.append(main.body_count)
    return main, starts


def structure(b) -> tuple:
    """What corresponding articulations of MuJoCo-Warp's worlds must share, of a package builder
    ``b``: per joint (type, (linear, angular) dofs, parent, child), and per body its colliding
    shapes other than meshes (Newton pads only mesh slots of worlds that differ)."""
    collide = _COLLIDE
    joints = tuple((int(t), tuple(int(x) for x in d), int(p), int(c))
                   for t, d, p, c in zip(b.joint_type, b.joint_dof_dim, b.joint_parent, b.joint_child))
    shapes = tuple(sorted((int(body), int(t)) for body, t, f in zip(b.shape_body, b.shape_type, b.shape_flags)
                          if int(t) not in MESH_TYPES and int(f) & collide))
    return joints, shapes


def build_separate_worlds(scenes: Sequence[Path], dof_step: int = DOF_STEP):
    """(a ``newton.ModelBuilder`` with scene k in world k, body index where each world's bodies
    start (len(scenes) + 1,), indices of padding bodies).

    MuJoCo-Warp steps worlds that share one structure (Newton's ``SolverMuJoCo`` checks: same body,
    joint and joint-type sequence, same non-mesh shapes per body; mesh shapes may differ per world),
    so each world is padded to the chunk's structure: its instances are grouped by package
    ``structure`` (sorted), and a world with fewer instances of a structure than another gets
    copies of a package of that structure ``PAD_FAR`` [m] below the floor whose mesh shapes do not
    collide (they fall or hang alone and are not reported); layout colliders (static, not meshes)
    are padded by static boxes there; then degrees of freedom are padded per world (``pad_dofs``)."""
    import warp as wp

    placed = [_placed(s) for s in scenes]
    groups: list[dict[tuple, list]] = []
    example: dict[tuple, object] = {}
    for items in placed:
        g: dict[tuple, list] = {}
        for item in items[1:]:
            key = structure(item[1])
            g.setdefault(key, []).append(item)
            example.setdefault(key, item[1])
        groups.append(g)
    need = {k: max(len(g.get(k, ())) for g in groups) for k in example}
    static = [_static_shapes(items[0][1]) for items in placed]
    static_need = {k: max(len(st.get(k, ())) for st in static) for st in static for k in st}
    main = _main_builder()
    starts: list[int] = []
    pads: list[int] = []
    for w, items in enumerate(placed):
        main.begin_world(label=f"scene_{w}")
        starts.append(main.body_count)
        prefix, lay, xf = items[0]
        main.add_builder(lay, xform=xf, label_prefix=prefix)
        n = 0
        for key in sorted(static_need):
            for _ in range(static_need[key] - len(static[w].get(key, ()))):
                _pad_static(main, key, n)
                n += 1
        for key in sorted(need):
            mine = groups[w].get(key, [])
            for prefix, b, xf in mine:
                main.add_builder(b, xform=xf, label_prefix=prefix)
            for _ in range(need[key] - len(mine)):
                first_body, first_shape = main.body_count, main.shape_count
                main.add_builder(example[key], xform=wp.transform(wp.vec3(10.0 * n, 0.0, -PAD_FAR), wp.quat_identity()),
                                 label_prefix=f"{PAD_PREFIX}copy_{n}")
                for s in range(first_shape, main.shape_count):
                    if int(main.shape_type[s]) in MESH_TYPES:
                        main.shape_flags[s] = int(main.shape_flags[s]) & ~_COLLIDE
                pads.extend(range(first_body, main.body_count))
                n += 1
        first_body = main.body_count
        pad_dofs(main, dof_step)
        pads.extend(range(first_body, main.body_count))
        main.end_world()
    starts.append(main.body_count)
    drop_parent_filters(main)
    return main, starts, pads


def drop_parent_filters(builder) -> int:
    """Remove the collision filter pairs between a body and its parent by a non-fixed joint (a
    drawer and its cabinet), which MuJoCo's ``filterparent`` excludes anyway (see
    ``check_parent_filter``); the number removed. Newton compiles a heterogeneous model's filter
    pairs into 32-bit contype/conaffinity masks, which a house's hundreds of such pairs exceed."""
    parent_of = {int(c): int(p) for t, p, c in zip(builder.joint_type, builder.joint_parent, builder.joint_child)
                 if int(t) != _FIXED and int(p) >= 0}
    body = builder.shape_body
    keep = [(a, c) for a, c in builder.shape_collision_filter_pairs
            if not (parent_of.get(int(body[a])) == int(body[c]) or parent_of.get(int(body[c])) == int(body[a]))]
    dropped = len(builder.shape_collision_filter_pairs) - len(keep)
    builder.shape_collision_filter_pairs = keep
    return dropped


def check_parent_filter(mj_model) -> None:
    """Raise unless MuJoCo excludes every body's contacts with its parent (``filterparent`` on and
    no parent welded to the world body, whose children it does not filter): what
    ``drop_parent_filters`` relies on."""
    import mujoco

    child = np.arange(1, mj_model.nbody)
    parent = mj_model.body_parentid[child]
    bad = child[(parent != 0) & (mj_model.body_weldid[parent] == 0)]
    if mj_model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT or len(bad):
        raise ValueError(f"MuJoCo does not filter parent contacts of bodies {bad[:5].tolist()} (filter pairs dropped)")


def _static_shapes(b) -> dict[tuple[int, int], list[int]]:
    """Static colliding shapes of ``b`` other than meshes, by (type, collision group)."""
    out: dict[tuple[int, int], list[int]] = {}
    for s, (body, t, f) in enumerate(zip(b.shape_body, b.shape_type, b.shape_flags)):
        if body < 0 and int(t) not in MESH_TYPES and int(f) & _COLLIDE:
            out.setdefault((int(t), int(b.shape_collision_group[s])), []).append(s)
    return out


def _pad_static(main, key: tuple[int, int], n: int) -> None:
    """A static box of type/collision group ``key`` ``PAD_FAR`` [m] below the floor, apart from
    everything (a layout collider slot this world lacks)."""
    import warp as wp

    kind, group = key
    if kind != _BOX:
        raise ValueError(f"static layout collider of shape type {kind} differs in count between scenes; "
                         "only boxes are padded")
    cfg = main.default_shape_cfg.copy()
    cfg.collision_group = group
    cfg.is_visible = False
    main.add_shape_box(-1, xform=wp.transform(wp.vec3(10.0 * n, 50.0, -2 * PAD_FAR), wp.quat_identity()),
                       hx=0.05, hy=0.05, hz=0.05, cfg=cfg, label=f"{PAD_PREFIX}static_{n}")


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
                 dof_step: int = DOF_STEP, worlds: bool = True) -> BatchSettle:
    """Settle ``scenes`` together for ``seconds`` [s] on ``device`` and report per scene which
    instances moved more than ``tolerance`` [m] (see the module docstring).

    ``worlds``: scene k is world k of the model (``build_separate_worlds``), stepped by MuJoCo-Warp
    as one batch: one launch per kernel steps every scene, and per-world costs (geom pairs, the
    dense nv x nv factorisation) stay those of one house. False: side by side in one world
    (``build_worlds``), whose cost grows faster than the number of scenes (MuJoCo-Warp's model
    upload enumerates every geom pair, the factorisation is of all scenes' dofs together).
    ``cuda_graph``: step through a captured graph (``_run_steps``; a CUDA graph, or on the CPU
    Warp's CPU capture; its capture [s] is ``seconds["capture"]``). ``dof_step``: see ``pad_dofs`` (0: no padding);
    ``bodies`` counts the scenes' bodies only (not padding)."""
    import warp as wp
    from newton.solvers import SolverMuJoCo

    from stages.physics_checks import _collider_points_in_bodies

    secs: dict[str, float] = {}
    t = time.perf_counter()
    if worlds:
        builder, starts, pads = build_separate_worlds(scenes, dof_step)
    else:
        builder, starts = build_worlds(scenes)
        first = builder.body_count
        pads = list(range(first, first + pad_dofs(builder, dof_step)))
    padding = set(pads)
    secs["build"] = time.perf_counter() - t
    labels = list(builder.body_label)
    body_world = np.searchsorted(np.asarray(starts), np.arange(builder.body_count), side="right") - 1
    pts: dict[int, list[np.ndarray]] = {}
    for b, p in _collider_points_in_bodies(builder):
        if b >= 0 and b not in padding and _instance_of(labels[b]) is not None:
            pts.setdefault(b, []).append(p)
    bodies = sorted(pts)
    points = [np.vstack(pts[b]) for b in bodies]
    _keep_hull_adjacency()
    with wp.ScopedDevice(device):
        t = time.perf_counter()
        model = builder.finalize(device=device)
        per_world = model.body_count // max(1, model.world_count)  # capacities are per MuJoCo world
        solver = SolverMuJoCo(model, use_mujoco_cpu=False, iterations=50, ls_iterations=20, integrator="implicitfast",
                              cone="elliptic", impratio=IMPRATIO, use_mujoco_contacts=True, enable_multiccd=True,
                              separate_worlds=worlds, nconmax=capacity(CONTACT_SLOTS_PER_BODY * per_world + 64),
                              njmax=capacity(ROWS_PER_CONTACT * (CONTACTS_PER_BODY * per_world + 64)))
        if worlds:
            check_parent_filter(solver.mj_model)
        s0, s1, control = model.state(), model.state(), model.control()
        secs["finalize"] = time.perf_counter() - t
        t = time.perf_counter()
        q0 = s0.body_q.numpy().astype(np.float64)
        steps = max(1, round(seconds / dt))
        s0, captured = _run_steps(solver, s0, s1, control, dt, steps, cuda_graph, progress)
        if captured is not None:
            secs["capture"] = captured
        q1 = s0.body_q.numpy().astype(np.float64)
        secs["simulate"] = time.perf_counter() - t
    moved: list[dict[str, float]] = [{} for _ in scenes]
    for b, p in zip(bodies, points):
        d = float(np.linalg.norm(_apply(q1[b], p) - _apply(q0[b], p), axis=1).max())
        d = d if math.isfinite(d) else math.inf
        w, inst = int(body_world[b]), _instance_of(labels[b])
        moved[w][inst] = max(moved[w].get(inst, 0.0), d)
    offenders = tuple(tuple(sorted(k for k, v in m.items() if v > tolerance)) for m in moved)
    shapes = sum(1 for lb in builder.shape_label if not lb.startswith(PAD_PREFIX))
    return BatchSettle(scenes=tuple(Path(s) for s in scenes), moved=tuple(moved), offenders=offenders,
                       passed=tuple(not o for o in offenders), bodies=model.body_count - len(padding),
                       shapes=shapes, simulated=steps * dt, seconds={k: round(v, 3) for k, v in secs.items()})


def _run_steps(solver, s0, s1, control, dt: float, steps: int, graph: bool, progress: bool):
    """(the state after ``steps`` steps of ``dt`` [s], seconds the CUDA graph capture took or None).

    ``graph``: one step eagerly (module loads, lazy allocations), then two steps captured as a graph
    (CUDA; on the CPU Warp's CPU capture, same results to the bit) and replayed: run eagerly,
    MuJoCo-Warp's solver loop (``wp.capture_while``) copies its condition to the host and waits
    for the stream at every iteration, besides ~235 launches from Python per step; in a CUDA graph
    it is a conditional node. A capture that fails (e.g. a driver without conditional nodes, CUDA
    < 12.4) is logged and the steps run eagerly."""
    import warp as wp
    from tqdm import tqdm

    captured = None
    if graph and steps >= 3:
        t = time.perf_counter()
        solver.step(s0, s1, control, None, dt)
        s0, s1 = s1, s0
        steps -= 1
        try:
            with wp.ScopedCapture() as cap:
                solver.step(s0, s1, control, None, dt)
                solver.step(s1, s0, control, None, dt)
        except Exception as e:  # noqa: BLE001 - any capture failure: step eagerly instead
            log.warning("settle: CUDA graph capture failed (%s); stepping eagerly", str(e).splitlines()[0])
        else:
            captured = time.perf_counter() - t
            for _ in range(steps // 2):  # the capture itself ran nothing
                wp.capture_launch(cap.graph)
            steps %= 2
    for _ in tqdm(range(steps), desc="settle worlds", unit="step", disable=not progress, leave=False):
        solver.step(s0, s1, control, None, dt)
        s0, s1 = s1, s0
    return s0, captured


def _apply(q: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Points p (K, 3) in a body frame -> world by the Newton transform q (7,) = (pos, quat xyzw)."""
    from scipy.spatial.transform import Rotation

    return p @ Rotation.from_quat(q[3:]).as_matrix().T + q[:3]
