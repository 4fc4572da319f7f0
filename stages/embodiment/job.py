"""The ``robots`` job kind: embodiment specs -> USD asset packages of their robots.

One work item per spec; its function is the ingest stage's own ``stages.ingest:ingest_asset``
with the parameters of ``stages.embodiment.sources.ingest_params`` (so the packages are made and
cached exactly like catalog assets; the cache key covers the spec's TOML files, the description and
every mesh it references). A spec that does not load or whose description is not found fails alone.

Job TOML::

    [[step]]
    name = "robots"
    kind = "robots"
    [step.config]
    specs = ["g1_29dof", "h1", "my_robot.toml"]   # shipped names, or TOML paths (job folder relative)
    shared_assets = "../shared/assets"             # optional (default: $AGENTWORLD_SHARED_ASSETS or ../shared/assets)
"""

from __future__ import annotations

from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field

from pipeline.types import ItemError, JobKind, PlanContext, PlannedFailure, WorkItem
from stages.collision import CollisionConfig
from stages.embodiment.spec import EmbodimentError, load_spec, spec_files


class RobotsConfig(BaseModel):
    """specs: shipped spec names or TOML paths; shared_assets: the shared third-party assets folder;
    collision: collider parameters (the specs choose the kind)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    specs: tuple[str, ...] = Field(min_length=1)
    shared_assets: Path | None = None
    collision: CollisionConfig = CollisionConfig()


def plan_robots(config: RobotsConfig, pctx: PlanContext) -> list[WorkItem | PlannedFailure]:
    from stages.embodiment.sources import ingest_params
    from stages.ingest import referenced_files

    shared = None if config.shared_assets is None else pctx.job_dir / config.shared_assets
    out: list[WorkItem | PlannedFailure] = []
    for source in config.specs:
        src = pctx.job_dir / source if source.endswith(".toml") else source
        try:
            spec = load_spec(src)
            params = ingest_params(spec, shared_assets=shared, pipeline_version=_version())
        except (EmbodimentError, ItemError) as e:
            out.append(PlannedFailure(item_id=Path(str(source)).stem, reason=str(e)))
            continue
        params = params.model_copy(update={"collision": config.collision})
        files = (*spec_files(src), params.source, *referenced_files(params.source, params.catalog_dir))
        out.append(WorkItem(item_id=spec.name, fn="stages.ingest:ingest_asset", params=params, input_files=files))
    return out


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("agentworld")
    except PackageNotFoundError:
        return "0+unknown"


ROBOTS_JOB = JobKind(name="robots", config=RobotsConfig, plan=plan_robots,
                     description="ingest embodiment specs' robot descriptions into USD asset packages")
