"""The ``demos`` job kind: scripted demonstrations of the basic tasks, one dataset shard per item.

Job file (after a ``default_catalog`` step and an ``ingest`` step of the same job)::

    [[step]]
    name = "demos"
    kind = "demos"
    [step.config]
    catalog_step = "catalog"    # the default_catalog step (its generated.json: surfaces, handles, joints)
    assets_step = "assets"      # the ingest step of that catalog (the USD packages, referenced)
    tasks = ["pick_place_bowl", "open_drawer"]   # default: every basic task
    worlds = 1                  # worlds (kitchen variants) per task; one item per (task, kitchen)
    episodes_per_shard = 2      # episodes attempted per item; failed ones are counted, not written
    batch_worlds = 1            # engine worlds per item (simulated together, one shard each)
    program_procs = 0           # worker processes for the experts of an item's engine (GPU)
    writer_procs = 0            # processes writing an item's shards (0: the engine's process)
    # mixed = true              # one item per kitchen: one engine runs every task (stages.demos.mixed)
    # episodes_per_task = 30    # with mixed: episodes of each task per kitchen
    # max_sim_seconds = 120.0   # with mixed: stop each engine after this much simulated time [s]
    width = 128
    height = 96
    # panda_root = "..."        # the Panda description's root (default: pip example-robot-data)
    # [step.config.action_noise]  # DART: execute the expert's commands plus noise, record them clean
    # arm_std = 0.02            # [rad] per arm joint
    # base_std = [0.05, 0.05, 0.1]   # base velocity vx, vy [m/s], vtheta [rad/s]
    # hold_seconds = 0.3        # each draw held this long [s]
    # base_quiet_radius = 0.6   # [m] no base noise this close to a drive's stop (default 0)
    # environment_state = true  # frames record the task objects' state (stages.engine.env_state)
    # environment_gripper = true  # ... ending with the gripper's opening [m]
    # environment_base_velocity = true  # ... holding the base's measured velocity (base frame)
    # environment_front = true  # ... holding the part front's direction (base frame; open/close tasks)

Items are ``<task>_w<k>``: each authors its world (a kitchen from the ingested catalog, see
:mod:`stages.demos.kitchen`: asset variants, poses and colours from the world's seed, shared by
every task with the same ``k``), builds the batched engine (:mod:`stages.engine`: ``batch_worlds``
copies of the kitchen in one simulation), runs ``episodes_per_shard`` episodes of the scripted
expert (seeds from the item's seed; episode ``e`` in engine world ``e mod batch_worlds``) and writes
one complete shard per engine world to ``<out>/<step>/<item>/dataset_w<k>`` through
:mod:`stages.dataset`. ``finalize`` merges the shards into
``<out>/datasets/<step>`` (LeRobot v3.0, loadable with ``LeRobotDataset``) and writes
``<out>/reports/<step>.json``: per task attempts, successes, success rate and failure reasons,
plus recorded frames and the wall time per stage.

With ``mixed = true`` the items are ``mixed_w<k>`` instead: one engine per kitchen runs
``episodes_per_task`` episodes of every task, round robin (:mod:`stages.demos.mixed`); the shards
and the report are the same. The report also counts contact overflows (items failed on dropped
contacts, see :mod:`stages.simulate.contacts`) and, for MuJoCo-Warp, the peak contacts and
constraint rows per world against their capacities.
"""

from __future__ import annotations

import json
import logging
import shutil
from collections import Counter
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from pipeline.types import ItemContext, ItemError, JobKind, PlanContext, PlannedFailure, WorkItem, derive_seed
from stages.demos import mixed as _mixed
from stages.demos.tasks import BASIC_TASKS, TASKS


log = logging.getLogger(__name__)

FN = "stages.demos.job:record_shard"


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class DemosConfig(_Strict):
    """catalog_step: the default_catalog step (generated.json); assets_step: the ingest step of it
    (packages); tasks: task names (default all); worlds: worlds per task; episodes_per_shard:
    episodes per item; width, height: camera image size [px]; fps; device: "cpu" or "cuda";
    record_images: False writes state/action only (no camera is rendered: a fast success-rate
    run); record_depth: with record_images, each camera's lossless depth too (False: RGB only, a
    fraction of the bytes: no policy of stages/policy reads depth); video_gop: keyframe interval
    of the RGB videos [frames] (30: small files; 2: lerobot's, random access while training decodes
    at most one extra frame per sample instead of about 15); batch_worlds: worlds of the batched engine per item (one model of that many worlds on
    CUDA, one MuJoCo C model each on CPU); program_procs: worker processes for the experts'
    planning and IK of an item's engine (0: threads; needs the batched layout, i.e. CUDA);
    program_wait: with program_procs, seconds the engine waits for planning experts before it
    holds their worlds and steps the others on (None: wait for all); writer_procs: processes that
    write an item's shards (:mod:`stages.dataset.pool`; 0: the engine's process writes them; the
    files are the same); panda_root: the Panda
    description's root (None: the pip package example-robot-data); max_seconds: episode time limit
    [s] for every task (None: each task's own).

    mixed: one item per kitchen (``worlds`` kitchens), whose engine of ``batch_worlds`` worlds runs
    ``episodes_per_task`` episodes of every task round robin (:mod:`stages.demos.mixed`) instead of
    one item per (task, kitchen) running ``episodes_per_shard``; max_sim_seconds: with mixed, stop
    each engine after this much simulated time [s] (episodes still running are counted as
    unfinished; None: run every episode to its end).

    devices: on a host of several GPUs, the items' engines spread round robin over these CUDA
    devices ("cuda:0", "cuda:1", ...; with ``workers`` items at once), each engine alone on its
    GPU; empty: every item on ``device``.

    merge: merge the shards into ``datasets/<step>`` (False: a success-rate run keeps the items'
    shards only; the report says ``dataset: null``; merging a thousand one-episode shards takes
    minutes).

    action_noise: DART noise while recording (``[step.config.action_noise]``: arm_std [rad],
    base_std [m/s, m/s, rad/s], hold_seconds [s], mode_aware; :class:`~stages.demos.mixed.ActionNoiseSpec`):
    the robot executes the expert's commands plus held random offsets, the frames record the clean
    commands and the perturbed state (None: no noise).

    environment_state: every frame records ``observation.environment_state``, the task objects'
    key points in the robot base frame (:mod:`stages.engine.env_state`; per-task items only, every
    task of the step with the same layout; False: the feature is absent, the files as before).
    environment_gripper: that state ends with ``gripper_opening``, the fingers' opening [m] (needs
    ``environment_state``). environment_base_velocity: it holds the base's measured velocity in its
    own frame (``base_vx``, ``base_vy`` [m/s], ``base_vtheta`` [rad/s]; needs ``environment_state``).
    environment_front: it holds the articulated part front's planar direction in the base frame
    (``front_x``, ``front_y``; open/close tasks; needs ``environment_state``)."""

    catalog_step: str = "catalog"
    assets_step: str = "assets"
    tasks: tuple[str, ...] = BASIC_TASKS
    worlds: int = Field(default=1, ge=1, le=10000)
    episodes_per_shard: int = Field(default=2, ge=1, le=1000)
    width: int = Field(default=128, ge=16, le=1920)
    height: int = Field(default=96, ge=16, le=1080)
    fps: int = Field(default=30, ge=1, le=120)
    device: str = "cpu"
    record_images: bool = True
    record_depth: bool = True
    video_gop: int = Field(default=30, ge=1, le=300)
    batch_worlds: int = Field(default=1, ge=1, le=4096)
    program_procs: int = Field(default=0, ge=0, le=256)
    program_wait: float | None = Field(default=None, ge=0.0, le=60.0)
    writer_procs: int = Field(default=0, ge=0, le=64)
    panda_root: Path | None = None
    max_seconds: float | None = Field(default=None, gt=0.0, le=600.0)
    mixed: bool = False
    episodes_per_task: int = Field(default=1, ge=1, le=10000)
    max_sim_seconds: float | None = Field(default=None, gt=0.0, le=86400.0)
    devices: tuple[str, ...] = ()
    merge: bool = True
    action_noise: _mixed.ActionNoiseSpec | None = None
    environment_state: bool = False
    environment_gripper: bool = False
    environment_base_velocity: bool = False
    environment_front: bool = False

    def item_device(self, index: int) -> str:
        """The device of item ``index``: ``devices`` round robin, else ``device``."""
        return self.devices[index % len(self.devices)] if self.devices else self.device

    @field_validator("devices")
    @classmethod
    def _devices(cls, v: tuple[str, ...]) -> tuple[str, ...]:
        import re

        bad = [d for d in v if not re.fullmatch(r"cuda:\d+", d)]
        if bad or len(set(v)) != len(v):
            raise ValueError(f"devices must be distinct 'cuda:N' names, got {list(v)}")
        return v

    @field_validator("device")
    @classmethod
    def _device(cls, v: str) -> str:
        import re

        if not re.fullmatch(r"cpu|cuda(:\d+)?", v):
            raise ValueError(f"device must be 'cpu' or 'cuda[:n]', got {v!r}")
        return v

    @model_validator(mode="after")
    def _mode(self) -> DemosConfig:
        given = self.model_fields_set
        if self.mixed and "episodes_per_shard" in given:
            raise ValueError("episodes_per_shard is for per-(task, kitchen) items; with mixed = true "
                             "set episodes_per_task")
        for k in ("episodes_per_task", "max_sim_seconds"):
            if not self.mixed and k in given:
                raise ValueError(f"{k} needs mixed = true (per-(task, kitchen) items use episodes_per_shard)")
        if self.devices and not self.device.startswith("cuda"):
            raise ValueError("devices (items spread over several GPUs) needs device = 'cuda'")
        if self.program_procs and not self.device.startswith("cuda"):
            raise ValueError("program_procs needs device = 'cuda' (the batched engine layout); on CPU the "
                             "experts run as threads (program_procs = 0)")
        if self.program_wait is not None and not self.program_procs:
            raise ValueError("program_wait needs program_procs > 0")
        if self.environment_state:
            from stages.engine.env_state import common_layout

            if self.mixed:
                raise ValueError("environment_state needs per-task items (mixed = false): a dataset holds one layout")
            # ValueError names a task without one (or without a part, for the front), or the differing layouts
            common_layout(self.tasks, front=self.environment_front)
        elif self.environment_gripper:
            raise ValueError("environment_gripper needs environment_state = true")
        elif self.environment_base_velocity:
            raise ValueError("environment_base_velocity needs environment_state = true")
        elif self.environment_front:
            raise ValueError("environment_front needs environment_state = true")
        return self

    @field_validator("tasks")
    @classmethod
    def _known(cls, v: tuple[str, ...]) -> tuple[str, ...]:
        from stages.demos.multistage import MULTISTAGE, is_task

        bad = [t for t in v if not is_task(t)]
        if bad:
            raise ValueError(f"unknown task(s) {bad}; known: {sorted(TASKS)} and multistage {sorted(MULTISTAGE)}")
        if not v or len(set(v)) != len(v):
            raise ValueError(f"tasks must be a non-empty list without repeats, got {list(v)}")
        return v


class ShardParams(_Strict):
    """One shard: task, world index and seed, episodes, image settings, the catalog (generated.json
    and the kitchen categories' package root layers by asset id), the Panda root."""

    task: str
    world: int
    world_seed: int
    episodes: int
    width: int
    height: int
    fps: int
    device: str
    generated: str
    packages: dict[str, str]
    panda_root: str | None = None
    record_images: bool = True
    record_depth: bool = True
    video_gop: int = 30
    batch_worlds: int = 1
    program_procs: int = 0
    program_wait: float | None = None
    writer_procs: int = 0
    max_seconds: float | None = None
    action_noise: _mixed.ActionNoiseSpec | None = None
    environment_state: bool = False
    environment_gripper: bool = False
    environment_base_velocity: bool = False
    environment_front: bool = False


class EpisodeRecord(_Strict):
    seed: int
    success: bool
    reason: str
    frames: int
    sim_seconds: float


class ShardResult(_Strict):
    """dataset: the folder holding the item's shards (final location; None when no episode
    succeeded); datasets: the shards (one per engine world that wrote an episode); counts;
    failures by reason; timings [s] per stage; build_seconds: world authoring + simulation build."""

    task: str
    world: int
    scene_id: str
    dataset: str | None
    attempts: int
    episodes: int
    frames: int
    failures: dict[str, int]
    records: tuple[EpisodeRecord, ...]
    timings: dict[str, float]
    build_seconds: float
    datasets: tuple[str, ...] = ()
    contacts: dict = Field(default_factory=dict)


def _catalog_inputs(config: DemosConfig, ctx: PlanContext) -> tuple[Path, dict[str, str]]:
    """generated.json of the catalog step and the kitchen packages (asset id -> root layer) of the
    assets step. Raises ItemError naming the job file and the step."""
    import json

    from stages.demos.kitchen import KITCHEN_CATEGORIES

    cat = ctx.previous.get(config.catalog_step)
    if not cat:
        raise ItemError(f"{ctx.job_file}: demos step: catalog_step {config.catalog_step!r} has no results "
                        f"(is it an earlier default_catalog step?)")
    cat_dir = getattr(next(iter(cat.values())), "catalog_dir", None)
    if cat_dir is None:
        raise ItemError(f"{ctx.job_file}: demos step: step {config.catalog_step!r} does not produce a "
                        "catalog_dir")
    generated = Path(cat_dir) / "generated.json"
    try:
        info = json.loads(generated.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise ItemError(f"{generated}: cannot read the default catalog's records ({e})") from None
    assets = ctx.previous.get(config.assets_step)
    if not assets:
        raise ItemError(f"{ctx.job_file}: demos step: assets_step {config.assets_step!r} has no results "
                        f"(is it an earlier ingest step?)")
    packages = {}
    for r in assets.values():
        aid = getattr(r, "asset_id", None)
        if aid in info and info[aid].get("category") in KITCHEN_CATEGORIES:
            packages[aid] = str((ctx.work_dir / r.usd_path).resolve())
    if not packages:
        raise ItemError(f"{ctx.job_file}: demos step: no kitchen package ({', '.join(KITCHEN_CATEGORIES)}) "
                        f"among the {len(assets)} results of step {config.assets_step!r}")
    return generated, packages


def plan_demos(config: DemosConfig, ctx: PlanContext) -> list[WorkItem | PlannedFailure]:
    """One item per (task, world), or with ``mixed`` one per world; the Panda URDF, generated.json
    and the packages are its inputs."""
    from stages.simulate.robot import PANDA_URDF_REL, find_panda_description

    if config.mixed:
        ids = [f"mixed_w{w:03d}" for w in range(config.worlds)]
    else:
        ids = [f"{t}_w{w:03d}" for t in config.tasks for w in range(config.worlds)]
    try:
        urdf = find_panda_description(config.panda_root) / PANDA_URDF_REL
        generated, packages = _catalog_inputs(config, ctx)
    except ItemError as e:
        return [PlannedFailure(i, f"{ctx.job_file}: {e}" if str(ctx.job_file) not in str(e) else str(e))
                for i in ids]
    items: list[WorkItem | PlannedFailure] = []
    inputs = (urdf, generated, *sorted(Path(p) for p in packages.values()))
    panda_root = None if config.panda_root is None else str(config.panda_root)
    if config.mixed:
        for w, item_id in enumerate(ids):
            mp = _mixed.MixedParams(
                world=w, world_seed=derive_seed(ctx.seed, "demos-world", str(w)), tasks=config.tasks,
                episodes_per_task=config.episodes_per_task, max_sim_seconds=config.max_sim_seconds,
                max_seconds=config.max_seconds, width=config.width, height=config.height, fps=config.fps,
                device=config.item_device(w), record_images=config.record_images,
                record_depth=config.record_depth, video_gop=config.video_gop, batch_worlds=config.batch_worlds, program_procs=config.program_procs, program_wait=config.program_wait,
                writer_procs=config.writer_procs, generated=str(generated), packages=packages,
                panda_root=panda_root, action_noise=config.action_noise)
            items.append(WorkItem(item_id=item_id, fn=_mixed.FN, params=mp, input_files=inputs))
        return items
    for t in config.tasks:
        for w in range(config.worlds):
            params = ShardParams(task=t, world=w, world_seed=derive_seed(ctx.seed, "demos-world", str(w)),
                                 episodes=config.episodes_per_shard, width=config.width, height=config.height,
                                 fps=config.fps, device=config.item_device(w),
                                 record_images=config.record_images, record_depth=config.record_depth,
                                 video_gop=config.video_gop,
                                 batch_worlds=config.batch_worlds, program_procs=config.program_procs,
                                 program_wait=config.program_wait, writer_procs=config.writer_procs,
                                 max_seconds=config.max_seconds, action_noise=config.action_noise,
                                 environment_state=config.environment_state,
                                 environment_gripper=config.environment_gripper,
                                 environment_base_velocity=config.environment_base_velocity,
                                 environment_front=config.environment_front,
                                 generated=str(generated), packages=packages, panda_root=panda_root)
            items.append(WorkItem(item_id=f"{t}_w{w:03d}", fn=FN, params=params, input_files=inputs))
    return items


def record_shard(params: ShardParams, ctx: ItemContext) -> ShardResult:
    """Stage function: author the world, run the episodes on the batched engine, write the shards
    (on ``params.device``: "cuda:N" keeps it on that GPU)."""
    from stages.engine import device_scope

    with device_scope(params.device):
        return _record_shard(params, ctx)


def _record_shard(params: ShardParams, ctx: ItemContext) -> ShardResult:
    import time
    from contextlib import ExitStack

    import numpy as np

    from stages.dataset import EpisodeInfo
    from stages.dataset.pool import open_shards
    from stages.demos.kitchen import AssetLibrary, write_kitchen
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.env_state import state_names
    from stages.engine.programs import Listed
    from stages.simulate.contacts import ContactOverflowError

    t0 = time.perf_counter()
    scene_id = f"kitchen_{params.world:03d}"
    lib = AssetLibrary.from_packages({k: Path(v) for k, v in params.packages.items()}, Path(params.generated))
    from stages.demos.multistage import needs_clock, needs_drink, needs_household

    world = write_kitchen(ctx.out_dir / "world", lib, scene_id=scene_id,
                          rng=np.random.default_rng(params.world_seed), household=needs_household((params.task,)),
                          drink=needs_drink((params.task,)), clock=needs_clock((params.task,)))
    n = min(params.batch_worlds, params.episodes)
    from stages.demos.multistage import MULTISTAGE

    config = EngineConfig(worlds=n, width=params.width, height=params.height, fps=params.fps,
                          subtasks=params.task in MULTISTAGE,
                          device=params.device, record_images=params.record_images,
                          record_depth=params.record_depth, video_gop=params.video_gop,
                          max_seconds=params.max_seconds,
                          program_procs=params.program_procs if n > 1 else 0,
                          program_wait=params.program_wait if n > 1 and params.program_procs else None,
                          action_noise=None if params.action_noise is None else params.action_noise.engine(),
                          environment_state=(state_names(params.task, params.environment_gripper,
                                                         params.environment_base_velocity,
                                                         params.environment_front)
                                             if params.environment_state else ()))
    engine = BatchEngine(world, panda_root=None if params.panda_root is None else Path(params.panda_root),
                         work_dir=ctx.out_dir / "world", config=config, seed=params.world_seed)
    build = time.perf_counter() - t0
    records: dict[int, EpisodeRecord] = {}
    failures: Counter[str] = Counter()
    todo = {w: [k for k in range(params.episodes) if k % n == w] for w in range(n)}
    seeds = {k: derive_seed(ctx.seed, "episode", str(k)) % (2**62) for k in range(params.episodes)}
    written: Counter[int] = Counter()
    with ExitStack() as stack:
        shards = stack.enter_context(open_shards(ctx.out_dir, [f"dataset_w{w:03d}" for w in range(n)],
                                                 config.dataset_spec(), params.writer_procs if n > 1 else 0))

        next_instance = Listed(world, {w: [(params.task, seeds[k], None) for k in todo[w]] for w in range(n)})

        def begin(w: int, inst):
            shards[w].begin_episode(EpisodeInfo(task=inst.instruction, task_kind=params.task, scene_id=scene_id,
                                                seed=inst.seed, asset_ids=inst.asset_ids, subtasks=inst.subtasks))
            return shards[w].add_frame

        def end(w: int, inst, res):
            k = todo[w].pop(0)
            shards[w].end_episode(success=res.success, reason=res.reason)
            written[w] += res.success
            if not res.success:
                failures[res.reason] += 1
            records[k] = EpisodeRecord(seed=inst.seed, success=res.success, reason=res.reason, frames=res.frames,
                                       sim_seconds=round(res.sim_seconds, 3))

        try:
            stats = engine.run(next_instance, begin=begin, end=end)
        except ContactOverflowError as e:
            raise ItemError(f"{_mixed.OVERFLOW_PREFIX}{e}") from None
        t1 = time.perf_counter()
        contacts = _mixed.contact_summary(engine)  # an overflow fails the item: its shards are dropped
    total = stats.timings
    total.writing += time.perf_counter() - t1
    recs = tuple(records[k] for k in sorted(records))
    datasets = tuple(str(ctx.final_dir / f"dataset_w{w:03d}") for w in range(n) if written[w])
    return ShardResult(task=params.task, world=params.world, scene_id=scene_id,
                       dataset=str(ctx.final_dir) if datasets else None, datasets=datasets,
                       attempts=len(recs), episodes=sum(r.success for r in recs),
                       frames=sum(r.frames for r in recs if r.success), failures=dict(failures),
                       records=recs, timings=total.to_json(), build_seconds=round(build, 3), contacts=contacts)


def _tallies(r: ShardResult | _mixed.MixedResult) -> dict[str, _mixed.TaskTally]:
    """Per-task tallies of one item's result (either mode)."""
    if isinstance(r, _mixed.MixedResult):
        return r.tasks
    lengths = tuple(e.frames for e in r.records if e.success)
    return {r.task: _mixed.TaskTally(attempts=r.attempts, successes=r.episodes, unfinished=0,
                                     failures=r.failures, frames=r.frames, lengths=lengths)}


def success_report(results: list[ShardResult | _mixed.MixedResult]) -> dict[str, Any]:
    """Per task: attempts, successes, success_rate (of attempts), failures by reason, unfinished
    episodes (mixed mode, cut by max_sim_seconds), success_rate_of_planned (unfinished counted as
    failures), frames written and the median length of successful episodes [frames]; totals,
    min_success_rate (the lowest task's success_rate_of_planned), timings [s], and the contacts'
    peaks against their capacities (MuJoCo-Warp)."""
    tasks: dict[str, dict[str, Any]] = {}
    lengths: dict[str, list[int]] = {}
    stage_s: Counter[str] = Counter()
    peaks: Counter[str] = Counter()
    caps: dict[str, int] = {}
    for r in results:
        for name, tl in _tallies(r).items():
            t = tasks.setdefault(name, {"attempts": 0, "successes": 0, "unfinished": 0, "failures": Counter(),
                                        "frames": 0})
            t["attempts"] += tl.attempts
            t["successes"] += tl.successes
            t["unfinished"] += tl.unfinished
            t["failures"].update(tl.failures)
            t["frames"] += tl.frames
            lengths.setdefault(name, []).extend(tl.lengths)
        stage_s.update({k: v for k, v in r.timings.items() if k != "frames"})
        stage_s["build"] += r.build_seconds
        for k, v in r.contacts.items():
            if k.startswith("peak_"):
                peaks[k] = max(peaks[k], int(v))
            elif k.endswith("_cap_worlds"):
                peaks[k] += int(v)
            elif k in ("nconmax", "njmax", "naconmax"):
                caps[k] = min(caps.get(k, int(v)), int(v))
    for name, t in tasks.items():
        t["success_rate"] = round(t["successes"] / max(1, t["attempts"]), 4)
        t["success_rate_of_planned"] = round(t["successes"] / max(1, t["attempts"] + t["unfinished"]), 4)
        t["failures"] = dict(sorted(t["failures"].items()))
        t["median_frames"] = _mixed.median(lengths[name])
    frames = int(sum(r.timings.get("frames", 0) for r in results))
    busy = sum(v for k, v in stage_s.items() if k != "build")
    return {"tasks": dict(sorted(tasks.items())),
            "attempts": sum(t["attempts"] for t in tasks.values()),
            "successes": sum(t["successes"] for t in tasks.values()),
            "unfinished": sum(t["unfinished"] for t in tasks.values()),
            "min_success_rate": min((t["success_rate_of_planned"] for t in tasks.values()), default=None),
            "frames_recorded": frames,
            "seconds": {k: round(v, 3) for k, v in sorted(stage_s.items())},
            "frames_per_second": round(frames / busy, 3) if busy else None,
            "contacts": {"overflows": 0, **dict(sorted(peaks.items())), **caps}}


def finalize_demos(config: DemosConfig, ctx: PlanContext, results: dict[str, Any]) -> None:
    """Merge the shards into ``<work>/datasets/<step>`` and write ``<work>/reports/<step>.json``."""
    from stages.dataset import merge_datasets
    from stages.dataset.writer import write_json_atomic

    kind = _mixed.MixedResult if config.mixed else ShardResult
    res = [r if isinstance(r, kind) else kind.model_validate(r) for r in results.values()]
    step = ctx.step or "demos"
    report = success_report(res)
    report["mode"] = "mixed" if config.mixed else "per_task"
    failed_items = ctx.failed.get(step, {})
    report["failed_items"] = dict(failed_items)
    overflowed = _mixed.contact_overflows(failed_items)
    report["contacts"]["overflows"] = len(overflowed)
    report["contacts"]["overflowed_items"] = overflowed
    roots = [Path(d) for r in res for d in (r.datasets or (r.dataset,)) if d]  # shards with episodes
    out = ctx.work_dir / "datasets" / step
    report["dataset"] = None
    if roots and config.merge:
        if out.exists():
            shutil.rmtree(out)  # the previous run's merge; the shards are the source of truth
        merged = merge_datasets(roots, out, repo_id=f"agentworld/{step}")
        report["dataset"] = {"root": str(merged.root), "episodes": merged.episodes, "frames": merged.frames}
    path = ctx.work_dir / "reports" / f"{step}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(path, report)
    log.info("demos: %d/%d episodes succeeded; report %s\n%s", report["successes"], report["attempts"], path,
             json.dumps({k: v["success_rate"] for k, v in report["tasks"].items()}))


DEMOS_JOB = JobKind(name="demos", config=DemosConfig, plan=plan_demos, finalize=finalize_demos,
                    description="scripted demonstrations of the basic tasks: LeRobot shards, merged, "
                                "success report")
