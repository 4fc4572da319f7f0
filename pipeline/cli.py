"""The ``agentworld`` command.

    agentworld run JOB.toml [--out DIR] [--executor local|ray|inline] [--workers N] [--ray-address A]
    agentworld ingest CATALOG_DIR [--annotations FILE] [--out DIR] [...]   # one-step "ingest" job
    agentworld catalog list [--category C] [--room R] [--placement P] [--work-dir out/main]
    agentworld catalog build-default --out DIR [--variants N]
    agentworld status [--out DIR]
    agentworld <extra>  ...                       # subcommands registered in stages/commands.py

Starts fast: only argparse at import time; the runner, rich and the stage modules load when a
subcommand needs them (never pxr, warp or torch for the built-in subcommands' start-up).
Exit status: 0 success, 1 error (invalid job, finalize failure, ...), 2 usage error,
3 items failed and ``--strict`` was given, 130 interrupted.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)

BUILTIN = ("run", "ingest", "catalog", "status")
EXIT_OK, EXIT_ERROR, EXIT_USAGE, EXIT_FAILED_ITEMS, EXIT_INTERRUPTED = 0, 1, 2, 3, 130
LOG_LEVELS = ("DEBUG", "INFO", "WARNING", "ERROR")


LEGACY_ALIASES = {"catalog-build-default": ["catalog", "build-default"]}
"""Old spellings still accepted (not listed in ``--help``)."""


def _extra_commands() -> dict[str, tuple[str, str]]:
    """name -> ("module:function", one-line help) of the commands in ``stages.commands``."""
    try:
        from stages.commands import COMMANDS
    except ImportError:
        return {}
    out = {}
    for name, entry in COMMANDS.items():
        if name not in BUILTIN:
            ref, help_text = (entry, "") if isinstance(entry, str) else entry
            out[name] = (ref, help_text)
    return out


def _add_run_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", type=Path, help="output root (work dir); overrides the job's [job] out")
    p.add_argument("--executor", choices=("local", "ray", "inline"), help="overrides the job's executor")
    p.add_argument("--workers", type=int, help="worker processes / Ray CPUs (0 = all cores)")
    p.add_argument("--ray-address", help="Ray cluster address to connect to (else a local cluster starts)")
    p.add_argument("--retries", type=int, help="retries after an unexpected exception (overrides the job)")
    p.add_argument("--retry-failed", action="store_true",
                   help="recompute items that failed with bad input even if their inputs did not change")
    p.add_argument("--log-level", choices=LOG_LEVELS, default="INFO",
                   help="log level (stderr and logs/job.log)")
    p.add_argument("--verbose", "-v", action="store_true",
                   help="also show INFO messages on stderr (by default they go to logs/job.log only)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--strict", action="store_true", help="exit with status 3 if any item failed")


def build_parser() -> argparse.ArgumentParser:
    extras = _extra_commands()
    parser = argparse.ArgumentParser(
        prog="agentworld", description="AgentWorld: USD asset pipeline and dataset factory.",
        epilog="Each command has its own --help.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser("run", help="run a job (jobs/<name>.toml)")
    p.add_argument("job", type=Path, help="job TOML file")
    _add_run_options(p)

    p = sub.add_parser("ingest", help="ingest a catalog folder into USD asset packages (one-step job)")
    p.add_argument("catalog", type=Path, help="catalog folder (source files + annotations.toml)")
    p.add_argument("--annotations", type=Path, help="annotation file (default: <catalog>/annotations.toml)")
    p.add_argument("--seed", type=int, default=0, help="job seed")
    p.add_argument("--step-name", default="assets", help="step name (= output folder under --out)")
    _add_run_options(p)
    p.set_defaults(out_default=Path("out/ingest"))

    p = sub.add_parser("catalog", help="list the catalog index (list) or write the built-in procedural "
                                       "catalog (build-default)")
    csub = p.add_subparsers(dest="catalog_command", metavar="ACTION")
    csub.required = True
    c = csub.add_parser("list", help="list assets of the catalog index")
    c.add_argument("--category")
    c.add_argument("--room", help="room type, e.g. kitchen")
    c.add_argument("--placement", help="placement kind, e.g. on_surface")
    inter = c.add_mutually_exclusive_group()
    inter.add_argument("--interactable", action="store_const", const=True, dest="interactable")
    inter.add_argument("--basic", action="store_const", const=False, dest="interactable")
    c.add_argument("--status", choices=("ok", "failed", "all"), default="ok")
    c.add_argument("--work-dir", type=Path, default=Path("out/main"), help="work dir holding catalog.sqlite")
    c.add_argument("--db", type=Path, help="catalog index file (default: <work-dir>/catalog.sqlite)")
    c.add_argument("--json", action="store_true", help="print JSON lines instead of a table")
    csub.add_parser("build-default", help="write the built-in procedural catalog (--out DIR [--variants N])",
                    add_help=False)

    p = sub.add_parser("status", help="show the state of a work dir")
    p.add_argument("--out", type=Path, default=Path("out/main"), help="work dir")
    p.add_argument("--failures", type=int, default=50, help="show at most this many failures")

    for name, (_ref, help_text) in sorted(extras.items()):
        sub.add_parser(name, help=help_text or name, add_help=False)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] in LEGACY_ALIASES:
        argv = LEGACY_ALIASES[argv[0]] + argv[1:]
    extras = _extra_commands()
    if argv and argv[0] in extras:
        from pipeline._src.registry import import_object

        return int(import_object(extras[argv[0]][0])(argv[1:]) or 0)
    if argv[:2] == ["catalog", "build-default"]:
        from asset_catalog.default_catalog import main as build_default

        return int(build_default(argv[2:]) or 0)
    args = build_parser().parse_args(argv)
    try:
        if args.command == "run":
            return _cmd_run(args)
        if args.command == "ingest":
            return _cmd_ingest(args)
        if args.command == "catalog":
            return _cmd_catalog_list(args)
        return _cmd_status(args)
    except KeyboardInterrupt:
        print("agentworld: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


def _console() -> Any:
    from rich.console import Console

    return Console(stderr=True)


def _setup_logging(level: str, console: Any, *, verbose: bool = False) -> None:
    """Root logger at ``level`` (what logs/job.log records); stderr shows WARNING and above of our
    own packages unless ``verbose`` (then INFO and third-party records too), so the progress bar
    stays readable. Third-party chatter goes to logs/job.log (``pipeline._src.chatter``)."""
    from rich.logging import RichHandler

    from pipeline._src.chatter import OwnRecords

    handler = RichHandler(console=console, show_path=False, rich_tracebacks=False, markup=False)
    if not verbose:
        handler.addFilter(OwnRecords())
    handler.setFormatter(logging.Formatter("%(name)s: %(message)s"))
    numeric = logging.getLevelName(level)
    handler.setLevel(level if verbose or numeric >= logging.WARNING else logging.WARNING)
    root = logging.getLogger()
    root.handlers[:] = [handler]
    root.setLevel(level)


def _execute(job: Any, args: argparse.Namespace, registry: Any = None) -> int:
    from pipeline._src.report import render_summary, stdout_console
    from pipeline._src.runner import run_job

    console = _console()
    _setup_logging(args.log_level, console, verbose=getattr(args, "verbose", False))
    summary = run_job(job, out=args.out, executor=args.executor, workers=args.workers, retries=args.retries,
                      ray_address=args.ray_address, registry=registry,
                      progress=False if args.no_progress else None,
                      log_level=args.log_level, console=console, retry_failed=args.retry_failed)
    render_summary(summary, stdout_console())
    return EXIT_FAILED_ITEMS if args.strict and summary.failed else EXIT_OK


def _job_errors() -> tuple[type[BaseException], ...]:
    from pipeline._src.jobspec import JobError

    return (JobError,)


def _cmd_run(args: argparse.Namespace) -> int:
    from pipeline._src.jobspec import load_job

    try:
        job = load_job(args.job)
        return _execute(job, args)
    except _job_errors() as e:
        print(f"agentworld: error: {e}", file=sys.stderr)
        log.debug("error details", exc_info=True)
        return EXIT_ERROR


def ingest_job_data(catalog: Path, annotations: Path | None, *, seed: int = 0, out: Path = Path("out/ingest"),
                    step_name: str = "assets") -> dict[str, Any]:
    """The in-memory job of ``agentworld ingest``: one step of kind "ingest" (paths made absolute)."""
    config: dict[str, Any] = {"catalog": str(catalog.resolve())}
    if annotations is not None:
        config["annotations"] = str(annotations.resolve())
    return {"job": {"name": "ingest", "seed": seed, "out": str(out.resolve())},
            "step": [{"name": step_name, "kind": "ingest", "config": config}]}


def _cmd_ingest(args: argparse.Namespace) -> int:
    from pipeline._src.jobspec import build_job

    try:
        data = ingest_job_data(args.catalog, args.annotations, seed=args.seed,
                               out=args.out or args.out_default, step_name=args.step_name)
        job = build_job(data, source="agentworld ingest", base_dir=Path.cwd())
        return _execute(job, args)
    except _job_errors() as e:
        print(f"agentworld: error: {e}", file=sys.stderr)
        log.debug("error details", exc_info=True)
        return EXIT_ERROR


def _cmd_catalog_list(args: argparse.Namespace) -> int:
    from rich.table import Table
    from rich.text import Text

    from asset_catalog.index import index_path, query_index
    from pipeline._src.report import stdout_console

    db = args.db or index_path(args.work_dir)
    if not db.is_file():
        print(f"agentworld: error: {db}: no catalog index (run an ingest job first)", file=sys.stderr)
        return EXIT_ERROR
    recs = query_index(db, category=args.category, room=args.room, placement=args.placement,
                       interactable=args.interactable, status=None if args.status == "all" else args.status)
    if args.json:
        for r in recs:
            print(r.model_dump_json())
        return EXIT_OK
    t = Table(title=Text(f"{len(recs)} asset(s) in {db}"), title_justify="left")
    for col in ("id", "category", "rooms", "placement", "material", "interactable", "size [m]", "mass [kg]",
                "collider", "status"):
        t.add_column(Text(col), overflow="fold", no_wrap=col in ("id", "category"))
    for r in recs:
        size = "x".join(f"{v:.2f}" for v in r.dimensions) if r.dimensions else ""
        t.add_row(Text(r.id), Text(r.category), Text(",".join(r.room_types)), Text(r.placement or ""),
                  Text(r.material or ""), "yes" if r.interactable else "no", size,
                  f"{r.mass:.3g}" if r.mass is not None else "", Text(r.collider or ""),
                  Text(r.status if r.status == "ok" else f"failed: {r.error}"))
    stdout_console().print(t)
    return EXIT_OK


def _cmd_status(args: argparse.Namespace) -> int:
    from pipeline._src.status import print_status

    return print_status(args.out, max_failures=args.failures)


if __name__ == "__main__":
    raise SystemExit(main())
