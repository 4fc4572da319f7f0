"""Job kind ``default_catalog``: write the built-in procedural catalog as one work item.

Its output folder ``<out>/<step>/default/`` is a catalog folder (sources + ``annotations.toml``) that an
``ingest`` step reads with ``catalog_step = "<this step's name>"``.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from pipeline.types import ItemContext, JobKind, PlanContext, WorkItem

CODE_DEPS = ("asset_catalog.generators", "asset_catalog.default_catalog")

ITEM_ID = "default"


class DefaultCatalogConfig(BaseModel):
    """variants: variants per category (>= 1); categories: subset of generator categories (all if empty);
    seed: catalog seed (None: the job seed)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    variants: int = Field(default=5, ge=1, le=1000)
    categories: tuple[str, ...] = ()
    seed: int | None = Field(default=None, ge=0)


class DefaultCatalogParams(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)
    variants: int
    categories: tuple[str, ...]
    seed: int


class DefaultCatalogResult(BaseModel):
    """catalog_dir: absolute path of the written catalog folder; asset_ids in order."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    catalog_dir: str
    asset_ids: tuple[str, ...]
    categories: tuple[str, ...]
    n_files: int
    seconds: float


def build_catalog_item(params: DefaultCatalogParams, ctx: ItemContext) -> DefaultCatalogResult:
    from asset_catalog.default_catalog import build_default_catalog

    rep = build_default_catalog(ctx.out_dir, variants_per_category=params.variants, seed=params.seed,
                                categories=params.categories or None)
    return DefaultCatalogResult(catalog_dir=str(ctx.final_dir), asset_ids=rep.asset_ids,
                                categories=rep.categories, n_files=rep.n_files, seconds=rep.seconds)


def plan_default_catalog(config: DefaultCatalogConfig, pctx: PlanContext) -> list[WorkItem]:
    seed = pctx.seed if config.seed is None else config.seed
    params = DefaultCatalogParams(variants=config.variants, categories=config.categories, seed=seed)
    return [WorkItem(item_id=ITEM_ID, fn="stages.catalog:build_catalog_item", params=params)]


DEFAULT_CATALOG_JOB = JobKind(name="default_catalog", config=DefaultCatalogConfig, plan=plan_default_catalog,
                              description="write the built-in procedural catalog (sources + annotations)")
