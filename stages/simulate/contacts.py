"""MuJoCo-Warp contact and constraint buffers: sized from the model, overflow is an error.

MuJoCo-Warp keeps every world's contacts in one buffer of ``naconmax = nconmax * nworld`` slots:
the broadphase writes one slot per candidate geom pair (``d.ncollision``), the narrowphase one per
contact (``d.nacon``); past the capacity it drops them and prints "broadphase overflow" from the
device. Constraint rows are per world (``njmax``; ``d.nefc`` past it is dropped too). Both
capacities are fixed when the solver is built, so :func:`size_contact_buffers` sizes them from the
model, per world, before the solver exists:

    near   = shape pairs that may collide (``model.shape_contact_pairs``: same-body, filtered and
             static-static pairs removed) whose bounding spheres, at the initial pose, are closer
             than their margins + gaps + ``NEAR_GAP`` (the broadphase's first test; what rests on
             or next to something at the start);
    robot  = robot collision shapes x ``ROBOT_PARTNERS`` (the robot moves, so its pairs are not
             known at the start: each of its shapes may be near that many others at once);
    nconmax = round64(clamp(SAFETY * (near + robot), NCONMAX_FLOOR, NCONMAX_CAP))   per world
    njmax   = round64(clamp(fixed + rows * ACTIVE * nconmax, NJMAX_FLOOR, NJMAX_CAP)) per world

with ``fixed`` = 3 rows per dof (a limit row, a friction-loss row, and one for equality and weld
rows), ``rows`` the constraint rows of one contact (elliptic cone: condim; pyramidal:
2 (condim - 1)), and ``ACTIVE`` the share of contact slots that make rows at once (a contact inside the gap but not
touching makes none).
The world with the most near pairs sets the size. The demos task kitchen (211 geoms, 19 of them
the robot's; every shape's gap 1 cm, ``stages.simulate.world.CONTACT_GAP``): near = 903 pairs,
nconmax 1,856, njmax 3,008; at rest MuJoCo-Warp's broadphase (with its oriented-box test) finds 77
candidate pairs, 77 contacts and 244 constraint rows (with Newton's 0.1 m gap: 1,691 near pairs,
497 candidates, 427 contacts, the same 244 rows). The fixed 1,024 used before overflowed its
broadphase while the robot worked (issue 12).

:class:`OverflowMonitor` asks the solver for its per-world overflow bitmask
(``ObservableKind.OVERFLOW``) and, after every step, ORs it into a sticky device array and keeps
the peak counts (contacts and constraint rows per world, candidate pairs and contacts in all
worlds) with two
small kernels: no host synchronisation in the step loop, and CUDA-graph capturable. :meth:`check`
reads them back (every ``contact_check_every`` steps from :meth:`Sim.step
<stages.simulate.world.Sim.step>`, or when a caller asks) and raises :class:`ContactOverflowError`
naming the world and the count. Two bits are not dropped data but convergence caps:
``ITERATIONS`` (the solver stopped at ``iterations``) and ``LS_ITERATIONS`` (a linesearch stopped
at ``ls_iterations``), which MuJoCo's C library applies silently too; they do not raise, and
:meth:`OverflowMonitor.iteration_caps` counts the worlds that reached them. MuJoCo's C library (one CPU world) grows its own buffers; its arena
warnings are checked instead.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from pipeline.types import ItemError

NEAR_GAP = 0.05  # [m] extra distance between bounding spheres counted as "near" at the start
ROBOT_PARTNERS = 16  # shapes one robot collision shape may be near at once
SAFETY = 1.5  # contacts per candidate pair and motion headroom
ACTIVE = 0.25  # share of contact slots touching (with constraint rows) at once
NCONMAX_FLOOR, NCONMAX_CAP = 256, 16384  # per world
NJMAX_FLOOR, NJMAX_CAP = 512, 65536  # per world
_ALIGN = 64


class ContactOverflowError(ItemError):
    """Contacts or constraint rows were dropped. ``world``: the world that overflowed (the one
    with the most contacts when the shared contact buffer overflowed); ``count``: what it
    needed; ``capacity``: what it had; ``kind``: "broadphase", "narrowphase", "constraints" or
    "arena"."""

    def __init__(self, message: str, *, world: int, count: int, capacity: int, kind: str) -> None:
        super().__init__(message)
        self.world, self.count, self.capacity, self.kind = world, count, capacity, kind


@dataclass(frozen=True, kw_only=True)
class ContactCapacity:
    """Per-world capacities and the counts they came from (recorded in SimSettings.options).
    nconmax: contact slots per world; njmax: constraint rows per world; near_pairs: near shape
    pairs of the busiest world; busiest_world; robot_shapes: robot collision shapes per world;
    rows_per_contact; fixed_rows: rows not from contacts (limits, friction loss, equalities)."""

    nconmax: int
    njmax: int
    near_pairs: int
    busiest_world: int
    robot_shapes: int
    rows_per_contact: int
    fixed_rows: int

    def to_json(self) -> dict:
        return asdict(self)


def _round_up(n: float, lo: int, hi: int) -> int:
    return int(min(hi, max(lo, _ALIGN * math.ceil(n / _ALIGN))))


def near_pairs_per_world(model, body_q: np.ndarray, gap: float = NEAR_GAP) -> np.ndarray:
    """Collision shape pairs per world (W,) whose bounding spheres at body poses ``body_q``
    (B, 7) [m, xyzw] are within their margins + gaps + ``gap`` [m]. Pairs with a plane or a
    global (world -1) shape count for the other shape's world."""
    from scipy.spatial.transform import Rotation

    pairs = model.shape_contact_pairs
    nworld = max(int(model.world_count), 1)
    if pairs is None or len(pairs) == 0:
        return np.zeros(nworld, int)
    pairs = pairs.numpy().reshape(-1, 2)
    tf = model.shape_transform.numpy()  # (S, 7) in the body frame
    body = model.shape_body.numpy()
    center = tf[:, :3].copy()
    on_body = body >= 0
    bq = body_q[body[on_body]]
    center[on_body] = Rotation.from_quat(bq[:, 3:7]).apply(tf[on_body, :3]) + bq[:, :3]
    radius = model.shape_collision_radius.numpy()
    pad = model.shape_margin.numpy() + model.shape_gap.numpy()
    a, b = pairs[:, 0], pairs[:, 1]
    dist = np.linalg.norm(center[a] - center[b], axis=1)
    near = dist <= radius[a] + radius[b] + pad[a] + pad[b] + gap
    # planes have no finite bounding sphere: always a candidate (MuJoCo's plane filter decides)
    import newton

    plane = int(newton.GeoType.PLANE)
    gt = model.shape_type.numpy()
    near |= (gt[a] == plane) | (gt[b] == plane)
    sw = model.shape_world.numpy()
    world = np.where(sw[a] >= 0, sw[a], sw[b])
    world = np.where(world >= 0, world, 0)
    return np.bincount(world[near], minlength=nworld)[:nworld]


def size_contact_buffers(model, body_q: np.ndarray, *, robot_shapes: int, dofs_per_world: int,
                         cone: str = "elliptic") -> ContactCapacity:
    """MuJoCo-Warp ``nconmax`` / ``njmax`` per world for ``model`` at body poses ``body_q``
    (B, 7); ``robot_shapes``: the robot's collision shapes in one world. Formula in the module
    docstring."""
    near = near_pairs_per_world(model, body_q)
    busiest = int(np.argmax(near))
    nconmax = _round_up(SAFETY * (int(near[busiest]) + robot_shapes * ROBOT_PARTNERS),
                        NCONMAX_FLOOR, NCONMAX_CAP)
    condim = 3
    mj = getattr(model, "mujoco", None)
    if mj is not None and hasattr(mj, "condim"):
        condim = int(max(3, mj.condim.numpy().max(initial=3)))
    rows = condim if cone == "elliptic" else 2 * (condim - 1)
    fixed = 3 * dofs_per_world
    njmax = _round_up(fixed + rows * ACTIVE * nconmax, NJMAX_FLOOR, NJMAX_CAP)
    return ContactCapacity(nconmax=nconmax, njmax=njmax, near_pairs=int(near[busiest]),
                           busiest_world=busiest, robot_shapes=robot_shapes, rows_per_contact=rows,
                           fixed_rows=fixed)


def robot_collision_shapes(model, shape_start: int, shape_end: int) -> int:
    """Collision shapes among the robot's shapes [shape_start, shape_end) (markers excluded)."""
    import newton

    flags = model.shape_flags.numpy()[shape_start:shape_end]
    return int(np.count_nonzero(flags & int(newton.ShapeFlags.COLLIDE_SHAPES)))


# --------------------------------------------------------------------------------------------
# Overflow detection
# --------------------------------------------------------------------------------------------

_KERNELS: dict = {}


def _kernels():
    """The two monitor kernels (built on first use so that importing this module loads no warp)."""
    if _KERNELS:
        return _KERNELS["count"], _KERNELS["fold"]
    import warp as wp

    @wp.kernel
    def count_contacts(nacon: wp.array[wp.int32], naconmax: int, contact_worldid: wp.array[wp.int32],
                       counts: wp.array[wp.int32]):
        tid = wp.tid()
        if tid < wp.min(nacon[0], naconmax):
            wp.atomic_add(counts, contact_worldid[tid], 1)

    @wp.kernel
    def fold(overflow: wp.array[wp.int32], counts: wp.array[wp.int32], nefc: wp.array[wp.int32],
             ncollision: wp.array[wp.int32], nacon: wp.array[wp.int32],
             sticky: wp.array[wp.int32], peak_con: wp.array[wp.int32], peak_nefc: wp.array[wp.int32],
             peak_total: wp.array[wp.int32]):
        w = wp.tid()
        sticky[w] = sticky[w] | overflow[w]
        peak_con[w] = wp.max(peak_con[w], counts[w])
        peak_nefc[w] = wp.max(peak_nefc[w], nefc[w])
        if w == 0:
            peak_total[0] = wp.max(peak_total[0], ncollision[0])
            peak_total[1] = wp.max(peak_total[1], nacon[0])

    _KERNELS.update(count=count_contacts, fold=fold)
    return count_contacts, fold


class OverflowMonitor:
    """Sticky per-world overflow flags and peak counts of a :class:`SolverMuJoCo` (see the module
    docstring). ``observables``: pass to ``solver.step``; call :meth:`after_step` after each step
    (device-side, capturable) and :meth:`check` to raise on an overflow."""

    def __init__(self, solver) -> None:
        self.solver = solver
        self.cpu = bool(solver.use_mujoco_cpu)
        self.observables = None
        self._arena_seen = 0
        if self.cpu:
            return
        import warp as wp

        d = solver.mjw_data
        self.nworld, self.naconmax, self.njmax = int(d.nworld), int(d.naconmax), int(d.njmax)
        self.observables = solver.observables({solver.ObservableKind.OVERFLOW})
        dev = solver.model.device
        self._counts = wp.zeros(self.nworld, dtype=wp.int32, device=dev)
        self.sticky = wp.zeros(self.nworld, dtype=wp.int32, device=dev)
        self.peak_con = wp.zeros(self.nworld, dtype=wp.int32, device=dev)
        self.peak_nefc = wp.zeros(self.nworld, dtype=wp.int32, device=dev)
        self.peak_total = wp.zeros(2, dtype=wp.int32, device=dev)

    def after_step(self) -> None:
        """Fold this step's overflow bits and counts into the sticky arrays (no host sync)."""
        if self.cpu:
            return
        import warp as wp

        count_contacts, fold = _kernels()
        d, dev = self.solver.mjw_data, self.solver.model.device
        self._counts.zero_()
        wp.launch(count_contacts, dim=self.naconmax, inputs=[d.nacon, self.naconmax, d.contact.worldid],
                  outputs=[self._counts], device=dev)
        wp.launch(fold, dim=self.nworld,
                  inputs=[self.observables.overflow, self._counts, d.nefc, d.ncollision, d.nacon],
                  outputs=[self.sticky, self.peak_con, self.peak_nefc, self.peak_total], device=dev)

    def peaks(self) -> dict:
        """Peak counts since the monitor was made (host read: synchronises): stored contacts and
        constraint rows per world (W,), and candidate pairs and contacts in all worlds."""
        if self.cpu:
            return {}
        tot = self.peak_total.numpy()
        return {"contacts": self.peak_con.numpy(), "nefc": self.peak_nefc.numpy(),
                "ncollision": int(tot[0]), "nacon": int(tot[1])}

    def iteration_caps(self) -> dict[str, int]:
        """Worlds whose solver (``solver_iteration_cap_worlds``) or linesearch
        (``linesearch_iteration_cap_worlds``) stopped at its iteration limit at least once since
        the monitor was made (convergence, not dropped data; host read: synchronises)."""
        if self.cpu:
            return {}
        from mujoco_warp import OverflowType

        sticky = self.sticky.numpy()
        return {"solver_iteration_cap_worlds": int(np.count_nonzero(sticky & int(OverflowType.ITERATIONS))),
                "linesearch_iteration_cap_worlds": int(np.count_nonzero(sticky & int(OverflowType.LS_ITERATIONS)))}

    def check(self) -> None:
        """Raise :class:`ContactOverflowError` if any step since the monitor was made dropped
        contacts or constraint rows (host read of a few small arrays: synchronises). The solver's
        iteration caps (``ITERATIONS``, ``LS_ITERATIONS``) are not errors (:meth:`iteration_caps`)."""
        if self.cpu:
            self._check_arena()
            return
        from mujoco_warp import OverflowType

        sticky = self.sticky.numpy() & ~int(OverflowType.ITERATIONS | OverflowType.LS_ITERATIONS)
        if not sticky.any():
            return
        p = self.peaks()
        nconmax = self.naconmax // self.nworld
        bad = np.flatnonzero(sticky & int(OverflowType.NEFC))
        if len(bad):
            w = int(bad[np.argmax(p["nefc"][bad])])
            n = int(p["nefc"][w])
            raise ContactOverflowError(
                f"world {w}: {n} constraint rows, njmax is {self.njmax} per world ({len(bad)} world(s) "
                f"overflowed): constraints were dropped; raise SolverSettings.njmax",
                world=w, count=n, capacity=self.njmax, kind="constraints")
        for bit, kind, total in ((OverflowType.BROADPHASE, "broadphase", p["ncollision"]),
                                 (OverflowType.NARROWPHASE, "narrowphase", p["nacon"])):
            if (sticky & int(bit)).any():
                w = int(np.argmax(p["contacts"]))
                n = int(p["contacts"][w])
                what = "candidate pairs" if kind == "broadphase" else "contacts"
                raise ContactOverflowError(
                    f"world {w}: {kind} overflow, {total} {what} in all {self.nworld} world(s) for "
                    f"naconmax {self.naconmax} (nconmax {nconmax} per world; world {w} held the most "
                    f"contacts, {n}): contacts were dropped; raise SolverSettings.nconmax",
                    world=w, count=total, capacity=self.naconmax, kind=kind)
        raise ContactOverflowError(
            f"world {int(np.flatnonzero(sticky)[0])}: MuJoCo-Warp overflow bits {int(sticky.max()):#x}",
            world=int(np.flatnonzero(sticky)[0]), count=0, capacity=0, kind="other")

    def _check_arena(self) -> None:
        """MuJoCo C: its contact and constraint arena warnings (one world, world 0)."""
        import mujoco

        d = self.solver.mj_data
        for warn, kind in ((mujoco.mjtWarning.mjWARN_CONTACTFULL, "narrowphase"),
                           (mujoco.mjtWarning.mjWARN_CNSTRFULL, "constraints")):
            info = d.warning[int(warn)]
            if info.number > 0:
                raise ContactOverflowError(
                    f"world 0: MuJoCo arena full ({kind}, {info.lastinfo} needed, {info.number} times): "
                    f"contacts were dropped", world=0, count=int(info.lastinfo), capacity=0, kind="arena")
