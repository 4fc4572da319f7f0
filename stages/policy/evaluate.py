"""Closed-loop evaluation of a lerobot policy in task kitchens on the batched engine (issue 17).

:func:`evaluate` loads a checkpoint (:func:`stages.policy.runner.load_policy`), builds each
held-out kitchen (the default catalog's kitchen from a world seed, scene id ``kitchen_ws<seed>``)
and runs every (task, episode seed) there on :class:`~stages.engine.BatchEngine` with ``worlds``
worlds. The policy replaces the scripted expert as each world's episode driver (``act``, as
teleoperation does): once per frame (1 / fps [s]) the world's program asks for an action; the first
world to ask at a frame step gets actions for every world acting at that step from one batched
policy call (:class:`~stages.policy.runner.BatchedRunner`: per-world chunking and ACT's temporal
ensembling), applies its own and steps to the next frame.

What the policy sees is frame ``k`` as the recorder writes it: the state read at the frame step and
the images rendered at that step (:meth:`~stages.engine.capture.FrameCapture.images_now` waits for
that render, which the engine launched before the programs ran; the recorded frames get the same
images one step later), and, for a policy trained with ``observation.environment_state``, the task
objects' state as the recorder computes it (:mod:`stages.engine.env_state`, from the same state
read; the evaluation engine then records it too). Actions are applied as the dataset's action
vector reads: arm joint targets [rad], base velocity (vx, vy [m/s], vtheta [rad/s]) in the base frame, gripper command in
[0, 1] (clipped); the end-effector target and mode entries are not commands, unless ``arm_command``
is "ee": the arm then follows the end-effector target through CLIK (:func:`ee_arm_targets`) and the
joint targets are not commands. A policy trained on a state view (:mod:`stages.dataset.view`) is
given the entries of the state its checkpoint names (:func:`state_selection`).

An episode ends when the task's success predicate holds (checked every ``check_seconds``) or at the
time limit (the task's, or ``max_seconds``); its result is the predicate's (success, or the failure
reason). Outputs in ``out``: ``eval.json`` (per task and family: episodes, successes, rate, failure
reasons; every episode; the held-out check; timings) and ``videos/<task>/<scene>_seed<seed>.mp4``
(the policy's cameras side by side, for the first ``videos`` episodes of each task; for a policy of no
camera, which takes the state and the environment state, the third-person camera, rendered only when
``videos`` > 0: with 0 such an evaluation renders nothing).

Held out: the checkpoint's training dataset (its ``train_config.json``) lists its episodes' scene
ids, tasks and seeds (``meta/episodes``); an evaluation episode whose kitchen or (task, seed) is
among them is refused unless ``allow_seen``.
"""

from __future__ import annotations

import json
import logging
import math
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)


@dataclass(frozen=True, kw_only=True)
class EvalConfig:
    """checkpoint: a lerobot ``pretrained_model`` folder; tasks: basic task names; scenes: kitchen
    world seeds; seeds: episode seeds (each task runs each seed in each kitchen); worlds: engine
    worlds run together; device: "cpu" or "cuda[:n]"; fps: frames per second (the dataset's);
    max_seconds: episode time limit [s] (None: the task's); check_seconds: how often the success
    predicate is checked [s]; videos: rollout videos per task; training_dataset: the dataset the
    policy was trained on (None: from the checkpoint's train_config.json); allow_seen: run episodes
    whose kitchen or (task, seed) the training dataset holds; action_steps: actions run from each
    predicted chunk (None: the checkpoint's ``n_action_steps``; for ACT a value turns temporal
    ensembling off); ensemble_coeff: ACT's temporal ensembling coefficient (None: the checkpoint's;
    it needs one action per chunk); arm_command: "joints" (the action's arm joint targets) or "ee"
    (its end-effector target, through CLIK: :func:`ee_arm_targets`). The last three are inference
    settings: the weights are the same."""

    checkpoint: Path
    tasks: tuple[str, ...]
    scenes: tuple[int, ...] = (101,)
    seeds: tuple[int, ...] = (1_000_000,)
    worlds: int = 4
    device: str = "cpu"
    fps: int = 30
    max_seconds: float | None = None
    check_seconds: float = 0.5
    videos: int = 2
    training_dataset: Path | None = None
    allow_seen: bool = False
    action_steps: int | None = None
    ensemble_coeff: float | None = None
    arm_command: str = "joints"

    def __post_init__(self) -> None:
        from stages.demos.tasks import TASKS

        problems = []
        bad = [t for t in self.tasks if t not in TASKS]
        if bad or not self.tasks:
            problems.append(f"unknown tasks {bad}; known {sorted(TASKS)}" if bad else "no task given")
        if not self.scenes or not self.seeds:
            problems.append("scenes and seeds must not be empty")
        if self.worlds < 1 or self.videos < 0 or self.fps < 1:
            problems.append("worlds and fps must be >= 1 and videos >= 0")
        if self.max_seconds is not None and not (math.isfinite(self.max_seconds) and self.max_seconds > 0):
            problems.append(f"max_seconds must be a positive number, got {self.max_seconds}")
        if self.arm_command not in ("joints", "ee"):
            problems.append(f"arm_command must be 'joints' or 'ee', got {self.arm_command!r}")
        if self.action_steps is not None and self.action_steps < 1:
            problems.append(f"action_steps must be >= 1, got {self.action_steps}")
        if self.ensemble_coeff is not None and not math.isfinite(self.ensemble_coeff):
            problems.append(f"ensemble_coeff must be a finite number, got {self.ensemble_coeff}")
        if self.ensemble_coeff is not None and self.action_steps not in (None, 1):
            problems.append("temporal ensembling runs one action per chunk: action_steps must be 1 with ensemble_coeff")
        if problems:
            raise ValueError("eval: " + "; ".join(problems))


def scene_id(world_seed: int) -> str:
    """The scene id of the default-catalog kitchen of ``world_seed`` (evaluation and the tests'
    training data use it, so that the held-out check can compare kitchens)."""
    return f"kitchen_ws{int(world_seed)}"


def build_kitchen(work_dir: Path, world_seed: int):
    """The default catalog's kitchen of ``world_seed`` (:func:`stages.teleop.world.teleop_kitchen`)."""
    from stages.teleop.world import teleop_kitchen

    return teleop_kitchen(Path(work_dir), int(world_seed), scene_id=scene_id(world_seed))


def training_episodes(cfg: EvalConfig) -> tuple[Path | None, list[dict]]:
    """The training dataset and its episodes' columns (scene_id, seed, task_kind, ...)."""
    from stages.dataset import read_episode_columns

    root = cfg.training_dataset
    if root is None:
        tc = Path(cfg.checkpoint) / "train_config.json"
        if tc.is_file():
            root = (json.loads(tc.read_text()).get("dataset") or {}).get("root")
    if root is None or not (Path(root) / "meta" / "episodes").is_dir():
        return (None if root is None else Path(root)), []
    return Path(root), read_episode_columns(Path(root))


def held_out_check(cfg: EvalConfig) -> dict:
    """Which evaluation kitchens and (task, seed) pairs the training data holds; raises
    ``ValueError`` (one line) when any does and ``allow_seen`` is off."""
    root, rows = training_episodes(cfg)
    train_scenes = sorted({str(r.get("scene_id")) for r in rows})
    train_pairs = {(str(r.get("task_kind")), int(r.get("seed", -1))) for r in rows}
    seen_scenes = sorted({scene_id(s) for s in cfg.scenes} & set(train_scenes))
    seen_pairs = sorted({(t, s) for t in cfg.tasks for s in cfg.seeds} & train_pairs)
    out = {"training_dataset": None if root is None else str(root), "training_episodes": len(rows),
           "training_scenes": train_scenes, "seen_scenes": seen_scenes,
           "seen_task_seeds": [list(p) for p in seen_pairs], "checked": root is not None and bool(rows)}
    if (seen_scenes or seen_pairs) and not cfg.allow_seen:
        raise ValueError(f"eval: not held out: the training dataset {root} has kitchens {seen_scenes} and "
                         f"(task, seed) {seen_pairs[:5]}{' ...' if len(seen_pairs) > 5 else ''} (--allow-seen runs them)")
    return out


@dataclass
class EpisodeRecord:
    """One evaluated episode: task, kitchen scene id, seed, engine world, success, reason (the
    predicate's, "" on success), frames, simulated seconds, video path ("" if none)."""

    task: str
    scene: str
    seed: int
    world: int
    success: bool
    reason: str
    frames: int
    sim_seconds: float
    video: str = ""


@dataclass(eq=False)
class _Episode:
    inst: object
    limit: float
    video: object = None
    frames: int = 0
    env: object = None  # its EnvKeys (stages.engine.env_state), for a policy with an environment state input


class Evaluator:
    """Runs one kitchen's evaluation episodes on an engine (see the module docstring).

    ``observers``: functions ``f(world, frame, observation)`` called with what the policy was given
    (tests compare it with the recorded frames); ``frame_listeners``: ``f(world, frame)`` with each
    recorded :class:`~stages.dataset.Frame`; ``episode_listeners``: ``f(record)`` with each
    finished episode's :class:`EpisodeRecord` (progress); ``action_listeners``: ``f(world, frame,
    action)`` with each action (the dataset's action vector, as the policy returned it) before it is applied."""

    def __init__(self, engine, runner, cfg: EvalConfig, world, out: Path, video_quota: Counter) -> None:
        self.engine, self.runner, self.cfg, self.world, self.out = engine, runner, cfg, world, Path(out)
        self.video_quota = video_quota
        self.records: list[EpisodeRecord] = []
        self.observers: list = []
        self.frame_listeners: list = []
        self.episode_listeners: list = []
        self.action_listeners: list = []
        self._active: set[int] = set()
        self._episodes: dict[int, _Episode] = {}
        self._cache: dict[int, np.ndarray] = {}
        self._cache_step = -1
        self._taken: set[int] = set()  # worlds that took their action at this step
        self._queues: dict[int, list] = {}
        self._start: dict[int, int] = {}  # each acting world's episode start [global step]
        self._state_cols = state_selection(engine.config.dataset_spec().state_names(), runner.loaded, cfg.checkpoint)

    # -- the engine's callbacks ----------------------------------------------------------------
    def run(self, episodes: list[tuple[str, int]]) -> list[EpisodeRecord]:
        n = self.engine.config.worlds
        self._queues = {w: [e for k, e in enumerate(episodes) if k % n == w] for w in range(n)}
        self.engine.run(self._next_instance, begin=self._begin, end=self._end, act=self._act)
        return self.records

    def _next_instance(self, w: int):
        from pipeline.types import ItemError
        from stages.demos.sampling import sample_instance
        from stages.demos.tasks import task

        while self._queues.get(w):
            name, seed = self._queues[w].pop(0)
            try:
                inst = sample_instance(name, self.world, seed)
            except ItemError as e:
                self._record(EpisodeRecord(task=name, scene=self.world.scene_id, seed=seed, world=w,
                                           success=False, reason=f"no instance: {e}", frames=0, sim_seconds=0.0))
                continue
            limit = self.cfg.max_seconds if self.cfg.max_seconds is not None else task(name).max_seconds
            self._episodes[w] = _Episode(inst=inst, limit=float(limit))
            if self.runner.loaded.env_state_dim:  # its environment state's keys, once per episode
                from stages.engine.env_state import episode_goal, episode_keys

                self._episodes[w].env = episode_keys(self.engine, name, episode_goal(inst))
            return inst, float(limit) + 1.0  # the act loop stops at ``limit``; the engine's limit is a guard
        return None

    def _begin(self, w: int, ticket):
        ep = self._episodes[w]
        if self.video_quota[ticket.task] < self.cfg.videos and self.engine.config.record_images:
            from .video import RolloutVideo

            self.video_quota[ticket.task] += 1
            path = self.out / "videos" / ticket.task / f"{self.world.scene_id}_seed{ticket.seed}.mp4"
            ep.video = RolloutVideo(path, fps=self.cfg.fps, cameras=self.engine.config.cameras)

        def sink(frame) -> None:
            ep.frames += 1
            if ep.video is not None:
                ep.video.add(frame.rgb)
            for f in self.frame_listeners:
                f(w, frame)
        return sink

    def _end(self, w: int, ticket, res) -> None:
        ep = self._episodes.pop(w)
        path = ep.video.close() if ep.video is not None else None
        video = "" if path is None else str(path)
        self._record(EpisodeRecord(task=ticket.task, scene=self.world.scene_id, seed=ticket.seed, world=w,
                                   success=bool(res.success), reason=res.reason, frames=res.frames,
                                   sim_seconds=round(res.sim_seconds, 3), video=video))

    def _record(self, rec: EpisodeRecord) -> None:
        self.records.append(rec)
        log.info("eval: %s seed %d (%s, world %d): %s %s", rec.task, rec.seed, rec.scene, rec.world,
                 "success" if rec.success else "failed", rec.reason)
        for f in self.episode_listeners:
            f(rec)

    # -- a world's program: the policy drives the episode -----------------------------------------
    def _act(self, inst, drv) -> None:
        from stages.demos.tasks import task
        from stages.simulate.state import read_state

        view = drv.sim
        w = view.world
        ep = self._episodes[w]
        spec = task(inst.task)
        S, f = self.engine.steps_per_second, self.cfg.fps
        check = max(1, round(self.cfg.check_seconds * f))
        self.runner.reset(w, inst.seed)
        self._start[w] = self.engine.global_step
        self._active.add(w)
        try:
            k = 0
            while True:
                self._apply(drv, self._action(w))
                k += 1
                view.step(max(1, -(-k * S // f) - view.steps))  # to frame k
                if k / f >= ep.limit - 1e-9:
                    return  # the time limit: the engine's success predicate decides
                if k % check == 0:
                    ok, _ = spec.success(inst, read_state(view), peaks=self.engine.side.peaks.read(w))
                    if ok:
                        return
        finally:
            self._active.discard(w)

    def _action(self, w: int) -> np.ndarray:
        """World ``w``'s action at this frame step; the first world to ask computes every acting
        world's action in one batched call."""
        step = self.engine.global_step
        if step != self._cache_step:
            self._cache, self._cache_step, self._taken = {}, step, set()
        if w in self._taken:
            raise RuntimeError(f"eval: world {w} asked twice for an action at step {step}")
        if w not in self._cache:  # every acting world that has no action for this step yet
            worlds = sorted(v for v in self._active if v not in self._cache and v not in self._taken)
            obs = self.observe(worlds)
            for v in worlds:
                for fn in self.observers:
                    fn(v, self._frame_index(v), obs[v])
            self._cache.update(self.runner.act(obs))
            for fn in self.action_listeners:
                for v in worlds:
                    fn(v, self._frame_index(v), self._cache[v])
        self._taken.add(w)
        return self._cache.pop(w)

    def _frame_index(self, w: int) -> int:
        """World ``w``'s frame index in its episode at this (frame) step."""
        e = self.engine
        return round((e.global_step - self._start[w]) * self.cfg.fps / e.steps_per_second)

    def observe(self, worlds: list[int]) -> dict[int, dict[str, np.ndarray]]:
        """The policy's observations of ``worlds`` at this frame step: ``observation.state``
        (arm q, end-effector pose in the base frame, base pose: the recorder's; of a policy trained
        on a state view, its entries of it: :func:`state_selection`), the RGB image
        of each policy camera (H, W, 3) uint8 and, if the policy takes it,
        ``observation.environment_state`` (D,) float32 (the recorder's)."""
        e = self.engine
        q, _, base = e.capture.robot_state(worlds)
        ee = e.arm_fk.pose7(q)  # as the recorder writes it
        state = np.concatenate([q, ee, base], axis=1).astype(np.float32)
        if self._state_cols is not None:  # a policy of a state view takes these entries
            state = state[:, self._state_cols]
        out = {w: {"observation.state": state[j]} for j, w in enumerate(worlds)}
        if self.runner.loaded.env_state_dim and worlds:  # the recorder's function on the same state read
            from stages.engine.env_state import ENV_STATE_KEY, engine_environment_state

            env = engine_environment_state(e, worlds, [self._episodes[w].env for w in worlds], base)
            for j, w in enumerate(worlds):
                out[w][ENV_STATE_KEY] = env[j]
        images: dict[int, dict] = {}
        for w in worlds if self.runner.loaded.cameras else ():
            bank, i = e._where[w]
            if id(bank) not in images:
                images[id(bank)] = e.capture.images_now(bank)
            for cam in self.runner.loaded.cameras:
                out[w][f"observation.images.{cam}"] = images[id(bank)][cam][0][i].copy()
        return out

    def _apply(self, drv, a: np.ndarray) -> None:
        """The dataset's action vector -> commands (see the module docstring; with ``arm_command``
        "ee" the arm follows the action's end-effector target through :func:`ee_arm_targets`)."""
        n = len(drv.sim.desc.arm_joints)
        if self.cfg.arm_command == "ee":
            drv.ctl.set_arm_targets(ee_arm_targets(drv, self.engine.arm_fk, a[n:n + 7]))
        else:
            drv.ctl.set_arm_targets(a[:n])
        drv.base(tuple(float(x) for x in a[n + 7:n + 10]))
        g = float(np.clip(a[n + 10], 0.0, 1.0))
        drv.cmd.gripper = g
        drv.ctl.set_gripper(g)
        drv.cmd.mode = int(a[n + 11] >= 0.5)


def ee_arm_targets(drv, arm_fk, ee7: np.ndarray) -> np.ndarray:
    """Arm joint targets (n,) [rad] putting the end effector at ``ee7`` (x, y, z [m], qw, qx, qy,
    qz in the base frame: the action's ``ee_*_target``, which the recorder writes as the forward
    kinematics of the arm's joint targets): CLIK on the robot's model from the current targets and
    base joints (the base frame placed in the robot's root frame by the same arm kinematics)."""
    from scipy.spatial.transform import Rotation

    ik = drv.ik
    q_pin = ik.with_arm(ik.from_sim(drv.sim), drv.ctl.arm_targets())
    root_base = ik.fk(q_pin) @ np.linalg.inv(arm_fk(ik.arm_q(q_pin)[None])[0])
    goal = np.eye(4)
    quat = np.asarray(ee7[3:7], float)
    goal[:3, :3] = Rotation.from_quat([quat[1], quat[2], quat[3], quat[0]]).as_matrix()  # scipy: x, y, z, w
    goal[:3, 3] = ee7[:3]
    return ik.arm_q(ik.solve(root_base @ goal, q_pin, max_iters=100).q)


@dataclass
class EvalResult:
    """report: what ``eval.json`` holds; records: the episodes."""

    report: dict
    records: list[EpisodeRecord] = field(default_factory=list)


def evaluate(cfg: EvalConfig, out: Path, *, work_dir: Path | None = None, observers=(),
             frame_listeners=(), episode_listeners=(), action_listeners=()) -> EvalResult:
    """Evaluate ``cfg.checkpoint`` (see the module docstring); writes ``out/eval.json`` and the videos.
    ``episode_listeners``: ``f(record)`` with each finished episode; ``action_listeners``: ``f(world,
    frame, action)`` with each action (:class:`Evaluator`)."""
    from stages.engine import BatchEngine, EngineConfig

    from .runner import BatchedRunner, load_policy

    t0 = time.perf_counter()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    work = Path(work_dir) if work_dir is not None else out / ".work"
    held = held_out_check(cfg)
    loaded = load_policy(cfg.checkpoint, cfg.device)
    inference_settings(loaded, cfg)
    sizes = {s[1:] for s in loaded.image_shapes.values()}
    if len(sizes) > 1:
        raise ValueError(f"eval: the policy's cameras differ in size {sorted(sizes)}; the engine renders one size")
    size = dict(zip(("height", "width"), *sizes)) if sizes else {}  # no camera: the engine's default (videos)
    cams = loaded.cameras or (("third_person",) if cfg.videos else ())  # rendered: the policy's, or the videos'
    env_names = env_layout(cfg, loaded)
    runner = BatchedRunner(loaded)
    episodes = [(t, int(s)) for t in cfg.tasks for s in cfg.seeds]
    records: list[EpisodeRecord] = []
    quota: Counter = Counter()
    engine_stats = []
    for ws in cfg.scenes:
        world = build_kitchen(work / "kitchens", ws)
        ecfg = EngineConfig(worlds=min(cfg.worlds, len(episodes)), device=cfg.device, **size,
                            fps=cfg.fps, cameras=cams, environment_state=env_names, record_images=bool(cams))
        engine = BatchEngine(world, panda_root=None, work_dir=work / f"engine_ws{ws}", config=ecfg, seed=ws)
        ev = Evaluator(engine, runner, cfg, world, out, quota)
        ev.observers.extend(observers)
        ev.frame_listeners.extend(frame_listeners)
        ev.episode_listeners.extend(episode_listeners)
        ev.action_listeners.extend(action_listeners)
        records += ev.run(episodes)
        engine_stats.append(engine.stats.to_json())
    report = summarize(cfg, records, held, loaded, runner, time.perf_counter() - t0, engine_stats)
    (out / "eval.json").write_text(json.dumps(report, indent=2) + "\n")
    return EvalResult(report=report, records=records)


def inference_settings(loaded, cfg: EvalConfig) -> None:
    """Apply ``cfg``'s chunk execution settings to the loaded policy's config (the report reads
    them back); ValueError (one line) when the policy's chunk is shorter than ``action_steps``."""
    pc = loaded.policy.config
    horizon = getattr(pc, "chunk_size", None) or getattr(pc, "horizon", None)
    if cfg.action_steps is not None and horizon is not None and cfg.action_steps > horizon:
        raise ValueError(f"eval: {cfg.checkpoint}: action_steps {cfg.action_steps} > the policy's chunk of {horizon}")
    if loaded.type == "act":
        if cfg.ensemble_coeff is not None:
            pc.temporal_ensemble_coeff, pc.n_action_steps = float(cfg.ensemble_coeff), 1
        elif cfg.action_steps is not None:
            pc.temporal_ensemble_coeff, pc.n_action_steps = None, int(cfg.action_steps)
    elif cfg.ensemble_coeff is not None:
        raise ValueError(f"eval: {cfg.checkpoint}: temporal ensembling is ACT's; this is a {loaded.type} policy")
    elif cfg.action_steps is not None:
        pc.n_action_steps = int(cfg.action_steps)


def state_selection(recorded: list[str], loaded, checkpoint) -> list[int] | None:
    """Indices of the policy's state entries in the recorder's state ``recorded`` (None: the whole
    state); ValueError (one line, naming the checkpoint) when the policy takes an entry the
    recorder has not, or a state of another size without its names."""
    from stages.dataset.view import state_columns

    if loaded.state_names is None:
        if loaded.state_dim != len(recorded):
            raise ValueError(f"eval: {checkpoint}: the policy takes a state of {loaded.state_dim} entries, the robot's "
                             f"has {len(recorded)} and the checkpoint names none (no agentworld_policy.json)")
        return None
    if list(loaded.state_names) == list(recorded):
        return None
    return state_columns(recorded, loaded.state_names, f"eval: {checkpoint}")


def env_layout(cfg: EvalConfig, loaded) -> tuple[str, ...]:
    """The environment state's names of a policy that takes one (() otherwise): its checkpoint's
    names (:data:`~stages.policy.runner.POLICY_INFO`) when recorded, else the tasks' layout of the
    policy's input size; ValueError (one line) when the tasks' layouts differ or none is the policy's."""
    if not loaded.env_state_dim:
        return ()
    from stages.engine.env_state import optional_layouts

    try:  # with and without the optional entries (the front's direction, the base's velocity, the gripper's opening)
        layouts = optional_layouts(cfg.tasks)
    except ValueError as e:
        raise ValueError(f"eval: {cfg.checkpoint}: the policy takes observation.environment_state; {e}") from None
    recorded = loaded.env_state_names  # the checkpoint's names (None: not recorded)
    if recorded is not None:
        if tuple(recorded) not in layouts:
            raise ValueError(f"eval: {cfg.checkpoint}: the policy's environment state {list(recorded)} is none of the "
                             f"tasks' layouts {[list(n) for n in layouts]}")
        return tuple(recorded)
    names = next((n for n in layouts if len(n) == loaded.env_state_dim), None)
    if names is None:
        raise ValueError(f"eval: {cfg.checkpoint}: the policy takes an environment state of {loaded.env_state_dim} "
                         f"entries; the tasks' layouts are {dict.fromkeys(cfg.tasks, layouts[0])}")
    return names


def summarize(cfg: EvalConfig, records: list[EpisodeRecord], held: dict, loaded, runner, wall: float,
              engine_stats: list) -> dict:
    """The ``eval.json`` report: success per task and per family with failure reasons, every episode."""
    from dataclasses import asdict

    from stages.demos.tasks import task

    def table(recs: list[EpisodeRecord]) -> dict:
        n, ok = len(recs), sum(r.success for r in recs)
        fails = Counter(r.reason or "unspecified" for r in recs if not r.success)
        return {"episodes": n, "successes": ok, "success_rate": round(ok / n, 4) if n else None,
                "failures": dict(sorted(fails.items()))}

    pc = loaded.policy.config
    policy = {"type": loaded.type, "cameras": list(loaded.cameras), "chunk_size": getattr(pc, "chunk_size", None),
              "n_action_steps": getattr(pc, "n_action_steps", None),
              "temporal_ensemble_coeff": getattr(pc, "temporal_ensemble_coeff", None),
              "n_obs_steps": getattr(pc, "n_obs_steps", None), "horizon": getattr(pc, "horizon", None),
              "environment_state": loaded.env_state_dim}
    fams = sorted({str(task(r.task).family) for r in records})
    return {"checkpoint": str(cfg.checkpoint), "policy": policy, "device": cfg.device, "worlds": cfg.worlds,
            "scenes": [scene_id(s) for s in cfg.scenes], "seeds": list(cfg.seeds), "held_out": held,
            "tasks": {t: table([r for r in records if r.task == t]) for t in cfg.tasks},
            "families": {f: table([r for r in records if str(task(r.task).family) == f]) for f in fams},
            "overall": table(records), "episodes": [asdict(r) for r in records],
            "runner": {"model_calls": runner.model_calls, "chunks": runner.chunks},
            "engine": engine_stats, "wall_seconds": round(wall, 2)}
