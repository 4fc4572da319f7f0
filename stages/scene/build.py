"""One scene from a floor plan: populate -> check -> materials -> lighting -> compose -> settle -> validate.

``build_scene`` makes one attempt and raises ``SceneRejected`` with the reason when the attempt
fails (a required rule cannot be met, a check fails after repairs); the job makes several attempts
with different sub-seeds and records every rejection.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict

from stages.layout.floorplan import FloorPlan, load_floor_plan
from stages.scene.lighting import LightingConfig, LightSpec, plan_lights
from stages.scene.rules import PlacementRules
from stages.scene.library import Library
from stages.scene.room import room_interior
from stages.scene.solver import PlacementFailure, Populator
from stages.scene.verify import remove_instances, verify

log = logging.getLogger(__name__)

SCENE_JSON = "scene.json"


class SceneRejected(Exception):
    """This attempt produced no valid scene; the message is the reason."""


class InstanceRecord(BaseModel):
    """A placed asset as recorded in scene.json: position [m], yaw [rad]."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    name: str
    asset_id: str
    category: str
    room: str
    floor: int
    position: tuple[float, float, float]
    yaw: float
    support: str | None
    interactable: bool
    usd: str


class SceneSummary(BaseModel):
    """What ``build_scene`` produced: instance records, rooms populated, checks, lights, timings [s]."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    instances: tuple[InstanceRecord, ...]
    rooms: dict[str, str]
    placed: dict[str, dict[str, int]]
    candidates_rejected: dict[str, int]
    arrangements_rejected: dict[str, int] = {}
    repairs: tuple[str, ...]
    settle_max_move: float
    settle_simulated: float = 0.0
    settle_analytic: int = 0
    settle_bodies: int
    penetrations: int
    path_problems: int
    validation_errors: int
    validation_warnings: int
    looks: tuple[str, ...]
    lights: tuple[LightSpec, ...]
    seconds: dict[str, float]
    cpu_seconds: dict[str, float] = {}


@dataclass
class BuildOptions:
    """rooms: room types to populate (empty: all); n_looks: material variants; settle seconds [s]
    and tolerance [m]; max_repairs: settle repairs (drop offenders) before rejecting; validate: run
    usd_schemas.validate_package on the scene; settle: run the Newton settle check;
    settle_early_exit: stop the settle simulation early once every body is still (see StillExit)
    (``stages.scene.settle.StillExit``); cache_dir: where per-package check results (validation,
    rest) are kept across processes (``stages.scene.checkcache``; None: in this process only)."""

    rooms: tuple[str, ...] = ()
    n_looks: int = 3
    settle_seconds: float = 2.0
    settle_tolerance: float = 0.01
    max_repairs: int = 2
    validate: bool = True
    settle: bool = True
    settle_early_exit: bool = True
    lighting: LightingConfig = field(default_factory=LightingConfig)
    cache_dir: Path | None = None


def wall_rooms(plan: FloorPlan) -> dict[str, str]:
    """wall id -> id of a room it bounds (the wall's material follows that room's look)."""
    from stages.scene.geom import points_in_polygon

    out = {}
    for fl in plan.floors:
        for w in fl.walls:
            x0, y0, x1, y1 = w.box
            c = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
            off = np.array([0.0, 0.2]) if (x1 - x0) >= (y1 - y0) else np.array([0.2, 0.0])
            for r in fl.rooms:
                poly = np.asarray(r.polygon)
                if points_in_polygon(np.array([c + off, c - off]), poly).any():
                    out[w.id] = r.id
                    break
    return out


def build_scene(plan_path: Path, layout_usd: Path, library: Library, rules: PlacementRules,
                rng: np.random.Generator, out_dir: Path, final_dir: Path, opts: BuildOptions) -> SceneSummary:
    """One attempt: writes scene.usda + sublayers + textures + scene.json into ``out_dir`` (paths
    inside are relative and valid once the folder is moved to ``final_dir``)."""
    from stages.scene import compose
    from stages.scene.materials import ASSET_KINDS, FLOOR_KINDS, WALL_KINDS, sample_looks, write_textures

    secs: dict[str, float] = {}
    cpu: dict[str, float] = {}
    t, c = time.perf_counter(), time.process_time()
    plan = load_floor_plan(plan_path)
    pop = Populator(plan, layout_usd, library, rules, rng, shape_cache=opts.cache_dir)
    rooms = [r for f in plan.floors for r in f.rooms if not opts.rooms or str(r.type) in opts.rooms]
    if not rooms:
        raise SceneRejected(f"{plan_path}: no room of type {', '.join(opts.rooms)}")
    try:
        for r in rooms:
            pop.populate_room(r)
    except PlacementFailure as e:
        raise SceneRejected(f"placement: {e}") from None
    check = verify(pop)
    if not check.ok:
        raise SceneRejected("checks: " + "; ".join([f"{a} penetrates {b} {d * 1000:.1f} mm" for a, b, d in
                                                    check.penetrations] + list(check.path))[:300])
    secs["place"], cpu["place"] = time.perf_counter() - t, time.process_time() - c

    t, c = time.perf_counter(), time.process_time()
    out_dir.mkdir(parents=True, exist_ok=True)
    classes = sorted({i.p.record.material for i in pop.insts if i.p.record.material})
    textures = write_textures([*FLOOR_KINDS, *WALL_KINDS, *[f"asset_{c}" for c in classes if f"asset_{c}" in ASSET_KINDS]],
                              out_dir / "textures", rng, rel_to=out_dir)
    looks = sample_looks([r.id for r in rooms], classes, opts.n_looks, rng)
    light_rooms = [(r.id, room_interior(plan, r), plan.floors[r.floor].elevation, plan.floors[r.floor].ceiling_height)
                   for r in rooms]
    lights = plan_lights(light_rooms, opts.lighting, rng)
    walls = wall_rooms(plan)
    layout_final = Path(layout_usd).parent
    meta = {"plan": str(plan_path.name), "seed_note": "see scene.json"}
    # while checking, paths are relative to out_dir (where the files are); the final rewrite makes
    # them relative to final_dir (where the runner moves the folder)
    compose.write_root(out_dir, layout_usd, layout_final, out_dir, meta)
    compose.write_lighting(out_dir, lights)

    def instance_specs() -> list[compose.InstanceSpec]:
        return [compose.InstanceSpec(name=i.p.inst, usd=library.usd(i.p.record), position=i.p.position,
                                     yaw=i.p.yaw, material=i.p.record.material, room=i.p.room,
                                     support=i.p.support or "", category=i.p.record.category) for i in pop.insts]

    def write_instances() -> None:
        specs = instance_specs()
        compose.write_placement(out_dir, out_dir, specs)
        compose.write_materials(out_dir, looks, textures, specs, layout_usd, walls)

    write_instances()
    secs["compose"], cpu["compose"] = time.perf_counter() - t, time.process_time() - c
    scene = out_dir / compose.SCENE_NAME

    t, c = time.perf_counter(), time.process_time()
    repairs: list[str] = []
    max_move, bodies, simulated, analytic = 0.0, 0, 0.0, 0
    if opts.settle:
        from stages.scene.checkcache import process_cache
        from stages.scene.rest import analytic_rest, to_simulate

        cache = process_cache(opts.cache_dir)
        for attempt in range(opts.max_repairs + 1):
            proof = analytic_rest(pop, lambda i: _package_unknown(i, cache, opts.settle_tolerance))
            sim = to_simulate(pop, list(proof.unproven))
            analytic = len(pop.insts) - len(sim)
            if not sim:
                max_move, bodies, simulated = 0.0, 0, 0.0
                break
            rep = _settle(scene, opts, sim)
            max_move, bodies = (max(rep.moved.values()) if rep.moved else 0.0), rep.bodies
            simulated = rep.simulated
            if rep.passed:
                break
            if rep.nan:
                raise SceneRejected("settle: simulation produced NaN")
            if attempt == opts.max_repairs:
                worst = ", ".join(f"{k} {rep.moved[k] * 100:.1f} cm" for k in rep.offenders[:4])
                raise SceneRejected(f"settle: still moving after {opts.max_repairs} repairs: {worst}")
            repairs.extend(f"dropped {k} (moved {rep.moved[k] * 100:.1f} cm)" for k in rep.offenders)
            remove_instances(pop, set(rep.offenders))
            check = verify(pop)
            if not check.ok:
                raise SceneRejected("checks after repair: " + "; ".join(check.path)[:300])
            write_instances()
    secs["settle"], cpu["settle"] = time.perf_counter() - t, time.process_time() - c

    t, c = time.perf_counter(), time.process_time()
    n_err = n_warn = 0
    if opts.validate:
        from stages.scene.checkcache import process_cache
        from stages.scene.validation import validate_scene

        packages = sorted({library.usd(i.p.record) for i in pop.insts}) + [Path(layout_usd)]
        vr = validate_scene(scene, packages, process_cache(opts.cache_dir))
        n_err, n_warn = len(vr.errors), vr.warnings
        if n_err:
            raise SceneRejected(f"validation: {n_err} errors: " + "; ".join(vr.errors[:3])[:400])
    secs["validate"], cpu["validate"] = time.perf_counter() - t, time.process_time() - c
    t, c = time.perf_counter(), time.process_time()
    if Path(final_dir).resolve() != Path(out_dir).resolve():
        # stages the checks opened (Newton's USD loader, the validators) can sit in reference cycles
        # until the garbage collector runs; such a stage is not reloaded (reload=False): it would
        # recompose with paths that resolve only from the final folder, and warn about each. (A full
        # gc.collect() here instead cost 0.1-0.9 s of CPU per scene in a process holding a library.)
        compose.write_root(out_dir, layout_usd, layout_final, final_dir, meta, reload=False)
        compose.write_placement(out_dir, final_dir, instance_specs(), reload=False)
    secs["finalize"], cpu["finalize"] = time.perf_counter() - t, time.process_time() - c

    records = tuple(InstanceRecord(name=i.p.inst, asset_id=i.p.record.id, category=i.p.record.category, room=i.p.room,
                                   floor=i.p.floor, position=i.p.position, yaw=i.p.yaw, support=i.p.support,
                                   interactable=i.p.record.interactable, usd=str(library.usd(i.p.record)))
                    for i in pop.insts)
    rejected: dict[str, int] = {}
    for rr in pop.reports:
        for k, v in rr.rejected.items():
            key = k.split(" (")[0]
            rejected[key] = rejected.get(key, 0) + v
    summary = SceneSummary(
        instances=records, rooms={r.id: str(r.type) for r in rooms},
        placed={rr.room: rr.placed for rr in pop.reports}, candidates_rejected=rejected,
        arrangements_rejected=arrangement_reasons(pop), repairs=tuple(repairs),
        settle_max_move=max_move, settle_simulated=simulated, settle_analytic=analytic, settle_bodies=bodies, penetrations=len(check.penetrations),
        path_problems=len(check.path), validation_errors=n_err, validation_warnings=n_warn,
        looks=tuple(lk.name for lk in looks), lights=tuple(lights), seconds={k: round(v, 3) for k, v in secs.items()},
        cpu_seconds={k: round(v, 3) for k, v in cpu.items()})
    (out_dir / SCENE_JSON).write_text(summary.model_dump_json(indent=1) + "\n", encoding="utf-8")
    return summary


def arrangement_reasons(pop: Populator) -> dict[str, int]:
    """Room arrangements given up while populating (see ``Populator.populate_room``), counted by
    reason, the room id replaced by its type ("kitchen: could not place required fridge (...)")."""
    out: dict[str, int] = {}
    for rr in pop.reports:
        for reason in rr.arrangements_rejected:
            key = f"{rr.room_type}: {reason.split(': ', 1)[-1]}"
            out[key] = out.get(key, 0) + 1
    return out


def _settle(scene: Path, opts: BuildOptions, instances: Sequence[str] | None = None):
    from stages.scene.settle import StillExit, settle_check

    return settle_check(scene, seconds=opts.settle_seconds, tolerance=opts.settle_tolerance,
                        early_exit=StillExit() if opts.settle_early_exit else None, instances=instances)


def _package_unknown(inst, cache, tolerance: float) -> str | None:
    """Why an instance's package is not known to rest on a flat floor (None: it is): a dynamic
    package of several bodies, or any package with joints gravity works on, must pass the package
    rest check (``stages.scene.rest.package_rest``, cached per package content)."""
    from stages.scene.rest import package_rest

    geo = inst.geo
    if not ((geo.dynamic and geo.n_bodies > 1) or not geo.neutral_joints):
        return None
    r = package_rest(geo.usd_path, geo, cache, tolerance=tolerance)
    return None if r["passed"] else f"the package alone moves {r['moved'] * 100:.1f} cm on a flat floor"


def populate_rooms(plan_path: Path, layout_usd: Path, library: Library, rules: PlacementRules,
                   rng: np.random.Generator, rooms: Sequence[str] = ()) -> Populator:
    """Only the placement step (used by the benchmark): a Populator with every room populated."""
    plan = load_floor_plan(plan_path)
    pop = Populator(plan, layout_usd, library, rules, rng)
    for r in (r for f in plan.floors for r in f.rooms if not rooms or str(r.type) in rooms):
        pop.populate_room(r)
    return pop


def write_json(path: Path, obj) -> None:
    path.write_text(json.dumps(obj, indent=1) + "\n", encoding="utf-8")
