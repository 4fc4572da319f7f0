"""Scene loading, robot insertion, world replication and stepping.

:func:`build_sim` turns scene USD files into a Newton model with the robot inserted at a free,
reachable spawn pose, replicated over ``world_count`` worlds, on a chosen device, with a solver
whose settings are recorded in :class:`SimSettings`::

    desc = write_robot_urdf(out_dir, panda_root=...)
    sim = build_sim(SimConfig(scenes=(room_usd,), world_count=1, device="cpu"), desc, rng)
    sim.step(100)

Solvers: MuJoCo (``"mujoco"``, the default for articulated robots) runs MuJoCo-Warp on CUDA and
the MuJoCo C library on CPU with a single world (``use_mujoco_cpu``; several CPU worlds use
MuJoCo-Warp's CPU path). Featherstone, semi-implicit and XPBD need small steps (objects are
launched at one step per 1/240 s): they run ``substeps`` steps of ``dt / substeps`` with Newton's
collision pipeline. Every choice is written to :class:`SimSettings`."""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, field
from enum import StrEnum
from pathlib import Path

import numpy as np

from pipeline.types import ItemError
from stages.simulate.mujoco_cpu import cpu_stepper
from stages.simulate.robot import RobotDescription
from stages.simulate.robot_load import DriveGains, RobotIndices, add_robot

log = logging.getLogger(__name__)
ROBOT_LABEL = "robot"
MAX_EXPLICIT_STEP = 1.0 / 960.0  # [s] longest substep for Featherstone / semi-implicit / XPBD
#: every shape's contact gap [m] (Newton's default 0.1: MuJoCo's convex collision with a 0.1 m margin
#: found a fingertip mm inside a thin hull, the clock's button cap, separated: the fingers went through)
CONTACT_GAP = 0.01


class SolverKind(StrEnum):
    MUJOCO = "mujoco"
    FEATHERSTONE = "featherstone"
    SEMI_IMPLICIT = "semi_implicit"
    XPBD = "xpbd"


@dataclass(frozen=True, kw_only=True)
class SolverSettings:
    """dt: physics step [s] (the time one :meth:`Sim.step` advances); substeps: solver steps per physics
    step (1 for MuJoCo; the others need dt / substeps <= 1/960 s); use_mujoco_cpu: None = auto (True on
    CPU with one world); iterations / ls_iterations: MuJoCo solver iterations; cone, impratio,
    integrator: MuJoCo options; njmax / nconmax: per-world constraint rows and contacts for MuJoCo-Warp
    (None: sized from the model, :mod:`stages.simulate.contacts`); contact_check_every: steps between
    overflow checks (a small host read; an overflow raises ``ContactOverflowError`` naming the world and
    the count; 0: at :meth:`Sim.check_contacts` only); cuda_graph: on CUDA, replay MuJoCo-Warp's step as
    a captured CUDA graph (one graph per state-buffer parity) instead of launching its kernels one by
    one from Python; fast_cpu_step: on the MuJoCo C library, Newton's step from recorded kernel launches
    into buffers allocated once (the same states; a teleop frame's 17 steps 43 -> 28 ms of CPU:
    :mod:`stages.simulate.mujoco_cpu`); multiccd: MuJoCo's multi-CCD contacts (up to 4 points per
    convex pair, not 1: light things on a bed crept 3-8 mm/s)."""

    kind: SolverKind = SolverKind.MUJOCO
    dt: float = 0.002
    substeps: int = 1
    use_mujoco_cpu: bool | None = None
    iterations: int = 50
    ls_iterations: int = 25
    cone: str = "elliptic"
    impratio: float = 10.0
    integrator: str = "implicitfast"
    njmax: int | None = None
    nconmax: int | None = None
    contact_check_every: int = 250
    cuda_graph: bool = True
    fast_cpu_step: bool = True
    multiccd: bool = False

    def __post_init__(self) -> None:
        if self.dt <= 0 or self.substeps < 1:
            raise ItemError(
                f"solver {self.kind}: dt must be > 0 and substeps >= 1 (got {self.dt}, {self.substeps})"
            )
        if self.kind != SolverKind.MUJOCO and self.dt / self.substeps > MAX_EXPLICIT_STEP + 1e-12:
            need = int(np.ceil(self.dt / MAX_EXPLICIT_STEP - 1e-9))
            raise ItemError(
                f"solver {self.kind}: step {self.dt / self.substeps:.5f} s is too long; use substeps "
                f">= {need} at dt {self.dt} s (at most {MAX_EXPLICIT_STEP:.5f} s per substep)"
            )


@dataclass(frozen=True, kw_only=True)
class SimConfig:
    """scenes: scene USD files: one (replicated to every world) or one per world;
    world_count; device: "cpu" or "cuda[:n]"; spawn: robot root (x, y, yaw) or None to pick a free
    spawn pose; spawn_near: with spawn None, the free pose nearest this point (x, y) [m], facing
    it; add_ground_plane: add an infinite plane (scenes without a floor collider);
    robot_radius: clearance radius of the base footprint [m] used to pick the spawn;
    contact_ke / contact_kd: default contact stiffness and damping of shapes without their own
    (MuJoCo maps them to solref: time constant 2/kd = 5 ms, damping ratio 1; Newton's default
    20 ms lets a squeezing gripper sink centimetres into light objects); contact_gap: :data:`CONTACT_GAP`."""

    scenes: tuple[Path, ...] = ()
    world_count: int = 1
    device: str = "cpu"
    spawn: tuple[float, float, float] | None = None
    spawn_near: tuple[float, float] | None = None
    add_ground_plane: bool = False
    robot_radius: float = 0.45
    contact_ke: float = 4.0e4
    contact_kd: float = 400.0
    contact_gap: float = CONTACT_GAP
    solver: SolverSettings = field(default_factory=SolverSettings)
    gains: DriveGains = field(default_factory=DriveGains)


@dataclass(frozen=True, kw_only=True)
class SimSettings:
    """What was actually used (recorded next to episodes): the resolved solver options, the
    spawn pose, counts per world, and Newton/MuJoCo versions."""

    solver: str
    dt: float
    substeps: int
    device: str
    world_count: int
    use_mujoco_cpu: bool | None
    separate_worlds: bool | None
    options: dict
    spawn: tuple[float, float, float]
    bodies_per_world: int
    shapes_per_world: int
    dofs_per_world: int
    newton_version: str
    scenes: tuple[str, ...]

    def to_json(self) -> dict:
        d = asdict(self)
        d["scenes"] = list(self.scenes)
        d["spawn"] = list(self.spawn)
        return d


# --------------------------------------------------------------------------------------------
# Scene loading
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class LoadedScene:
    """Per-world-template facts from loading scene USDs: shape labels and prim paths by shape
    index (world-local), body prim paths by body index, joint prim paths by joint index."""

    shape_label: tuple[str, ...]
    shape_path: tuple[str, ...]
    body_path: dict[int, str]
    joint_path: dict[int, str]
    lights: tuple = ()


def _semantic_label(prim) -> str:
    """The first UsdSemantics class label on the prim or its nearest labelled ancestor ('' if none)."""

    p = prim
    while p and p.IsValid() and p.GetPath() != p.GetPath().absoluteRootPath:
        for attr in p.GetAttributes():
            name = attr.GetName()
            if name.startswith("semantics:labels:") and attr.HasAuthoredValue():
                v = attr.Get()
                if v:
                    return str(v[0])
        p = p.GetParent()
    return ""


def load_scene(builder, usd: Path) -> LoadedScene:
    """Add one scene USD to ``builder`` (``add_usd``) and map each new shape to its semantic label."""
    from pxr import Usd

    usd = Path(usd)
    if not usd.is_file():
        raise ItemError(f"{usd}: scene USD not found")
    stage = Usd.Stage.Open(str(usd))
    if stage is None:
        raise ItemError(f"{usd}: cannot open as USD")
    shape0 = builder.shape_count
    try:
        res = builder.add_usd(stage, load_visual_shapes=True, hide_collision_shapes=True)
    except ImportError as e:
        raise ItemError(f"{usd}: Newton's USD importer is unavailable ({e})") from None
    n = builder.shape_count - shape0
    paths = [""] * n
    for path, idx in res.get("path_shape_map", {}).items():
        if shape0 <= idx < builder.shape_count:
            paths[idx - shape0] = path
    labels = []
    cache: dict[str, str] = {}
    for p in paths:
        if p not in cache:
            prim = stage.GetPrimAtPath(p) if p else None
            cache[p] = _semantic_label(prim) if prim else ""
        labels.append(cache[p])
    from stages.simulate.sensors import read_usd_lights

    return LoadedScene(
        shape_label=tuple(labels),
        shape_path=tuple(paths),
        body_path={v: k for k, v in res.get("path_body_map", {}).items()},
        joint_path={v: k for k, v in res.get("path_joint_map", {}).items()},
        lights=read_usd_lights(stage),
    )


# -- free spawn pose --------------------------------------------------------------------------


def shape_footprints(builder, z_range=(0.03, 1.6)) -> tuple[np.ndarray, np.ndarray]:
    """World AABBs (K, 4) [xmin, ymin, xmax, ymax] of the builder's shapes that overlap the
    robot's height band ``z_range`` [m] (floors and ceilings are outside it), and their shape
    indices (K,)."""
    import newton
    from scipy.spatial.transform import Rotation

    out, idx = [], []
    for s in range(builder.shape_count):
        gt = int(builder.shape_type[s])
        if gt == int(newton.GeoType.PLANE):
            continue
        sc = np.asarray(builder.shape_scale[s], float)
        if gt == int(newton.GeoType.BOX):
            corners = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float) * sc
        elif gt in (int(newton.GeoType.MESH), int(newton.GeoType.CONVEX_MESH)):
            src = builder.shape_source[s]
            if src is None:
                continue
            corners = np.asarray(src.vertices, float) * sc
        else:
            r = float(sc[0])
            hh = float(max(sc[1], sc[0]))
            corners = np.array([[i * r, j * r, k * hh] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
        tf = np.asarray(builder.shape_transform[s], float)
        b = int(builder.shape_body[s])
        if b >= 0:
            bq = np.asarray(builder.body_q[b], float)
            m_b = np.eye(4)
            m_b[:3, :3] = Rotation.from_quat(bq[3:7]).as_matrix()
            m_b[:3, 3] = bq[:3]
        else:
            m_b = np.eye(4)
        m_s = np.eye(4)
        m_s[:3, :3] = Rotation.from_quat(tf[3:7]).as_matrix()
        m_s[:3, 3] = tf[:3]
        pts = corners @ (m_b @ m_s)[:3, :3].T + (m_b @ m_s)[:3, 3]
        lo, hi = pts.min(0), pts.max(0)
        if hi[2] < z_range[0] or lo[2] > z_range[1]:
            continue
        out.append([lo[0], lo[1], hi[0], hi[1]])
        idx.append(s)
    return np.asarray(out, float).reshape(-1, 4), np.asarray(idx, int)


def find_free_spawn(
    builder, rng: np.random.Generator, *, radius: float = 0.45, near=None, cell: float = 0.05
) -> tuple[float, float, float]:
    """A robot root pose (x, y, yaw) whose footprint disc of ``radius`` [m] touches no shape,
    inside the largest connected free region of the scene (so the robot can drive from it).

    With ``near`` (x, y): the free cell nearest that point, yawed to face it; else a random free
    cell from ``rng`` with a random yaw. Raises ItemError when no cell is free.
    """
    from scipy import ndimage

    boxes, _ = shape_footprints(builder)
    if len(boxes) == 0:
        raise ItemError("scene: no obstacles or walls to bound a spawn region")
    lo, hi = boxes[:, :2].min(0), boxes[:, 2:].max(0)
    xs = np.arange(lo[0] + cell / 2, hi[0], cell)
    ys = np.arange(lo[1] + cell / 2, hi[1], cell)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    free = np.ones(gx.shape, bool)
    occupied = np.zeros(gx.shape, bool)
    for x0, y0, x1, y1 in boxes:
        dx = np.maximum(np.maximum(x0 - gx, gx - x1), 0.0)
        dy = np.maximum(np.maximum(y0 - gy, gy - y1), 0.0)
        free &= dx * dx + dy * dy > radius * radius
        occupied |= (dx == 0) & (dy == 0)
    # the region enclosed by walls: free cells not connected to the grid border
    lab, n = ndimage.label(free)
    if n == 0:
        raise ItemError("scene: no free spawn pose for the robot footprint")
    border = set(np.unique(np.concatenate([lab[0], lab[-1], lab[:, 0], lab[:, -1]]))) - {0}
    sizes = ndimage.sum(free, lab, index=np.arange(1, n + 1))
    candidates = [i + 1 for i in np.argsort(-sizes) if (i + 1) not in border] or [int(np.argmax(sizes)) + 1]
    region = lab == candidates[0]
    ii, jj = np.nonzero(region)
    px, py = gx[ii, jj], gy[ii, jj]
    if near is not None:
        k = int(np.argmin((px - near[0]) ** 2 + (py - near[1]) ** 2))
        yaw = float(np.arctan2(near[1] - py[k], near[0] - px[k]))
    else:
        k = int(rng.integers(len(px)))
        yaw = float(rng.uniform(-np.pi, np.pi))
    return float(px[k]), float(py[k]), yaw


# --------------------------------------------------------------------------------------------
# The simulation
# --------------------------------------------------------------------------------------------


@dataclass
class Sim:
    """A built simulation: Newton model, states, control, solver, and the robot's indices.

    robot: world-local indices (world 0); per world w, add ``w * dofs_per_world`` to dof indices,
    ``w * coords_per_world`` to coordinates, ``w * bodies_per_world`` to bodies and
    ``w * shapes_per_world`` to shapes. shape_label: semantic label of every model shape (N_s,).
    """

    model: object
    solver: object
    state_0: object
    state_1: object
    control: object
    contacts: object | None
    pipeline: object | None
    robot: RobotIndices
    desc: RobotDescription
    settings: SimSettings
    scene: LoadedScene
    shape_label: np.ndarray
    bodies_per_world: int
    shapes_per_world: int
    dofs_per_world: int
    coords_per_world: int
    spawn: tuple[float, float, float]
    solver_settings: SolverSettings = field(default_factory=SolverSettings)
    time: float = 0.0
    steps: int = 0
    pre_step: list = field(default_factory=list)
    post_step: list = field(default_factory=list)  # callbacks after each step
    _graphs: dict = field(default_factory=dict, repr=False)  # (state_0 id, h) -> captured CUDA graph
    _graphs_warm: bool = field(default=False, repr=False)
    contact_monitor: object | None = field(default=None, repr=False)  # contacts.OverflowMonitor
    _cpu_step: object | None = field(default=None, repr=False)  # mujoco_cpu.MujocoCpuStep (False: none)

    @property
    def world_count(self) -> int:
        return int(self.model.world_count)

    def step(self, n: int = 1) -> None:
        """Advance ``n`` physics steps of ``settings.dt`` [s]; ``pre_step`` callbacks run before
        each (controllers: drive targets), ``post_step`` ones after (the engine's world hold)."""
        s = self.settings
        h = s.dt / s.substeps
        graphs = self._use_graphs()
        for _ in range(n):
            for cb in self.pre_step:
                cb(self)
            for _ in range(s.substeps):
                if graphs:
                    self._graph_substep(h)
                else:
                    self._substep(h)
                self.state_0, self.state_1 = self.state_1, self.state_0
            for cb in self.post_step:
                cb(self)
            self.time += s.dt
            self.steps += 1
            every = self.solver_settings.contact_check_every
            if self.contact_monitor is not None and every and self.steps % every == 0:
                self.contact_monitor.check()

    def check_contacts(self) -> None:
        """Raise ``ContactOverflowError`` (world, count) if a step dropped contacts or rows."""
        if self.contact_monitor is not None:
            self.contact_monitor.check()

    def _substep(self, h: float) -> None:
        """One solver step of ``h`` [s] from ``state_0`` into ``state_1``."""
        fast = None if self._cpu_step is False else cpu_stepper(self)
        if fast is not None:  # MuJoCo C: Newton's step without its per-step overhead (no observables)
            return fast.step(self.state_0, self.state_1, h)
        self.state_0.clear_forces()
        if self.pipeline is not None:
            self.pipeline.collide(self.state_0, self.contacts)
        mon = self.contact_monitor
        self.solver.step(self.state_0, self.state_1, self.control, None if self.pipeline is None else self.contacts,
                         h, observables=None if mon is None else mon.observables)
        if mon is not None:
            mon.after_step()

    def _use_graphs(self) -> bool:
        """CUDA graph replay applies to MuJoCo-Warp on a CUDA device (no Newton pipeline)."""
        return (self.solver_settings.cuda_graph and self.pipeline is None
                and str(self.model.device).startswith("cuda")
                and self.solver_settings.kind == SolverKind.MUJOCO)

    def _graph_substep(self, h: float) -> None:
        """:meth:`_substep` replayed from a CUDA graph captured for the current buffer parity (the
        step writes ``state_1`` from ``state_0``; the two buffers alternate, so two graphs). The
        first step runs uncaptured so that every kernel is compiled and loaded before capture."""
        import warp as wp

        if not self._graphs_warm:
            self._substep(h)
            self._graphs_warm = True
            return
        key = (id(self.state_0), h)
        g = self._graphs.get(key)
        if g is None:
            with wp.ScopedCapture(device=self.model.device) as cap:
                self._substep(h)
            g = self._graphs[key] = cap.graph
        wp.capture_launch(g)

    def reset(self, base: tuple[float, float, float] | None = None) -> None:
        """Back to the model's initial state (joint positions, velocities, drive targets), time 0;
        with ``base`` (x, y, yaw) [m, rad] in the world, the robot's base joints are set so that
        the base starts there instead of at the spawn pose (in every world). Callbacks stay
        registered; controllers should re-send their commands."""
        import newton
        import warp as wp

        m = self.model
        q = m.joint_q.numpy().copy()
        if base is not None:
            x0, y0, yaw0 = self.spawn
            c, s = np.cos(yaw0), np.sin(yaw0)
            dx, dy = base[0] - x0, base[1] - y0
            local = (c * dx + s * dy, -s * dx + c * dy, base[2] - yaw0)
            for w in range(self.world_count):
                for name, v in zip(self.desc.base_joints, local, strict=True):
                    q[self.world_coord(name, w)] = v
        q_wp = wp.array(q, dtype=wp.float32, device=m.device)
        self.state_0.joint_q.assign(q_wp)
        self.state_0.joint_qd.assign(m.joint_qd)
        newton.eval_fk(m, q_wp, m.joint_qd, self.state_0)
        self.state_1.assign(self.state_0)
        self.control.joint_target_q.assign(m.joint_target_q)
        self.control.joint_target_qd.assign(m.joint_target_qd)
        self.time, self.steps = 0.0, 0

    def world_dof(self, name: str, world: int = 0) -> int:
        return self.robot.dof[name] + world * self.dofs_per_world

    def world_coord(self, name: str, world: int = 0) -> int:
        return self.robot.coord[name] + world * self.coords_per_world

    def world_body(self, name: str, world: int = 0) -> int:
        return self.robot.body[name] + world * self.bodies_per_world

    def body_of_path(self, path: str, world: int = 0) -> int:
        """Model body index of a scene prim path (a rigid body of the scene)."""
        for b, p in self.scene.body_path.items():
            if p == path:
                return b + world * self.bodies_per_world
        raise KeyError(path)

    def joint_q_of_path(self, path: str, world: int = 0) -> float:
        """Position of a one-dof scene joint (by prim path) [m or rad]."""
        for j, p in self.scene.joint_path.items():
            if p == path:
                q0 = int(self.model.joint_q_start.numpy()[j]) + world * self.coords_per_world
                return float(self.state_0.joint_q.numpy()[q0])
        raise KeyError(path)


def _build_template(cfg: SimConfig, scene: Path, desc: RobotDescription, rng):
    import newton
    from newton.solvers import SolverMuJoCo

    b = newton.ModelBuilder()
    b.default_shape_cfg.ke, b.default_shape_cfg.kd = cfg.contact_ke, cfg.contact_kd
    b.rigid_gap = cfg.contact_gap
    SolverMuJoCo.register_custom_attributes(b)
    loaded = load_scene(b, scene)
    spawn = cfg.spawn or find_free_spawn(b, rng, radius=cfg.robot_radius, near=cfg.spawn_near)
    adder = getattr(desc, "add_to_builder", None)     # a description that loads itself (dual_arm.py)
    robot = adder(b, spawn) if adder else add_robot(b, desc, spawn_xy_yaw=spawn, gains=cfg.gains)
    labels = list(loaded.shape_label) + [ROBOT_LABEL] * (robot.shape_end - robot.shape_start)
    return b, loaded, robot, spawn, labels


def _make_solver(model, s: SolverSettings, device: str, world_count: int, capacity=None):
    """The solver; MuJoCo's unset njmax / nconmax come from ``capacity`` (a contacts.ContactCapacity)."""
    import newton

    opts: dict = {}
    if s.kind == SolverKind.MUJOCO:
        from newton.solvers import SolverMuJoCo

        cpu = s.use_mujoco_cpu if s.use_mujoco_cpu is not None else (device == "cpu" and world_count == 1)
        separate = not cpu
        opts = dict(
            use_mujoco_cpu=cpu,
            separate_worlds=separate,
            solver="newton",
            integrator=s.integrator,
            cone=s.cone,
            impratio=s.impratio,
            iterations=s.iterations,
            ls_iterations=s.ls_iterations,
            njmax=s.njmax if s.njmax is not None or capacity is None else capacity.njmax,
            nconmax=s.nconmax if s.nconmax is not None or capacity is None else capacity.nconmax,
            disable_sensors=True, **({"enable_multiccd": True} if s.multiccd else {}),
        )
        return SolverMuJoCo(model, **opts), None, cpu, separate, opts
    pipeline = newton.CollisionPipeline(model)
    if s.kind == SolverKind.FEATHERSTONE:
        solver = newton.solvers.SolverFeatherstone(model)
    elif s.kind == SolverKind.SEMI_IMPLICIT:
        solver = newton.solvers.SolverSemiImplicit(model)
    else:
        solver = newton.solvers.SolverXPBD(model, iterations=max(2, s.iterations // 10))
        opts = {"iterations": max(2, s.iterations // 10)}
    return solver, pipeline, None, None, opts


def build_sim(cfg: SimConfig, desc: RobotDescription, rng: np.random.Generator) -> Sim:
    """Load the scene(s), insert the robot, replicate to ``cfg.world_count`` worlds, finalize on
    ``cfg.device`` and create the solver. Different scenes per world must have the same number
    of bodies, joints and shapes for MuJoCo-Warp (it batches identical worlds)."""
    import newton

    if not cfg.scenes:
        raise ItemError("simulate: no scene USD given")
    if len(cfg.scenes) not in (1, cfg.world_count):
        raise ItemError(
            f"simulate: {len(cfg.scenes)} scenes for {cfg.world_count} worlds (need 1 or one per world)"
        )
    tpl, loaded, robot, spawn, labels = _build_template(cfg, cfg.scenes[0], desc, rng)
    main = newton.ModelBuilder()
    main.rigid_gap = cfg.contact_gap  # (the ground plane's)
    newton.solvers.SolverMuJoCo.register_custom_attributes(main)
    if len(cfg.scenes) == 1:
        main.replicate(tpl, cfg.world_count)
        all_labels = labels * cfg.world_count
    else:
        all_labels = []
        for w, scene in enumerate(cfg.scenes):
            b, _, _, _, lab = (
                (tpl, loaded, robot, spawn, labels)
                if w == 0
                else _build_template(SimConfig(**{**cfg.__dict__, "spawn": spawn}), scene, desc, rng)
            )
            if (b.body_count, b.shape_count, b.joint_count) != (
                tpl.body_count,
                tpl.shape_count,
                tpl.joint_count,
            ):
                raise ItemError(f"{scene}: differs in structure from {cfg.scenes[0]}; worlds must match")
            main.add_world(b)
            all_labels += lab
    if cfg.add_ground_plane:
        main.add_ground_plane()
        all_labels.append("floor")
    model = main.finalize(device=cfg.device)
    capacity = monitor = None
    if cfg.solver.kind == SolverKind.MUJOCO:
        from stages.simulate import contacts as _contacts

        capacity = _contacts.size_contact_buffers(
            model, model.body_q.numpy(), cone=cfg.solver.cone, dofs_per_world=tpl.joint_dof_count,
            robot_shapes=_contacts.robot_collision_shapes(model, robot.shape_start, robot.shape_end))
    solver, pipeline, cpu, separate, opts = _make_solver(model, cfg.solver, cfg.device, cfg.world_count,
                                                         capacity)
    if capacity is not None:
        monitor = _contacts.OverflowMonitor(solver)
    contacts = pipeline.contacts() if pipeline is not None else None
    state_0, state_1, control = model.state(), model.state(), model.control()
    newton.eval_fk(model, model.joint_q, model.joint_qd, state_0)
    settings = SimSettings(
        solver=cfg.solver.kind.value,
        dt=cfg.solver.dt,
        substeps=cfg.solver.substeps,
        device=cfg.device,
        world_count=cfg.world_count,
        use_mujoco_cpu=cpu,
        separate_worlds=separate,
        options={
            **{k: v for k, v in opts.items() if v is not None},
            "contact_ke": cfg.contact_ke,
            "contact_kd": cfg.contact_kd,
            "contact_gap": cfg.contact_gap,
            "cuda_graph": cfg.solver.cuda_graph and pipeline is None and cfg.device.startswith("cuda"),
            **({"contact_capacity": capacity.to_json()} if capacity is not None else {}),
        },
        spawn=tuple(spawn),
        bodies_per_world=tpl.body_count,
        shapes_per_world=tpl.shape_count,
        dofs_per_world=tpl.joint_dof_count,
        newton_version=newton.__version__,
        scenes=tuple(str(s) for s in cfg.scenes),
    )
    log.info("simulation built: %s", settings)
    return Sim(model=model, solver=solver, state_0=state_0, state_1=state_1, control=control,
               contacts=contacts, pipeline=pipeline, robot=robot, desc=desc, settings=settings, scene=loaded,
               shape_label=np.asarray(all_labels), bodies_per_world=tpl.body_count,
               shapes_per_world=tpl.shape_count,
               dofs_per_world=tpl.joint_dof_count, coords_per_world=tpl.joint_coord_count, spawn=tuple(spawn),
               solver_settings=cfg.solver, contact_monitor=monitor)
