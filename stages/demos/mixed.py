"""The ``demos`` job's mixed-task mode: one engine per kitchen runs every task, round robin.

With ``mixed = true`` the demos job (:mod:`stages.demos.job`) plans one item per kitchen
(``mixed_w<k>``) instead of one per (task, kitchen). The item builds one
:class:`~stages.engine.BatchEngine` of ``batch_worlds`` copies of kitchen ``k`` and runs
``episodes_per_task`` episodes of every task of the job's list in it:

- episode ``e`` (0 .. T * E - 1, T tasks, E episodes per task) is task ``tasks[e mod T]`` with seed
  ``derive_seed(item seed, "episode", e)`` (the item seed derives from the job seed, the stage name
  and the item id), run in engine world ``e mod N`` (N = min(batch_worlds, T * E)): every world
  runs its episodes in order, the tasks interleaved, and the outcome of episode ``e`` depends only
  on the job seed, the stage name, the kitchen and ``e``;
- ``max_sim_seconds`` (optional) stops the engine after that much simulated time [s] (a
  deterministic bound); episodes still running then are *unfinished*: counted apart, not written,
  not attempts;
- one shard per engine world, ``<out>/<step>/mixed_w<k>/dataset_w<NNNN>`` (successful episodes;
  failed ones are counted by reason, not written), merged by the job's finalize;
- contacts: MuJoCo-Warp's overflow monitor (:mod:`stages.simulate.contacts`) is checked after the
  run (and every ``contact_check_every`` steps during it); an overflow fails the item with
  ``contact overflow: world W ...`` (what :func:`contact_overflows` counts), and a clean run
  reports its peak contacts and constraint rows against the capacities.

The per-task tallies of one item (:class:`MixedResult`) add up in the job's report exactly as the
per-(task, kitchen) items' do.
"""

from __future__ import annotations

import logging
import statistics
from collections import Counter
from pathlib import Path
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from pipeline.types import ItemContext, ItemError, derive_seed

log = logging.getLogger(__name__)

FN = "stages.demos.mixed:record_mixed"
OVERFLOW_PREFIX = "contact overflow: "


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


_Std = Annotated[float, Field(ge=0.0, le=2.0, allow_inf_nan=False)]


class ActionNoiseSpec(_Strict):
    """The demos step's DART noise (``[step.config.action_noise]``; see
    :mod:`stages.engine.action_noise`): the robot executes the expert's commands plus held random
    offsets while the frames record the clean commands. arm_std: per arm joint [rad]; base_std:
    base velocity (vx, vy [m/s], vtheta [rad/s]); hold_seconds: each draw held this long [s];
    mode_aware: base noise only while the base drives, arm noise only in manipulation;
    base_quiet_radius: no base noise within this distance [m] of a drive's stop."""

    arm_std: _Std = 0.02
    base_std: tuple[_Std, _Std, _Std] = (0.05, 0.05, 0.1)
    hold_seconds: float = Field(default=0.3, gt=0.0, le=60.0, allow_inf_nan=False)
    mode_aware: bool = True
    base_quiet_radius: float = Field(default=0.0, ge=0.0, le=10.0, allow_inf_nan=False)

    def engine(self):
        """The engine's :class:`~stages.engine.action_noise.ActionNoise`."""
        from stages.engine.action_noise import ActionNoise

        return ActionNoise(arm_std=self.arm_std, base_std=tuple(self.base_std),
                           hold_seconds=self.hold_seconds, mode_aware=self.mode_aware,
                           base_quiet_radius=self.base_quiet_radius)


class MixedParams(_Strict):
    """One kitchen's engine: kitchen index and seed, the tasks and episodes per task, an optional
    bound on simulated time [s] and episode time limit [s], image settings, engine settings, the
    catalog (generated.json, package root layers by asset id), the Panda root."""

    world: int
    world_seed: int
    tasks: tuple[str, ...]
    episodes_per_task: int
    max_sim_seconds: float | None = None
    max_seconds: float | None = None
    width: int
    height: int
    fps: int
    device: str
    record_images: bool
    record_depth: bool = True
    video_gop: int = 30
    batch_worlds: int
    program_procs: int = 0
    program_wait: float | None = None
    writer_procs: int = 0
    generated: str
    packages: dict[str, str]
    panda_root: str | None = None
    action_noise: ActionNoiseSpec | None = None


class Episode(_Strict):
    """One planned episode: index, task, seed, engine world; ended (False: unfinished when the
    engine stopped); success, failure reason, frames recorded, simulated time [s]."""

    index: int
    task: str
    seed: int
    world: int
    ended: bool
    success: bool = False
    reason: str = ""
    frames: int = 0
    sim_seconds: float = 0.0


class TaskTally(_Strict):
    """Per task of an item: attempts (ended episodes), successes, unfinished, failures by reason,
    frames written (successful episodes), frames of each successful episode."""

    attempts: int
    successes: int
    unfinished: int
    failures: dict[str, int]
    frames: int
    lengths: tuple[int, ...]


class MixedResult(_Strict):
    """dataset: the item's shard folder (final location; None when nothing was written); datasets:
    the shards with episodes; tasks: tallies by task; episodes: every planned episode; timings [s]
    per stage; build_seconds: kitchen authoring + engine build; sim_seconds: simulated time the
    engine ran [s]; contacts: see :func:`contact_summary`."""

    world: int
    scene_id: str
    worlds: int
    dataset: str | None
    datasets: tuple[str, ...]
    tasks: dict[str, TaskTally]
    episodes: tuple[Episode, ...]
    timings: dict[str, float]
    build_seconds: float
    sim_seconds: float
    contacts: dict


def plan_episodes(tasks: tuple[str, ...], per_task: int, item_seed: int) -> list[tuple[str, int]]:
    """(task, seed) of episode e = 0 .. T * per_task - 1: task ``tasks[e mod T]``, seed derived from
    the item seed and ``e`` (below 2**62, what the samplers take)."""
    n = len(tasks) * per_task
    return [(tasks[e % len(tasks)], derive_seed(item_seed, "episode", str(e)) % (2**62)) for e in range(n)]


def contact_summary(engine) -> dict:
    """Check every Sim of ``engine`` for dropped contacts (raises ``ItemError`` "contact overflow:
    world W ...") and return the peaks against the capacities: solver; peak_contacts_per_world,
    nconmax (per world); peak_constraint_rows_per_world, njmax (per world); peak_candidate_pairs,
    peak_contacts_all_worlds, naconmax (the shared buffer, per Sim); solver_iteration_cap_worlds,
    linesearch_iteration_cap_worlds (worlds whose solver stopped at an iteration limit: not an
    overflow). MuJoCo C (the CPU per-world
    layout) grows its own buffers: its arena warnings are checked, no peaks."""
    from stages.simulate.contacts import ContactOverflowError

    peaks: dict[str, int] = Counter()
    caps: dict[str, int] = {}
    solver = "mujoco"
    for b in engine.banks:
        try:
            b.sim.check_contacts()
        except ContactOverflowError as e:
            raise ItemError(f"{OVERFLOW_PREFIX}{e}") from None
        mon = b.sim.contact_monitor
        if mon is None or mon.cpu:
            continue
        solver = "mujoco_warp"
        p = mon.peaks()
        for k, v in (("peak_contacts_per_world", int(p["contacts"].max(initial=0))),
                     ("peak_constraint_rows_per_world", int(p["nefc"].max(initial=0))),
                     ("peak_candidate_pairs", p["ncollision"]), ("peak_contacts_all_worlds", p["nacon"])):
            peaks[k] = max(peaks[k], int(v))
        caps = {"nconmax": mon.naconmax // mon.nworld, "njmax": mon.njmax, "naconmax": mon.naconmax}
        for k, v in mon.iteration_caps().items():
            peaks[k] += v
    return {"overflows": 0, "solver": solver, **dict(peaks), **caps}


def contact_overflows(failed_items: dict[str, str]) -> dict[str, str]:
    """The failed items (id -> reason) that failed on dropped contacts."""
    return {k: v for k, v in failed_items.items() if OVERFLOW_PREFIX in v}


def record_mixed(params: MixedParams, ctx: ItemContext) -> MixedResult:
    """Stage function: author kitchen ``params.world``, run every task's episodes on one engine,
    write one shard per engine world (on ``params.device``: "cuda:N" keeps it on that GPU)."""
    from stages.engine import device_scope

    with device_scope(params.device):
        return _record_mixed(params, ctx)


def _record_mixed(params: MixedParams, ctx: ItemContext) -> MixedResult:
    import time
    from contextlib import ExitStack

    import numpy as np

    from stages.dataset import EpisodeInfo
    from stages.dataset.pool import open_shards
    from stages.demos.kitchen import AssetLibrary, write_kitchen
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed
    from stages.simulate.contacts import ContactOverflowError

    t0 = time.perf_counter()
    scene_id = f"kitchen_{params.world:03d}"
    lib = AssetLibrary.from_packages({k: Path(v) for k, v in params.packages.items()}, Path(params.generated))
    from stages.demos.multistage import needs_clock, needs_drink, needs_household

    world = write_kitchen(ctx.out_dir / "world", lib, scene_id=scene_id,
                          rng=np.random.default_rng(params.world_seed), household=needs_household(params.tasks),
                          drink=needs_drink(params.tasks), clock=needs_clock(params.tasks))
    plan = plan_episodes(params.tasks, params.episodes_per_task, ctx.seed)
    n = min(params.batch_worlds, len(plan))
    from stages.demos.multistage import MULTISTAGE

    config = EngineConfig(worlds=n, width=params.width, height=params.height, fps=params.fps,
                          subtasks=any(t in MULTISTAGE for t in params.tasks),
                          device=params.device, record_images=params.record_images,
                          record_depth=params.record_depth, video_gop=params.video_gop,
                          max_seconds=params.max_seconds,
                          program_procs=params.program_procs if n > 1 else 0,
                          program_wait=params.program_wait if n > 1 and params.program_procs else None,
                          action_noise=None if params.action_noise is None else params.action_noise.engine())
    engine = BatchEngine(world, panda_root=None if params.panda_root is None else Path(params.panda_root),
                         work_dir=ctx.out_dir / "world", config=config, seed=params.world_seed)
    build = time.perf_counter() - t0
    todo = {w: [e for e in range(len(plan)) if e % n == w] for w in range(n)}
    ended: dict[int, Episode] = {}
    live: dict[int, int] = {}  # world -> the episode it is recording
    written: Counter[int] = Counter()
    max_steps = None if params.max_sim_seconds is None else int(round(params.max_sim_seconds
                                                                       * engine.steps_per_second))
    with ExitStack() as stack:
        shards = stack.enter_context(open_shards(ctx.out_dir, [f"dataset_w{w:04d}" for w in range(n)],
                                                 config.dataset_spec(), params.writer_procs if n > 1 else 0))

        def begin(w: int, inst):
            live[w] = todo[w][0]
            # with multistage tasks in the mix every episode lists its stages (a basic task: one)
            subtasks = inst.subtasks or ((inst.instruction,) if config.subtasks else ())
            shards[w].begin_episode(EpisodeInfo(task=inst.instruction, task_kind=inst.task, scene_id=scene_id,
                                                seed=inst.seed, asset_ids=inst.asset_ids, subtasks=subtasks))
            return shards[w].add_frame

        def end(w: int, inst, res):
            e = todo[w].pop(0)
            del live[w]
            shards[w].end_episode(success=res.success, reason=res.reason)
            written[w] += res.success
            ended[e] = Episode(index=e, task=inst.task, seed=inst.seed, world=w, ended=True, success=res.success,
                               reason=res.reason, frames=res.frames, sim_seconds=round(res.sim_seconds, 3))

        queues = {w: [(*plan[e], None) for e in todo[w]] for w in range(n)}
        try:
            stats = engine.run(Listed(world, queues), begin=begin, end=end, max_steps=max_steps)
        except ContactOverflowError as e:
            raise ItemError(f"{OVERFLOW_PREFIX}{e}") from None
        t1 = time.perf_counter()
        for w in sorted(live):  # cut by max_sim_seconds: dropped
            shards[w].end_episode(success=False, reason="unfinished")
        contacts = contact_summary(engine)  # an overflow fails the item: its shards are dropped
    timings = stats.timings
    timings.writing += time.perf_counter() - t1
    episodes = tuple(ended.get(e) or Episode(index=e, task=t, seed=s, world=e % n, ended=False)
                     for e, (t, s) in enumerate(plan))
    datasets = tuple(str(ctx.final_dir / f"dataset_w{w:04d}") for w in range(n) if written[w])
    res = MixedResult(world=params.world, scene_id=scene_id, worlds=n,
                      dataset=str(ctx.final_dir) if datasets else None, datasets=datasets,
                      tasks=tally(episodes), episodes=episodes, timings=timings.to_json(),
                      build_seconds=round(build, 3), sim_seconds=round(engine.global_step / engine.steps_per_second, 3),
                      contacts=contacts)
    log.info("%s: %d worlds, %d/%d episodes succeeded, %d unfinished, %.0f s simulated", ctx.item_id, n,
             sum(e.success for e in episodes), len(episodes), sum(not e.ended for e in episodes), res.sim_seconds)
    return res


def tally(episodes) -> dict[str, TaskTally]:
    """Per task (in first-seen order): attempts, successes, unfinished, failures, frames."""
    out: dict[str, TaskTally] = {}
    for task in dict.fromkeys(e.task for e in episodes):
        eps = [e for e in episodes if e.task == task]
        done = [e for e in eps if e.ended]
        lengths = tuple(e.frames for e in done if e.success)
        out[task] = TaskTally(attempts=len(done), successes=len(lengths), unfinished=len(eps) - len(done),
                              failures=dict(sorted(Counter(e.reason for e in done if not e.success).items())),
                              frames=sum(lengths), lengths=lengths)
    return out


def median(values) -> float | None:
    """The median of ``values`` (None when empty)."""
    values = list(values)
    return float(statistics.median(values)) if values else None
