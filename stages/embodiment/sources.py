"""Where a spec's robot description lives, and its ingestion into a USD asset package.

Resolution (:func:`resolve_description`), in this order:

1. ``package``: the pip distribution's data root, the folder ``package://<package>/`` resolves to.
   For cmeel packages (example-robot-data) that is ``site-packages/cmeel.prefix/share/<package>``;
   it is found from the distribution's file list, as ``stages.simulate.robot`` finds the Panda;
2. ``shared``: that folder under the shared third-party assets (``shared_assets`` argument, else
   ``$AGENTWORLD_SHARED_ASSETS``, else ``../shared/assets`` beside the repository).

Ingestion (:func:`ingest_embodiment`) runs the project's articulated path, the ingest stage's own
function ``stages.ingest.ingest_asset`` (load URDF/MJCF -> colliders -> physics annotation -> USD
package -> validation), with the resolved root as the catalog folder, category ``robot`` and the
spec's collider kind. The package keeps what the source gives: joint limits, effort limits,
armature, damping, velocity limits; a legged or holonomic base stays movable, a fixed base is fixed.
The spec's drives (PD gains, overrides) are applied when the robot is simulated, not written.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

from pipeline.types import ItemError
from stages.embodiment.spec import BaseKind, DescriptionSpec, EmbodimentSpec

_REPO = Path(__file__).resolve().parents[2]


@dataclass(frozen=True)
class ResolvedDescription:
    """path: the URDF/MJCF file; root: the folder its ``file`` is relative to (the catalog folder
    for ingestion; ``package://<package>/`` resolves there); origin: "package" or "shared"."""

    path: Path
    root: Path
    origin: str


def default_shared_assets() -> Path:
    """``$AGENTWORLD_SHARED_ASSETS``, else ``../shared/assets`` beside the repository."""
    return Path(os.environ.get("AGENTWORLD_SHARED_ASSETS", _REPO.parent / "shared" / "assets"))


def package_data_root(package: str, file: str) -> Path | None:
    """The data root of the installed distribution ``package`` that holds ``file`` (relative), or
    None when the distribution is not installed or lacks the file."""
    try:
        dist = metadata.distribution(package)
    except metadata.PackageNotFoundError:
        return None
    suffix = "/" + Path(file).as_posix()
    for f in dist.files or ():
        if ("/" + f.as_posix()).endswith(suffix):
            p = Path(dist.locate_file(f))
            if p.is_file():
                return p.parents[len(Path(file).parts) - 1].resolve()
    return None


def resolve_description(desc: DescriptionSpec, *, shared_assets: Path | None = None) -> ResolvedDescription:
    """The description file of ``desc`` (see the module docstring). Raises ItemError naming what
    was tried."""
    tried = []
    if desc.package is not None:
        root = package_data_root(desc.package, desc.file)
        if root is not None:
            return ResolvedDescription(path=root / desc.file, root=root, origin="package")
        tried.append(f"pip package {desc.package!r}")
    if desc.shared is not None:
        root = (Path(shared_assets) if shared_assets is not None else default_shared_assets()) / desc.shared
        if (root / desc.file).is_file():
            return ResolvedDescription(path=(root / desc.file).resolve(), root=root.resolve(), origin="shared")
        tried.append(str(root / desc.file))
    raise ItemError(f"{desc.file}: robot description not found; tried {'; '.join(tried)}")


def robot_annotation(spec: EmbodimentSpec):
    """The catalog annotation of a spec's description: id = the spec's name, category ``robot``,
    the spec's collider kind; an arm mounted on the project's base (assembly ``mobile_base``) or a
    fixed base is fixed, a legged or holonomic robot keeps a movable root."""
    from asset_catalog.annotations import AssetAnnotation

    fixed = spec.base.kind == BaseKind.FIXED or spec.description.assembly == "mobile_base"
    return AssetAnnotation(id=spec.name, source=spec.description.file, category="robot", material="metal",
                           collider=spec.description.collider, fixed_base=fixed)


def ingest_params(spec: EmbodimentSpec, *, shared_assets: Path | None = None,
                  pipeline_version: str = "embodiment"):
    """The ingest stage's ``IngestParams`` for the spec's description (the resolved root is the
    catalog folder). Raises ItemError when the description is not found."""
    from stages.ingest import IngestParams

    res = resolve_description(spec.description, shared_assets=shared_assets)
    return IngestParams(annotation=robot_annotation(spec), catalog_dir=res.root, source=res.path,
                        pipeline_version=pipeline_version)


def ingest_embodiment(spec: EmbodimentSpec, out_dir: Path, *, shared_assets: Path | None = None,
                      seed: int = 0, pipeline_version: str = "embodiment"):
    """Ingest the spec's description into a USD asset package in ``out_dir`` (created) with the
    ingest stage's function, outside a job (the ``robots`` job kind does the same per spec);
    returns its ``IngestResult`` (``usd_path`` relative to ``out_dir.parent``). Raises ItemError
    naming the file."""
    from pipeline.types import ItemContext
    from stages.ingest import ingest_asset

    params = ingest_params(spec, shared_assets=shared_assets, pipeline_version=pipeline_version)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    ctx = ItemContext(item_id=spec.name, stage="ingest", seed=seed, out_dir=out_dir, final_dir=out_dir,
                      work_dir=out_dir.parent)
    return ingest_asset(params, ctx)
