"""Real, small stage functions and job kinds for the runner's tests.

``TEXT_KIND`` plans one item per text file of a folder; its stage function normalises the text,
writes it with a seeded random salt and a digest, and returns a typed result. ``MERGE_KIND`` plans
one item that depends on every text item and concatenates their outputs. ``TRIVIAL_KIND`` plans N
items that write one tiny file each (runner overhead benchmark).
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field

from pipeline.types import ItemContext, ItemError, JobKind, PlanContext, PlannedFailure, WorkItem


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


# --- text files ------------------------------------------------------------------------------------


class TextConfig(_Strict):
    folder: Path
    pattern: str = "*.txt"
    sleep_s: float = 0.0
    bad: list[str] = []             # item ids whose content is "bad" (ItemError)
    crash: list[str] = []           # item ids that always raise RuntimeError
    die: list[str] = []             # item ids whose worker process dies (os._exit)
    flaky: list[str] = []           # item ids that raise once, then succeed
    flaky_dir: Path | None = Field(default=None, json_schema_extra={"must_exist": False})
    rejected: list[str] = []        # item ids rejected at planning time (PlannedFailure)


class TextParams(_Strict):
    source: Path
    sleep_s: float = 0.0
    mode: str = "ok"                # ok | bad | crash | flaky | die
    flaky_marker: Path | None = None


class TextResult(_Strict):
    item_id: str
    words: int
    sha256: str
    salt: int
    relpath: str


def process_text(params: TextParams, ctx: ItemContext) -> TextResult:
    """Upper-case and word-wrap a text file; write ``text.txt`` and ``meta.json`` into ctx.out_dir."""
    if params.sleep_s:
        time.sleep(params.sleep_s)
    if params.mode == "bad":
        raise ItemError(f"{params.source}: content is not acceptable\n(second line of detail)")
    if params.mode == "crash":
        raise RuntimeError(f"boom in {ctx.item_id}")
    if params.mode == "die":
        os._exit(17)
    if params.mode == "flaky" and params.flaky_marker is not None:
        if not params.flaky_marker.exists():
            params.flaky_marker.parent.mkdir(parents=True, exist_ok=True)
            params.flaky_marker.write_text("attempted once")
            raise ConnectionError("transient failure")
    words = params.source.read_text(encoding="utf-8").split()
    salt = int(ctx.rng("salt").integers(0, 1_000_000))
    body = "\n".join(" ".join(w.upper() for w in words[i:i + 5]) for i in range(0, len(words), 5))
    (ctx.out_dir / "text.txt").write_text(f"{body}\nsalt={salt}\n", encoding="utf-8")
    sha = hashlib.sha256(body.encode()).hexdigest()
    meta = {"item": ctx.item_id, "stage": ctx.stage, "seed": ctx.seed, "words": len(words), "sha256": sha}
    (ctx.out_dir / "meta.json").write_text(json.dumps(meta, sort_keys=True), encoding="utf-8")
    rel = (ctx.final_dir / "text.txt").relative_to(ctx.work_dir).as_posix()
    return TextResult(item_id=ctx.item_id, words=len(words), sha256=sha, salt=salt, relpath=rel)


def plan_texts(cfg: TextConfig, pctx: PlanContext) -> list[WorkItem | PlannedFailure]:
    out: list[WorkItem | PlannedFailure] = []
    for f in sorted(cfg.folder.glob(cfg.pattern)):
        iid = f.stem
        if iid in cfg.rejected:
            out.append(PlannedFailure(iid, f"{f}: rejected while planning"))
            continue
        mode = ("bad" if iid in cfg.bad else "crash" if iid in cfg.crash else "die" if iid in cfg.die
                else "flaky" if iid in cfg.flaky else "ok")
        marker = (cfg.flaky_dir / f"{iid}.marker") if cfg.flaky_dir and mode == "flaky" else None
        out.append(WorkItem(item_id=iid, fn="stagefns:process_text",
                            params=TextParams(source=f, sleep_s=cfg.sleep_s, mode=mode, flaky_marker=marker),
                            input_files=(f,)))
    return out


def finalize_texts(cfg: TextConfig, pctx: PlanContext, results: dict[str, TextResult]) -> None:
    """Write ``<work>/reports/<step>_index.json``: succeeded ids with word counts, and failures."""
    path = pctx.work_dir / "reports" / f"{pctx.step}_index.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    doc = {"ok": {k: r.words for k, r in results.items()}, "failed": pctx.failed.get(pctx.step, {})}
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(doc, sort_keys=True), encoding="utf-8")
    os.replace(tmp, path)


TEXT_KIND = JobKind(name="texts", config=TextConfig, plan=plan_texts, finalize=finalize_texts,
                    description="normalise text files (test kind)")


# --- merge (depends on every text item) ------------------------------------------------------------


class MergeConfig(_Strict):
    source_step: str = "texts"


class MergeParams(_Strict):
    files: list[Path]


class MergeResult(_Strict):
    total_words: int


def merge_texts(params: MergeParams, ctx: ItemContext) -> MergeResult:
    parts = [p.read_text(encoding="utf-8") for p in params.files]
    (ctx.out_dir / "merged.txt").write_text("".join(parts), encoding="utf-8")
    return MergeResult(total_words=sum(len(p.split()) for p in parts))


def plan_merge(cfg: MergeConfig, pctx: PlanContext) -> list[WorkItem]:
    prev: dict[str, TextResult] = pctx.previous[cfg.source_step]
    files = [pctx.work_dir / r.relpath for r in prev.values()]
    return [WorkItem(item_id="all", fn="stagefns:merge_texts", params=MergeParams(files=files),
                     input_files=tuple(files), depends_on=tuple(f"{cfg.source_step}/{k}" for k in prev))]


MERGE_KIND = JobKind(name="merge", config=MergeConfig, plan=plan_merge, description="concatenate (test kind)")


# --- trivial (runner overhead) ---------------------------------------------------------------------


class TrivialConfig(_Strict):
    n: int = Field(ge=0)


class TrivialParams(_Strict):
    index: int


class TrivialResult(_Strict):
    value: int


def trivial(params: TrivialParams, ctx: ItemContext) -> TrivialResult:
    (ctx.out_dir / "v.txt").write_text(str(params.index * 2))
    return TrivialResult(value=params.index * 2)


def plan_trivial(cfg: TrivialConfig, pctx: PlanContext) -> list[WorkItem]:
    return [WorkItem(item_id=f"i{i:05d}", fn="stagefns:trivial", params=TrivialParams(index=i))
            for i in range(cfg.n)]


TRIVIAL_KIND = JobKind(name="trivial", config=TrivialConfig, plan=plan_trivial, description="no-op (benchmark)")

REGISTRY: dict[str, str] = {
    "texts": "stagefns:TEXT_KIND",
    "merge": "stagefns:MERGE_KIND",
    "trivial": "stagefns:TRIVIAL_KIND",
}


def echo_command(argv: list[str]) -> int:
    """An extra CLI subcommand (see stages/commands.py): prints its arguments, returns their count."""
    print("echo:", " ".join(argv))
    return len(argv)
