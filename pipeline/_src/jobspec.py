"""Job files (``jobs/<name>.toml``) and their validation.

Shape::

    [job]
    name = "main"            # [A-Za-z0-9_][A-Za-z0-9_.-]*
    seed = 0                 # job seed; item seeds = derive_seed(seed, kind name, item id)
    out = "out/main"         # output root (work dir); default "out/<name>"; CLI --out overrides
    executor = "local"       # local | ray | inline; CLI --executor overrides
    workers = 2              # 0 = os.cpu_count()
    retries = 1              # extra attempts after an unexpected exception (never after ItemError)
    ray_address = "auto"     # optional; Ray cluster to connect to (else a local one is started)

    [[step]]
    name = "assets"          # unique; outputs go to <out>/<step name>/<item_id>/
    kind = "ingest"          # key of stages.jobkinds.JOB_KINDS, or a direct "module:attribute"
    [step.config]            # validated by the JobKind's ``config`` model (extra keys forbidden)
    catalog = "catalogs/default"

Relative paths: a job file inside a folder named ``jobs`` resolves relative paths (``[job] out`` and
every path-typed field of a step's config) against that folder's parent, i.e. the repository root
for ``jobs/main.toml``; a job file anywhere else resolves them against its own folder. That base
folder is ``JobSpec.base_dir`` and reaches planners as ``PlanContext.job_dir``. Paths given on the
command line (``--out``, ``agentworld ingest CATALOG``) resolve against the current directory.

Path fields of a config model: a field annotated ``Path`` (also ``Path | None``, ``list[Path]``,
``tuple[Path, ...]``) is resolved against the base folder and must exist, unless it is declared with
``Field(json_schema_extra={"must_exist": False})`` (e.g. an output path). pydantic's ``FilePath`` /
``DirectoryPath`` are resolved too and check existence themselves. Nested models are not walked.

Every problem of a file is collected into one ``JobError`` whose message names the file and, for
each problem, the key (``job.workers``, ``step[0].config.catalog``) and what is wrong.
"""

from __future__ import annotations

import tomllib
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from pipeline._src.registry import KindError, Registry, resolve_kind

NAME_PATTERN = r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$"
RESERVED_STEP_NAMES = frozenset({"reports", "logs"})


class JobError(ValueError):
    """An invalid job file; the message names the file and every problem (key: what is wrong)."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class JobSection(_Strict):
    """The ``[job]`` table."""

    name: str = Field(pattern=NAME_PATTERN, max_length=128)
    seed: int = Field(default=0, ge=0)
    out: str | None = None
    executor: Literal["local", "ray", "inline"] = "local"
    workers: int = Field(default=0, ge=0, le=4096)
    retries: int = Field(default=1, ge=0, le=100)
    ray_address: str | None = None


class _StepTable(_Strict):
    name: str = Field(pattern=NAME_PATTERN, max_length=128)
    kind: str = Field(min_length=1)
    config: dict[str, Any] = Field(default_factory=dict)


class _JobFile(_Strict):
    job: JobSection
    step: list[_StepTable] = Field(min_length=1)


class StepSpec(BaseModel):
    """One validated step: its name, kind and the kind's validated config model."""

    model_config = ConfigDict(frozen=True, arbitrary_types_allowed=True)

    name: str
    kind: str
    config: BaseModel


class JobSpec(BaseModel):
    """A validated job.

    name, seed, executor, workers, retries, ray_address: from ``[job]``;
    out: the output root (absolute); steps: in run order;
    job_file: the TOML file (None for a job built in memory); source: the job file's path, or the
    label of an in-memory job (used in messages); base_dir: where relative paths resolve.
    """

    model_config = ConfigDict(frozen=True, arbitrary_types_allowed=True)

    name: str
    seed: int = 0
    out: Path
    executor: Literal["local", "ray", "inline"] = "local"
    workers: int = 0
    retries: int = 1
    ray_address: str | None = None
    steps: tuple[StepSpec, ...]
    job_file: Path | None = None
    source: str = ""
    base_dir: Path


def base_dir_for(job_file: Path) -> Path:
    """The folder that relative paths of ``job_file`` resolve against (see module docstring)."""
    folder = job_file.resolve().parent
    return folder.parent if folder.name == "jobs" else folder


def load_job(path: str | Path, *, registry: Registry | None = None) -> JobSpec:
    """Read and validate a job file (including each step's config); raises JobError."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise JobError(f"{path}: job file not found") from None
    except OSError as e:
        raise JobError(f"{path}: cannot read job file: {e.strerror or e}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise JobError(f"{path}: not valid TOML: {e}") from None
    return build_job(data, source=path, base_dir=base_dir_for(path), registry=registry)


def build_job(data: Mapping[str, Any], *, source: str | Path, base_dir: Path,
              registry: Registry | None = None) -> JobSpec:
    """Validate a job given as a mapping shaped like the TOML file (e.g. built by the CLI).

    source: the file name used in error messages (the job file, or a label such as ``"<ingest>"``).
    """
    base_dir = Path(base_dir).resolve()
    try:
        raw = _JobFile.model_validate(data)
    except ValidationError as e:
        raise JobError(f"{source}: " + "; ".join(_format_errors(e, data))) from None
    problems: list[str] = []
    steps: list[StepSpec] = []
    seen: set[str] = set()
    for i, st in enumerate(raw.step):
        where = f"step[{i}]"
        if st.name in seen:
            problems.append(f"{where}.name: duplicate step name {st.name!r}")
        if st.name in RESERVED_STEP_NAMES:
            problems.append(f"{where}.name: {st.name!r} is reserved for the runner's own folders")
        seen.add(st.name)
        try:
            kind = resolve_kind(st.kind, registry)
        except KindError as e:
            problems.append(f"step {st.name!r} kind: {e}")
            continue
        config, errs = validate_config(kind.config, st.config, base_dir)
        label = f"step {st.name!r}"
        problems.extend(f"{label} {msg}" if msg.startswith("config:") else f"{label} config.{msg}"
                        for msg in errs)
        if config is not None:
            steps.append(StepSpec(name=st.name, kind=st.kind, config=config))
    if problems:
        raise JobError(f"{source}: " + "; ".join(problems))
    j = raw.job
    out = Path(j.out) if j.out else Path("out") / j.name
    return JobSpec(name=j.name, seed=j.seed, out=(base_dir / out).resolve(), executor=j.executor,
                   workers=j.workers, retries=j.retries, ray_address=j.ray_address, steps=tuple(steps),
                   job_file=Path(source).resolve() if isinstance(source, Path) else None, source=str(source),
                   base_dir=base_dir)


def validate_config(model: type[BaseModel], raw: Mapping[str, Any], base_dir: Path
                    ) -> tuple[BaseModel | None, list[str]]:
    """Validate a step's config table; returns (model or None, ["key: problem", ...])."""
    if not isinstance(raw, Mapping):
        return None, ["config: must be a table"]
    resolved = _resolve_paths(model, dict(raw), base_dir)
    try:
        cfg = model.model_validate(resolved)
    except ValidationError as e:
        return None, _format_errors(e, resolved)
    missing = [f"{name}: path does not exist: {p}" for name, p in _paths_to_check(cfg) if not p.exists()]
    return (None, missing) if missing else (cfg, [])


# ---------------------------------------------------------------------------------------------------
# helpers


def _format_errors(e: ValidationError, data: Any) -> list[str]:
    """pydantic errors as ``"key.path: message (got <value>)"`` lines; list indices as ``[i]``."""
    out = []
    for err in e.errors():
        key = ""
        for part in err["loc"]:
            key += f"[{part}]" if isinstance(part, int) else (f".{part}" if key else str(part))
        key = key or "(top level)"
        if err["type"] == "extra_forbidden":
            out.append(f"{key}: unknown key")
        elif err["type"] == "missing":
            out.append(f"{key}: missing required key")
        else:
            got = err.get("input")
            shown = repr(got) if not isinstance(got, (dict, list)) else type(got).__name__
            if len(shown) > 60:
                shown = shown[:57] + "..."
            out.append(f"{key}: {err['msg']} (got {shown})")
    return out


def _has_path(ann: Any) -> bool:
    if isinstance(ann, type) and issubclass(ann, Path):
        return True
    return any(_has_path(a) for a in typing.get_args(ann) if a is not Ellipsis)


def _is_checked_path(ann: Any) -> bool:
    """True for pydantic's FilePath/DirectoryPath/NewPath (Annotated with a PathType)."""
    if typing.get_origin(ann) is typing.Annotated:
        return any(type(m).__name__ == "PathType" for m in ann.__metadata__)
    return any(_is_checked_path(a) for a in typing.get_args(ann))


def _resolve_value(v: Any, base: Path) -> Any:
    if isinstance(v, (str, Path)) and str(v):
        p = Path(v).expanduser()
        return str(p if p.is_absolute() else (base / p))
    if isinstance(v, (list, tuple)):
        return [_resolve_value(x, base) for x in v]
    return v


def _resolve_paths(model: type[BaseModel], raw: dict[str, Any], base: Path) -> dict[str, Any]:
    for name, f in model.model_fields.items():
        key = next((k for k in (f.alias, name) if k and k in raw), None)
        if key is not None and _has_path(f.annotation):
            raw[key] = _resolve_value(raw[key], base)
    return raw


def _paths_to_check(cfg: BaseModel) -> list[tuple[str, Path]]:
    out: list[tuple[str, Path]] = []
    for name, f in type(cfg).model_fields.items():
        extra = f.json_schema_extra if isinstance(f.json_schema_extra, dict) else {}
        checked = _is_checked_path(f.annotation) or any(type(m).__name__ == "PathType" for m in f.metadata)
        if not _has_path(f.annotation) or checked or extra.get("must_exist") is False:
            continue
        val = getattr(cfg, name)
        vals = val if isinstance(val, (list, tuple)) else [val]
        out.extend((name, v) for v in vals if isinstance(v, Path))
    return out

