"""Ingest stage and the ``ingest`` job kind: catalog sources -> simulation-ready USD asset packages.

One work item per valid ``[[asset]]`` entry of the catalog's annotation file::

    load (mesh formats: stages.loaders.mesh; .urdf: stages.loaders.urdf; .xml/.mjcf: stages.loaders.mjcf)
      -> compute_colliders (stages.collision)   rng = ctx.rng("collision")
      -> annotate_physics (stages.annotate)     rng = ctx.rng("annotate")
      -> plausible size and mass (asset_catalog.plausibility): a unit mistake fails the item with the
         likely meters_per_unit, an odd size or mass without one is a warning
      -> usd_schemas.write_asset_package into ctx.out_dir
      -> usd_schemas.validate_package (any error -> ItemError)

An invalid entry (bad id, '../' or absolute source, unknown type, missing source, ...) becomes a
PlannedFailure; a bad source fails its own item with a one-line ItemError naming the file. The
cache key of an item covers its parameters, the source file and every file it references (MTL,
textures, glTF buffers, URDF/MJCF meshes and includes), so editing any of them re-ingests it.
``finalize`` writes the catalog index ``<work_dir>/catalog.sqlite`` with one record per entry, ok
or failed (with its reason).

Job TOML::

    [[step]]
    name = "assets"
    kind = "ingest"
    [step.config]
    catalog = "../shared/assets"                       # or catalog_step = "<default_catalog step>"
    annotations = "tests/data/shared_rigid/annotations.toml"   # default <catalog>/annotations.toml
    only = ["ycb_apple"]                               # optional subset of ids
    [step.config.limits]                                # stages.loaders.LoadLimits
    max_file_mb = 200
    [step.config.collision]                             # stages.collision.CollisionConfig
    max_hulls_per_piece = 10
"""

from __future__ import annotations

import logging
import re
import time
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, model_validator

from asset_catalog.annotations import (ANNOTATION_FILENAME, AssetAnnotation, CatalogError, load_annotations,
                                       resolve_source)
from pipeline.types import ItemContext, ItemError, JobKind, PlanContext, PlannedFailure, WorkItem
from stages.collision import CollisionConfig
from stages.loaders import MESH_SUFFIXES, LoadLimits

log = logging.getLogger(__name__)

CODE_DEPS = ("stages.loaders", "stages.collision", "stages.annotate", "usd_schemas",
             "asset_catalog.asset_model", "asset_catalog.materials", "asset_catalog.annotations",
             "asset_catalog.plausibility")

INGEST_FN = "stages.ingest:ingest_asset"
_COLLIDER_RECORD = {"none": "none", "hull": "convexHull", "hulls": "convexDecomposition",
                    "coacd": "convexDecomposition"}
_ITEM_ID_BAD = re.compile(r"[^A-Za-z0-9_.-]")


def _pipeline_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("agentworld")
    except PackageNotFoundError:
        return "0+unknown"


# ------------------------------------------------------------------------------------------- types


class IngestParams(BaseModel):
    """One asset to ingest: its annotation, the catalog folder and the source (absolute paths)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    annotation: AssetAnnotation
    catalog_dir: Path
    source: Path
    pipeline_version: str
    limits: LoadLimits = LoadLimits()
    collision: CollisionConfig = CollisionConfig()


class IngestResult(BaseModel):
    """What one ingested asset became.

    usd_path: root layer relative to the work dir (POSIX); bbox_min/bbox_max/dimensions [m] (Z-up
    asset frame); volume [m^3] (mass volume, see stages.annotate); mass [kg]; friction and
    restitution [-]; collider: "convexHull" | "convexDecomposition" | "none" (USD approximation),
    collider_method: "hull" | "hulls" | "coacd" | "none" (how they were made); n_colliders: convex
    collider prims; n_joints; validation_errors (always 0 for a result: errors fail the item) and
    validation_warnings; timings: seconds per sub-step (load, collision, annotate, write, validate).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    asset_id: str
    usd_path: str
    source: str
    source_sha256: str
    bbox_min: tuple[float, float, float]
    bbox_max: tuple[float, float, float]
    dimensions: tuple[float, float, float]
    volume: float
    mass: float
    static_friction: float
    dynamic_friction: float
    restitution: float
    collider: str
    collider_method: str
    n_colliders: int
    n_joints: int
    is_articulated: bool
    validation_errors: int
    validation_warnings: int
    timings: dict[str, float]


class IngestConfig(BaseModel):
    """The ``[step.config]`` of an ingest step.

    catalog: the catalog folder (sources + annotations.toml), or catalog_step: an earlier step whose
    single result has a ``catalog_dir`` (e.g. ``default_catalog``); annotations: the annotation file
    (default ``<catalog>/annotations.toml``); only: ingest just these ids (default all);
    limits / collision: stage parameters.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    catalog: Path | None = None
    catalog_step: str | None = None
    annotations: Path | None = None
    only: tuple[str, ...] = ()
    limits: LoadLimits = LoadLimits()
    collision: CollisionConfig = CollisionConfig()

    @model_validator(mode="after")
    def _one_catalog(self) -> "IngestConfig":
        if (self.catalog is None) == (self.catalog_step is None):
            raise ValueError("give exactly one of 'catalog' (a folder) or 'catalog_step' (an earlier step)")
        return self


# ------------------------------------------------------------------------------------------ stage


def ingest_asset(params: IngestParams, ctx: ItemContext) -> IngestResult:
    """Load, collide, annotate, write and validate one asset into ``ctx.out_dir`` (see module doc)."""
    import usd_schemas
    from stages.annotate import annotate_with_stats
    from stages.collision import collider_kind, compute_colliders
    from stages.loaders import load_source

    src = Path(params.source)
    timings: dict[str, float] = {}
    with _step("load", timings, src):
        model = load_source(src, params.annotation, limits=params.limits,
                            catalog_root=Path(params.catalog_dir))
        _check_model_extent(model, params.limits, src)
    with _step("collision", timings, src):
        model = compute_colliders(model, params.collision, ctx.rng("collision"))
    with _step("annotate", timings, src):
        model, stats = annotate_with_stats(model, ctx.rng("annotate"))
        _check_plausible(model, stats, src)
    with _step("write", timings, src):
        pkg = usd_schemas.write_asset_package(model, ctx.out_dir, pipeline_version=params.pipeline_version)
    with _step("validate", timings, src):
        report = usd_schemas.validate_package(pkg.root_path)
    if report.errors:
        raise ItemError(f"{src}: output fails validation: {' '.join(report.summary().split())[:400]}")
    method = collider_kind(model)
    rel = (ctx.final_dir / pkg.root_layer).relative_to(ctx.work_dir).as_posix()
    log.info("ingested %s: %s, %.3g kg, %d collider(s) (%s), %s", params.annotation.id, src.name, stats.mass,
             pkg.collider_count, method, " ".join(f"{k} {v:.2f}s" for k, v in timings.items()))
    return IngestResult(
        asset_id=params.annotation.id, usd_path=rel, source=params.annotation.source,
        source_sha256=model.source_sha256, bbox_min=stats.bbox_min, bbox_max=stats.bbox_max,
        dimensions=stats.dimensions, volume=stats.volume, mass=stats.mass,
        static_friction=stats.static_friction,
        dynamic_friction=stats.dynamic_friction, restitution=stats.restitution,
        collider=_COLLIDER_RECORD[method], collider_method=method,
        n_colliders=sum(len(lk.colliders) for lk in model.links), n_joints=len(model.joints),
        is_articulated=model.is_articulated, validation_errors=len(report.errors),
        validation_warnings=len(report.warnings), timings=timings)


class _step:
    """Times a sub-step into ``timings`` and makes every ItemError it raises name the source file."""

    def __init__(self, name: str, timings: dict[str, float], src: Path) -> None:
        self.name, self.timings, self.src = name, timings, src

    def __enter__(self) -> None:
        self.t0 = time.perf_counter()

    def __exit__(self, exc_type, exc, tb) -> bool:
        self.timings[self.name] = round(time.perf_counter() - self.t0, 4)
        if isinstance(exc, ItemError) and str(self.src) not in str(exc) and self.src.name not in str(exc):
            raise ItemError(f"{self.src}: {self.name}: {exc}") from exc
        return False


def _check_model_extent(model, limits: LoadLimits, src: Path) -> None:
    """Absurd-scale check for every source type (mesh sources are checked by their loader too)."""
    from stages.annotate import model_bounds

    lo, hi = model_bounds(model)
    largest = float((hi - lo).max())
    if largest <= 0.0:
        raise ItemError(f"{src}: no geometry")
    if largest < limits.min_dimension_m or largest > limits.max_dimension_m:
        raise ItemError(f"{src}: absurd scale: largest dimension {largest:.4g} m is outside "
                        f"[{limits.min_dimension_m:g}, {limits.max_dimension_m:g}] m (check meters_per_unit)")


def _check_plausible(model, stats, src: Path) -> None:
    """Size and mass against the category's plausible range (asset_catalog.plausibility): ItemError for a
    likely unit mistake (naming the meters_per_unit to set), a warning for an odd asset."""
    from asset_catalog.plausibility import judge

    ann = model.annotation
    verdict = judge(ann.category, max(stats.dimensions), stats.mass,
                    meters_per_unit=ann.meters_per_unit or 1.0,
                    mass_scales=ann.mass is None and not any(lk.mass_from_source for lk in model.links),
                    size_range=ann.plausible_size, mass_range=ann.plausible_mass)
    if verdict.verdict == "unit":
        raise ItemError(f"{src}: {verdict.message}")
    if verdict.verdict == "odd":
        log.warning("%s: %s", src, verdict.message)


# ----------------------------------------------------------------------------------------- planning


def catalog_dir_of(config: IngestConfig, pctx: PlanContext) -> Path:
    """The catalog folder of an ingest step (its own ``catalog`` or an earlier step's result)."""
    if config.catalog is not None:
        return Path(config.catalog)
    prev = pctx.previous.get(config.catalog_step or "")
    if not prev:
        raise CatalogError(f"ingest: catalog_step {config.catalog_step!r} has no result "
                           f"(is it an earlier step that succeeded?)")
    first = next(iter(prev.values()))
    cat = getattr(first, "catalog_dir", None)
    if cat is None:
        raise CatalogError(f"ingest: step {config.catalog_step!r} does not produce a catalog_dir")
    return Path(cat)


def annotations_file_of(config: IngestConfig, catalog_dir: Path) -> Path:
    return Path(config.annotations) if config.annotations is not None else catalog_dir / ANNOTATION_FILENAME


def plan_ingest(config: IngestConfig, pctx: PlanContext) -> list[WorkItem | PlannedFailure]:
    """One WorkItem per valid entry (filtered by ``only``), a PlannedFailure per invalid one."""
    catalog = catalog_dir_of(config, pctx).resolve()
    ann_file = annotations_file_of(config, catalog)
    loaded = load_annotations(catalog, ann_file)
    version = _pipeline_version()
    out: list[WorkItem | PlannedFailure] = []
    wanted = set(config.only)
    for inv in loaded.invalid:
        if not wanted or inv.id in wanted:
            out.append(PlannedFailure(item_id=_item_id(inv.id, inv.index), reason=inv.reason))
    for a in loaded.assets:
        if wanted and a.id not in wanted:
            continue
        try:
            src = resolve_source(catalog, a.source)
        except CatalogError as e:
            out.append(PlannedFailure(item_id=a.id, reason=f"{ann_file}: asset {a.id!r}: {e}"))
            continue
        if not src.is_file():
            out.append(PlannedFailure(item_id=a.id, reason=f"{src}: source file not found (asset {a.id!r} in "
                                                          f"{ann_file})"))
            continue
        params = IngestParams(annotation=a, catalog_dir=catalog, source=src, pipeline_version=version,
                              limits=config.limits, collision=config.collision)
        out.append(WorkItem(item_id=a.id, fn=INGEST_FN, params=params,
                            input_files=(src, *referenced_files(src, catalog))))
    missing = wanted - {a.id for a in loaded.assets} - {i.id for i in loaded.invalid}
    if missing:
        raise CatalogError(f"{ann_file}: 'only' names unknown asset id(s): {', '.join(sorted(missing))}")
    return out


def _item_id(ident: str, index: int) -> str:
    s = _ITEM_ID_BAD.sub("_", ident).strip("._-")
    return s if s and not s.startswith("#") else f"entry_{index}"


def referenced_files(src: Path, catalog: Path) -> tuple[Path, ...]:
    """Existing files inside ``catalog`` that a source references (for the cache key)."""
    suffix = src.suffix.lower()
    if suffix in MESH_SUFFIXES:
        from stages.loaders.mesh import referenced_files as mesh_refs

        return mesh_refs(src, catalog)
    if suffix in (".urdf", ".xml", ".mjcf"):
        found: dict[Path, None] = {}
        _xml_refs(src, catalog.resolve(), found, depth=0, base=None)
        found.pop(src.resolve(), None)
        return tuple(found)
    return ()


def _xml_refs(path: Path, root: Path, found: dict[Path, None], depth: int, base: Path | None) -> None:
    """Files named by ``filename``/``file`` attributes of a URDF/MJCF (recursing into MJCF includes);
    MJCF ``meshdir``/``texturedir``/``assetdir`` and URDF ``package://`` are tried as bases."""
    if depth > 8 or path in found:
        return
    try:
        tree = ET.parse(path)
    except (ET.ParseError, OSError) as e:
        log.debug("%s: references not listed: %s", path, e)
        return
    found[path.resolve()] = None
    top = base or path.parent
    dirs = [top]
    for comp in tree.iter("compiler"):
        for key in ("meshdir", "texturedir", "assetdir"):
            if comp.get(key):
                dirs.append((top / comp.get(key)).resolve())
    for el in tree.iter():
        for attr in ("filename", "file"):
            ref = el.get(attr)
            if not ref:
                continue
            cands = _candidates(ref, path, dirs, root)
            hit = next((c for c in cands if c.is_file() and c.is_relative_to(root)), None)
            if hit is None:
                continue
            if el.tag == "include":
                _xml_refs(hit, root, found, depth + 1, top)
            else:
                found[hit] = None


def _candidates(ref: str, path: Path, dirs: list[Path], root: Path) -> list[Path]:
    if ref.startswith("package://"):
        rest = ref[len("package://"):].split("/", 1)
        tail = rest[1] if len(rest) == 2 else rest[0]
        parents = [p for p in path.resolve().parents if p.is_relative_to(root)]
        return [(p / tail).resolve() for p in parents] + [(p / rest[0] / tail).resolve() for p in parents]
    if ref.startswith("file://"):
        ref = ref[len("file://"):]
    return [(d / ref).resolve() for d in [path.parent, *dirs]]


# ----------------------------------------------------------------------------------------- finalize


def finalize_ingest(config: IngestConfig, pctx: PlanContext, results: dict[str, Any]) -> None:
    """Write ``<work_dir>/catalog.sqlite``: one record per annotation entry, ok or failed."""
    from asset_catalog.index import CatalogRecord, index_path, write_index

    catalog = catalog_dir_of(config, pctx).resolve()
    ann_file = annotations_file_of(config, catalog)
    loaded = load_annotations(catalog, ann_file)
    failed = pctx.failed.get(pctx.step, {}) if pctx.step else {}
    wanted = set(config.only)
    records: list[CatalogRecord] = []
    for a in loaded.assets:
        if wanted and a.id not in wanted:
            continue
        base = dict(id=a.id, category=a.category, room_types=tuple(str(r) for r in a.room_types),
                    placement=str(a.placement), material=str(a.material), interactable=a.interactable,
                    co_occurrence=a.co_occurrence, source=a.source)
        r = results.get(a.id)
        if r is not None:
            records.append(CatalogRecord(
                **base, status="ok", usd_path=r.usd_path, bbox_min=r.bbox_min, bbox_max=r.bbox_max,
                dimensions=r.dimensions, volume=r.volume, mass=r.mass, static_friction=r.static_friction,
                dynamic_friction=r.dynamic_friction, restitution=min(max(r.restitution, 0.0), 1.0),
                collider=r.collider, n_colliders=r.n_colliders, is_articulated=r.is_articulated,
                n_joints=r.n_joints, source_sha256=r.source_sha256))
        else:
            reason = failed.get(a.id) or "not ingested (no result)"
            records.append(CatalogRecord(**base, status="failed", error=reason))
    for inv in loaded.invalid:
        if wanted and inv.id not in wanted:
            continue
        iid = _item_id(inv.id, inv.index)
        if any(rec.id == iid for rec in records):
            iid = f"entry_{inv.index}"
        records.append(CatalogRecord(id=iid, status="failed", error=inv.reason))
    path = write_index(index_path(pctx.work_dir), records)
    n_ok = sum(r.status == "ok" for r in records)
    log.info("catalog index %s: %d ok, %d failed", path, n_ok, len(records) - n_ok)


INGEST_JOB = JobKind(name="ingest", config=IngestConfig, plan=plan_ingest, finalize=finalize_ingest,
                     description="ingest a catalog folder into USD asset packages + the catalog index")
