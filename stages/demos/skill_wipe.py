"""The wipe skill (issue 16, clean dishes): the sponge held and moved in a pattern over a plate
with contact (task ``wipe_plate``).

- :func:`wipe_setup`: the episode's plate and sponge on the table's near band (the mug, bowl and
  pushed object moved to its far band, where the kitchen parks plate and sponge for the other
  tasks; with a dish rack, rack, plate and sponge in a row as :mod:`stages.demos.house_dishes`
  lays them; a house kitchen's dishes where that layout put them) and the :class:`WipeTrace` that
  records the wipe;
- :func:`wipe_plate` (the expert): top-down grasp of the sponge across its width, over the plate,
  down until the sponge presses :data:`PRESS` into the plate's surface, rows across the plate's
  well (boustrophedon, :data:`ROW_STEP` apart); then, while the trace's coverage is short of
  :data:`COVERAGE` + :data:`TOUCH_UP_MARGIN` (the plate dragged along, the sponge turned or lifted in
  the hand: kitchen 1 ended at 0.799), up to :data:`TOUCH_UPS` passes over the cells still unwiped
  (:func:`_touch_up_rows`); up, the sponge back where it lay, release;
- :func:`wipe_plate_success` (the predicate): coverage of the plate's top (its flat well, radius
  ``well_ratio x radius`` + 1 cm) by the sponge's contact path at least :data:`COVERAGE`, the plate
  still on the table, the sponge released on the table.

Contact is geometric, from the simulated poses the expert samples along the rows (every
:data:`SAMPLE_STEP`): the sponge's centre over the plate and its bottom (its origin: the
catalog's sponge stands on z = 0) within :data:`CONTACT_TOL` of the plate's surface under its
footprint (the lathed profile of
the catalog's plate from its parameters) and tilted less than 20 deg; each 1 cm cell of the well
under the sponge's footprint at such a sample counts as wiped. (A policy's episode records no
trace: its wipe predicate needs the trace recorded by the engine; not done yet.)

Frame: world, Z up, metres, radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from stages.demos.driver import APPROACH_TOL, ExpertFailure

COVERAGE = 0.8          # wiped share of the plate's top for success
PRESS = 0.003           # the sponge's bottom this far below the plate's surface [m] (the hand presses)
CONTACT_TOL = 0.005     # in contact: the sponge's bottom at most this above the plate's surface [m]
ROW_STEP = 0.6          # rows this many sponge widths apart
SAMPLE_STEP = 0.015     # the path is moved and sampled in steps of this [m]
CELL = 0.01             # coverage cells [m]
TOUCH_UP_MARGIN = 0.06  # the expert strokes again over what is left until this share above COVERAGE is wiped
TOUCH_UPS = 2           # such passes at most
MAX_SPONGE_WIDTH = 0.072  # the Franka hand's 80 mm stroke grasps a sponge at most this wide [m]


@dataclass
class WipeTrace:
    """The plate and sponge of a wipe episode and what was wiped. plate / sponge: body prim paths;
    plate_params / sponge_size (length, width, height) [m]: catalog geometry; cells (K, 2): the
    well's cell centres in the plate frame [m]; wiped (K,) bool; samples: contact samples taken;
    tilted: samples refused for the sponge's tilt; gaps: the sponge bottom's height above the
    plate's surface at each untilted sample [m] (diagnostics); flat_top: the plate collides as one
    convex hull (the ingest's collider of a near-convex plate: every catalog plate), whose top is
    flat at the rim's height over the whole plate, not the lathe's well."""

    plate: str
    sponge: str
    plate_params: dict
    sponge_size: tuple[float, float, float]
    cells: np.ndarray = field(repr=False)
    wiped: np.ndarray = field(repr=False)
    samples: int = 0
    tilted: int = 0
    gaps: list = field(default_factory=list, repr=False)
    flat_top: bool = False

    @property
    def coverage(self) -> float:
        return float(self.wiped.mean()) if len(self.wiped) else 0.0

    def surface(self, r) -> np.ndarray:
        """Height [m] of the plate's upper surface above its base at radius ``r`` (the generator's
        lathe profile: well at the plate's thickness, then the rim up to its height; with
        ``flat_top``, the collider's top: the rim's height everywhere)."""
        p = self.plate_params
        rad, h, t = float(p["radius"]), float(p["height"]), float(p["thickness"])
        if self.flat_top:
            return np.full(np.shape(r), h)
        rf = rad * float(p["well_ratio"])
        return np.interp(np.asarray(r, float), [0.0, rf, rf + 0.01, rad - 0.004, rad],
                         [t, t, t + 0.002, h, h])

    def footprint(self, xy, yaw: float) -> np.ndarray:
        """Points (N, 2) [m] covering the sponge's bottom at (x, y), ``yaw``."""
        sx, sy, _ = self.sponge_size
        u, v = np.meshgrid(np.linspace(-sx / 2, sx / 2, 7), np.linspace(-sy / 2, sy / 2, 5))
        c, s = math.cos(yaw), math.sin(yaw)
        return np.column_stack([xy[0] + c * u.ravel() - s * v.ravel(), xy[1] + s * u.ravel() + c * v.ravel()])

    def record(self, state) -> bool:
        """Count the cells under the sponge if it touches the plate in ``state``; True if it does."""
        pl, sp = state.objects[self.plate], state.objects[self.sponge]
        pc, sc = np.asarray(pl.position), np.asarray(sp.position)
        w, x, y, z = (float(v) for v in sp.orientation)
        if 1 - 2 * (x * x + y * y) < math.cos(math.radians(20.0)):
            self.tilted += 1
            return False
        yaw = _yaw(sp.orientation)
        if np.linalg.norm(sc[:2] - pc[:2]) > float(self.plate_params["radius"]):
            return False  # (beside the plate: on the table, not on it)
        pts = self.footprint(sc[:2], yaw)
        under = float(self.surface(np.linalg.norm(pts - pc[:2], axis=1)).max()) + pc[2]
        self.gaps.append(round(float(sc[2] - under), 4))
        if not -CONTACT_TOL <= sc[2] - under <= CONTACT_TOL:
            return False  # above it, or (pushed under its rim) not on its surface
        self.samples += 1
        c, s = math.cos(yaw), math.sin(yaw)
        rel = (self.cells + pc[:2] - sc[:2]) @ np.array([[c, -s], [s, c]])  # sponge frame
        sx, sy, _ = self.sponge_size
        self.wiped |= (np.abs(rel[:, 0]) <= sx / 2) & (np.abs(rel[:, 1]) <= sy / 2)
        return True


def new_trace(world) -> WipeTrace:
    """An empty trace of ``world``'s plate and sponge (the well's cells, nothing wiped)."""
    plate, sponge = world.placed["plate"], world.placed["sponge"]
    p = plate.asset.params
    well = float(p["radius"]) * float(p["well_ratio"]) + 0.01
    g = np.arange(-well + CELL / 2, well, CELL)
    xx, yy = np.meshgrid(g, g)
    cells = np.column_stack([xx.ravel(), yy.ravel()])
    cells = cells[np.linalg.norm(cells, axis=1) <= well]
    sp = sponge.asset.params
    size = (float(sp["length"]), float(sp["width"]),
            float(sp["foam_thickness"]) + float(sp["scrub_thickness"]) + 0.002)
    return WipeTrace(plate=plate.body(), sponge=sponge.body(), plate_params=dict(p), sponge_size=size,
                     cells=cells, wiped=np.zeros(len(cells), bool), flat_top=_one_hull(plate.asset.usd))


def _one_hull(usd) -> bool:
    """Whether the package ``usd`` collides as one mesh (a convex hull: ``<link>/colliders/*``)."""
    from pxr import Usd

    stage = Usd.Stage.Open(str(usd))
    return sum(1 for q in stage.Traverse() if q.GetParent().GetName() == "colliders") == 1


def wipe_setup(world, rng: np.random.Generator) -> tuple[dict, WipeTrace]:
    """The episode's object poses (body -> (x, y, z, yaw)): the plate and the sponge on the table's
    near band, the mug, the bowl and the pushed object on its far band; and a new trace. ItemError
    when the world has no plate and sponge (:func:`stages.demos.kitchen.write_kitchen` parks them
    when the catalog has them)."""
    from pipeline.types import ItemError

    pl = world.placed
    if "plate" not in pl or "sponge" not in pl:
        raise ItemError(f"{world.usd}: no plate and sponge in this kitchen (a catalog with plate and sponge)")
    if "dish_rack" in pl and hasattr(world, "house"):  # a house kitchen's dishes (stages.demos.house_dishes):
        # where its layout put them
        objects = {}
        for role, yaw in (("plate", 0.0), ("sponge", float(rng.uniform(-0.2, 0.2)))):
            p = pl[role].position
            objects[pl[role].body()] = (p[0] + float(rng.uniform(-0.02, 0.02)), p[1], p[2], yaw)
        return objects, new_trace(world)
    x0, y0, x1, y1 = world.table_rect
    tx, z = 0.5 * (x0 + x1), world.table_z + 0.002
    if "dish_rack" in pl:  # a task kitchen with clean dishes' rack: the row of house_dishes on the near band
        from stages.demos.skill_rack import PLATE_BACK, RACK_FRONT, RACK_GAP, SPONGE_GAP, rack_box

        r, hx, hy = float(pl["plate"].asset.params["radius"]), *rack_box(pl["dish_rack"].asset.params)[:2]
        px = tx + 0.05 + float(rng.uniform(-0.02, 0.02))
        objects = {pl["plate"].body(): (px, y0 + PLATE_BACK + r, z, 0.0),
                   pl["sponge"].body(): (px + r + SPONGE_GAP, y0 + 0.12, z, float(rng.uniform(-0.2, 0.2))),
                   pl["dish_rack"].body(): (px - r - RACK_GAP - hx, y0 + RACK_FRONT + hy, z, 0.0)}
    else:
        objects = {pl["plate"].body(): (tx - 0.10 + float(rng.uniform(-0.02, 0.02)), y0 + 0.21, z, 0.0),
                   pl["sponge"].body(): (tx + 0.25 + float(rng.uniform(-0.02, 0.02)), y0 + 0.12, z,
                                         float(rng.uniform(-0.2, 0.2)))}
    far = {"mug": (-0.25, 0.14), "bowl": (0.02, 0.16), "pusher": (0.28, 0.12)}
    for role, (dx, back) in far.items():
        if role in pl:
            objects[pl[role].body()] = (tx + dx, y1 - back, z, 0.0)
    return objects, new_trace(world)


def wipe_plate_success(inst, state, peaks=None) -> tuple[bool, str]:
    """The wiped share of the plate's top at least :data:`COVERAGE`; the plate on the table top,
    flat; the sponge released on the table."""
    from stages.demos.predicates import _released, _upright

    trace: WipeTrace = inst.place
    w = inst.world
    plate = state.objects[trace.plate]
    if plate.position[2] < w.table_z - 0.01 or not _upright(plate.orientation):
        return False, "plate_moved"
    if trace.coverage < COVERAGE:
        return False, "not_wiped" if trace.samples else "no_contact"
    sponge = state.objects[trace.sponge]
    if sponge.position[2] < w.table_z - 0.01 or sponge.position[2] > w.table_z + 0.03:
        return False, "sponge_not_on_table"
    if not _released(state, trace.sponge):
        return False, "object_still_held"
    return True, ""


def _yaw(q) -> float:
    w, x, y, z = (float(v) for v in q)
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _rows(trace: WipeTrace, center, yaw: float) -> list[np.ndarray]:
    """The sponge centre's path (N, 2) [m] over the well: rows along the sponge's length (world
    ``yaw``), :data:`ROW_STEP` sponge widths apart, alternating direction, sampled every
    :data:`SAMPLE_STEP`."""
    sx, sy, _ = trace.sponge_size
    well = float(np.linalg.norm(trace.cells, axis=1).max()) + CELL / 2
    step = ROW_STEP * sy
    n = int(math.ceil((2 * well - sy) / step)) + 1
    offs = (np.arange(n) - (n - 1) / 2) * step
    along = np.array([math.cos(yaw), math.sin(yaw)])
    across = np.array([-along[1], along[0]])
    half = max(0.0, well - 0.25 * sx)
    rows = []
    for k, o in enumerate(offs):
        span = math.sqrt(max(well * well - o * o, 0.0)) if abs(o) < well else 0.0
        a = min(half, span)
        ts = np.linspace(-a, a, max(2, int(2 * a / SAMPLE_STEP) + 1))
        if k % 2:
            ts = ts[::-1]
        rows.append(np.asarray(center) + np.outer(ts, along) + o * across)
    return rows


def _touch_up_rows(trace: WipeTrace, center, yaw: float) -> list[np.ndarray]:
    """The sponge centre's path (N, 2) [m] over the cells of ``trace`` still unwiped, the plate at
    ``center``: rows along world ``yaw``, :data:`ROW_STEP` sponge widths apart across it, each over
    its band's unwiped cells (the sponge's half length short of their ends), alternating direction;
    the centre kept 1 cm inside the plate's rim (a sample counts only with the centre over the
    plate). Empty when everything is wiped."""
    missed = trace.cells[~trace.wiped]
    if not len(missed):
        return []
    sx, sy, _ = trace.sponge_size
    along = np.array([math.cos(yaw), math.sin(yaw)])
    across = np.array([-along[1], along[0]])
    u, v = missed @ along, missed @ across
    well = float(np.linalg.norm(trace.cells, axis=1).max()) + CELL / 2
    rim = float(trace.plate_params["radius"]) - 0.01
    step = ROW_STEP * sy
    band = np.floor((v - v.min()) / step).astype(int)
    rows = []
    for k, b in enumerate(np.unique(band)):
        m = band == b
        o = float(np.clip(0.5 * (v[m].min() + v[m].max()), -(well - sy / 2), well - sy / 2))
        lim = math.sqrt(max(rim * rim - o * o, 0.0))
        lo, hi = float(u[m].min()) + 0.25 * sx, float(u[m].max()) - 0.25 * sx
        lo, hi = (lo, hi) if lo <= hi else (0.5 * (lo + hi),) * 2
        lo, hi = float(np.clip(lo, -lim, lim)), float(np.clip(hi, -lim, lim))
        ts = np.linspace(lo, hi, max(2, int((hi - lo) / SAMPLE_STEP) + 1))
        if k % 2:
            ts = ts[::-1]
        rows.append(np.asarray(center, float) + np.outer(ts, along) + o * across)
    return rows


def wipe_plate(inst, d) -> None:
    """The expert (see the module doc)."""
    from stages.demos.driver import stow
    from stages.demos.counter import _pose, facing_north_goal
    from stages.simulate.control import top_down
    from stages.simulate.state import read_state

    w = inst.world
    trace: WipeTrace = inst.place
    sx, sy, sh = trace.sponge_size
    if sy > MAX_SPONGE_WIDTH:
        raise ExpertFailure("object_too_wide", f"sponge {sy * 1000:.0f} mm wide")
    sxy = np.asarray(inst.objects[trace.sponge][:2], float)
    s_yaw = float(inst.objects[trace.sponge][3])
    pxy = np.asarray(inst.objects[trace.plate][:2], float)
    tuck = stow(d, on_the_way=True)
    d.drive_to(facing_north_goal(w.table_rect[1], float((sxy[0] + pxy[0]) / 2)), w.grid(), tuck=tuck)
    top = w.table_z
    grasp_h = max(0.5 * sh, 0.014)  # TCP above the sponge's bottom [m]
    rot = top_down(s_yaw)  # fingers across the sponge's width
    d.grip(0.0, 0.2)
    at = np.array([*sxy, top + grasp_h])
    d.move(_pose(at + [0, 0, 0.10], rot), 1.5, segments=3, settle=0.1, tol=APPROACH_TOL)
    # the light sponge creeps on the table (turned up to 0.3 rad while the base drove up, measured):
    # grasp it where it lies now
    sp = read_state(d.sim).objects[trace.sponge]
    sxy, s_yaw = np.asarray(sp.position[:2], float), _yaw(sp.orientation)
    rot = top_down(s_yaw)
    at = np.array([*sxy, float(sp.position[2]) + grasp_h])
    d.move(_pose(at + [0, 0, 0.05], rot), 0.6, segments=2, settle=0.1, tol=APPROACH_TOL)
    d.move(_pose(at, rot), 0.6, segments=2, settle=0.2)
    d.grip(1.0, 0.8)
    d.move(_pose(at + [0, 0, 0.03], rot), 0.4, segments=1, carry=True)
    st = read_state(d.sim)
    if st.objects[trace.sponge].position[2] < top + 0.015:
        raise ExpertFailure("grasp_missed", f"sponge at {st.objects[trace.sponge].position}")
    plate_z = float(st.objects[trace.plate].position[2])
    pxy = np.asarray(st.objects[trace.plate].position[:2], float)
    wipe_yaw = 0.0  # rows along world x: the sponge turned to its length along them
    wrot = top_down(wipe_yaw)
    rows = _rows(trace, pxy, wipe_yaw)
    first = rows[0][0]
    d.move(_pose([*first, plate_z + 0.06 + grasp_h], wrot), 1.5, segments=3, carry=True, tol=APPROACH_TOL)

    def tcp_z(xy) -> float:
        under = float(trace.surface(np.linalg.norm(trace.footprint(xy, wipe_yaw) - pxy, axis=1)).max())
        return plate_z + under - PRESS + grasp_h

    d.move(_pose([*first, tcp_z(first)], wrot), 0.8, segments=2, settle=0.1)
    for k, row in enumerate(rows):
        if k:  # over to the next row, still pressing
            d.move(_pose([*row[0], tcp_z(row[0])], wrot), 0.3, segments=1)
        for xy in row[1:]:
            d.move(_pose([*xy, tcp_z(xy)], wrot), 0.1, segments=1)
            trace.record(read_state(d.sim))
    last = rows[-1][-1]
    for _ in range(TOUCH_UPS):
        if trace.coverage >= COVERAGE + TOUCH_UP_MARGIN:
            break
        pxy = np.asarray(read_state(d.sim).objects[trace.plate].position[:2], float)  # (tcp_z reads it)
        for row in _touch_up_rows(trace, pxy, wipe_yaw):
            # over to the row's start still pressing, at most 0.15 m/s (a quick drag shifts the plate)
            d.move(_pose([*row[0], tcp_z(row[0])], wrot), max(0.3, float(np.linalg.norm(row[0] - last)) / 0.15),
                   segments=2)
            trace.record(read_state(d.sim))
            for xy in row[1:]:
                d.move(_pose([*xy, tcp_z(xy)], wrot), 0.1, segments=1)
                trace.record(read_state(d.sim))
            last = row[-1]
    d.move(_pose([*last, plate_z + 0.06 + grasp_h], wrot), 0.8, segments=2, carry=True, tol=APPROACH_TOL)
    d.move(_pose([*sxy, top + grasp_h + 0.06], rot), 1.2, segments=3, carry=True, tol=APPROACH_TOL)
    d.move(_pose([*sxy, top + grasp_h + 0.004], rot), 0.6, segments=2, settle=0.1)
    d.grip(0.0, 0.6)
    d.move(_pose([*sxy, top + grasp_h + 0.12], rot), 0.8, segments=2, tol=APPROACH_TOL)
    stow(d)
