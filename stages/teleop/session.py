"""A teleop session: one task world on the batched engine, driven by an operator (or a replay).

The session runs the engine (:class:`~stages.engine.BatchEngine`, one world, CPU by default) in a
thread of its own. Each engine episode starts from a reset to a task instance (the scripted demos'
``sample_instance``: robot start, object poses, scene joints) and is driven by the session's
``act`` loop instead of a scripted expert: once per frame period (1 / fps [s] of simulated time)
it takes the operator's current controls (:class:`~stages.teleop.control.Tick`), applies them
(:class:`~stages.teleop.control.TickApplier`), logs them (:mod:`stages.teleop.inputlog`) and lets
the engine step to the next frame; live sessions pace that loop to the wall clock.

Episodes: a *preview* episode (not recorded) runs until the operator presses start; then a
*recorded* episode starts from a fresh reset of the same instance and runs until save (written,
:mod:`stages.teleop.recording`), discard, or the time limit (discarded as "timeout"); then the next
preview (the next seed). Every frame of either goes to the frame listeners (the server's stream).

Thread model: the server's thread calls :meth:`submit` (validated messages) and :meth:`status`;
everything else runs in the session's thread. Latencies: input-to-command is the wall time from a
command's arrival to the tick that applies it [ms]; render-to-display is from a frame's capture
to the arrival of the page's acknowledgement of having drawn it [ms] (an upper bound: it includes
the acknowledgement's way back).
"""

from __future__ import annotations

import collections
import logging
import secrets
import threading
import time
from dataclasses import asdict, dataclass, field, replace
from datetime import UTC, datetime
from pathlib import Path

from stages.teleop.control import TeleopConfig, Tick, TickApplier
from stages.teleop.inputlog import VERSION, InputLog, SessionScript
from stages.teleop.protocol import EpisodeControl, FrameAck, OperatorCommand, XrPoses
from stages.teleop.recording import TeleopRecorder, latency_stats

log = logging.getLogger(__name__)

PREVIEW_SECONDS = 24 * 3600.0  # a preview episode's time limit [s] (it ends at start or stop)


@dataclass(eq=False)
class _Episode:
    """An engine episode of the session: its index, instance seed, whether it is recorded, its
    instruction, how it ended and its latency samples [ms]."""

    k: int
    seed: int
    record: bool
    instruction: str
    ticks: int = 0
    outcome: str = ""
    reason: str = ""
    input_ms: list = field(default_factory=list)
    display_ms: list = field(default_factory=list)
    script: object = None  # the EpisodeScript being replayed
    started: float = 0.0
    xr_calib: object = None  # head pose (4, 4) at the episode's first XR message
    xr_gripper: int = 0
    xr_hand: tuple | None = None  # the last retargeted hand joint targets [rad]
    devices: set = field(default_factory=set)  # "webxr" once XR poses drove a tick


class TeleopSession:
    """One task world driven by an operator (or by ``replay``, a parsed input log: headless).

    world: a kitchen (:class:`~stages.demos.kitchen.KitchenWorld`); task: a basic task name;
    out: the output folder (:mod:`stages.teleop.recording`); world_seed: the kitchen's seed
    (logged, for replays); panda_root: the Panda description (None: example-robot-data)."""

    def __init__(self, world, *, task: str, out: Path, config: TeleopConfig, world_seed: int = 0,
                 replay: SessionScript | None = None, panda_root: Path | None = None,
                 world_info: dict | None = None) -> None:
        from stages.demos.tasks import TASKS
        from stages.engine import BatchEngine, EngineConfig

        if task not in TASKS:
            raise ValueError(f"teleop: unknown task {task!r}; known {sorted(TASKS)}")
        self.world, self.task, self.cfg, self.replay = world, task, config, replay
        self.out = Path(out)
        self._check_task()
        self.name = datetime.now(UTC).strftime("%Y%m%dT%H%M%S") + "-" + secrets.token_hex(3)
        # on the CPU (MuJoCo C) each frame renders in a thread of its own while the next frame's
        # physics steps run, and reaches the page as soon as it is rendered (the same frames:
        # stages.engine); the batched layout (CUDA: MuJoCo-Warp, a CUDA graph, the GPU's render)
        # renders in the engine's thread, on the CPU too (tests run the GPU's code path there)
        ecfg = EngineConfig(worlds=1, device=config.device, width=config.width, height=config.height,
                            fps=config.fps, cameras=config.cameras, gripper=config.hand or "panda_hand",
                            layout=config.layout)
        ecfg = replace(ecfg, background_render=ecfg.resolved_layout() == "per_world"
                       and not config.device.startswith("cuda"))
        self.engine = BatchEngine(world, panda_root=panda_root, work_dir=self.out / ".work" / self.name,
                                  config=ecfg, seed=world_seed)
        self.retargeter = None  # WebXR hand joints -> the dexterous hand's joint targets
        if config.hand is not None and replay is None:
            from stages.teleop.hand_retarget import HandRetargeter

            self.retargeter = HandRetargeter(config.hand, self.out / ".work" / self.name / "retarget",
                                             optimizer=config.retarget)
        self.hand_rejected = 0  # hand joint sets the retargeting refused (logged)
        self.recorder = TeleopRecorder(self.out, ecfg.dataset_spec(), self.name)
        self.recorder.preload()  # not at the first Start: the import stalled the stream 10-30 s
        self.log_path = self.out / "logs" / f"{self.name}.jsonl"
        self.input_log = InputLog(self.log_path)
        self.input_log.write({"kind": "session", "version": VERSION, "task": task, "world_seed": int(world_seed),
                              "world": world_info or {}, "config": asdict(config)})
        self.listeners: list = []  # f(frame_id, capture_time [s], {camera: RGB (H, W, 3) uint8})
        self._lock = threading.Lock()
        self._cmd = OperatorCommand(seq=0)
        self._controls: collections.deque[EpisodeControl] = collections.deque(maxlen=16)
        self._stop = threading.Event()
        self._want_record = replay is not None
        self._task_text = ""
        self._episodes: list[_Episode] = []
        self._ep: _Episode | None = None
        self._replay_queue = list(replay.recorded()) if replay is not None else []
        self._frame_id = 0
        self._captured: collections.OrderedDict[int, float] = collections.OrderedDict()
        self._frame_times: collections.deque[float] = collections.deque(maxlen=60)
        self._recent_input: collections.deque[float] = collections.deque(maxlen=60)
        self._recent_display: collections.deque[float] = collections.deque(maxlen=60)
        self.saved: list[Path] = []
        self.xr: XrPoses | None = None
        self.last_ee_pose: tuple | None = None  # newest frame's end-effector pose (7: xyz [m], wxyz) in the base frame
        self.error: BaseException | None = None
        self._thread: threading.Thread | None = None

    def _check_task(self) -> None:
        """Fail now, with the reason, if this world cannot hold the task (no start pose, no part)."""
        from pipeline.types import ItemError
        from stages.demos.sampling import sample_instance

        try:
            sample_instance(self.task, self.world, self.cfg.seed)
        except ItemError as e:
            raise ValueError(f"teleop: task {self.task!r} cannot run in {self.world.scene_id}: {e}") from None

    # -- the server's side ----------------------------------------------------------------------
    def submit(self, msg) -> None:
        """A validated operator message (:mod:`stages.teleop.protocol`)."""
        if isinstance(msg, OperatorCommand):
            with self._lock:
                self._cmd = msg
        elif isinstance(msg, EpisodeControl):
            self._controls.append(msg)
        elif isinstance(msg, FrameAck):
            with self._lock:
                t = self._captured.get(msg.frame)
                ep = self._ep
            if t is not None:
                ms = (msg.received - t) * 1000.0
                self._recent_display.append(ms)
                if ep is not None and ep.record:
                    ep.display_ms.append(ms)
        elif isinstance(msg, XrPoses):
            self.xr = msg

    def current_command(self) -> OperatorCommand:
        with self._lock:
            return self._cmd

    def status(self) -> dict:
        """What the page's status bar shows: frames per second (simulated frames per wall second),
        latencies [ms] (medians of the last 60), recording, episode, saved episodes, mode."""
        import numpy as np

        ft = list(self._frame_times)
        fps = (len(ft) - 1) / (ft[-1] - ft[0]) if len(ft) > 1 and ft[-1] > ft[0] else 0.0
        ep = self._ep
        with self._lock:
            cmd = self._cmd
        med = lambda d: round(float(np.median(list(d))), 1) if d else None  # noqa: E731
        return {"type": "status", "fps": round(fps, 1), "input_ms": med(self._recent_input),
                "display_ms": med(self._recent_display), "recording": bool(ep is not None and ep.record),
                "episode": ep.k if ep else None, "tick": ep.ticks if ep else 0, "saved": len(self.saved),
                "mode": cmd.mode, "gripper": cmd.gripper, "task": self.task,
                "instruction": ep.instruction if ep else "", "running": self.running,
                "ee_pose": self.last_ee_pose, "hand": self.cfg.hand,
                "hand_rejected": self.hand_rejected}

    def stop(self) -> None:
        """End the session: the episode in progress ends ("stop"; a recorded one is discarded)."""
        self._stop.set()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    # -- running ---------------------------------------------------------------------------------
    def start(self) -> threading.Thread:
        """Run the session in a thread (see :meth:`run`)."""
        self._thread = threading.Thread(target=self._main, name="teleop-session", daemon=True)
        self._thread.start()
        return self._thread

    def _main(self) -> None:
        try:
            self.run()
        except BaseException as e:  # noqa: BLE001 (kept for the caller: join() re-raises it)
            log.error("teleop: the session failed: %r", e, exc_info=e)
            self.error = e

    def join(self, timeout: float | None = None) -> None:
        if self._thread is not None:
            self._thread.join(timeout)
        if self.error is not None:
            raise RuntimeError(f"teleop session failed: {self.error!r}") from self.error

    def run(self) -> list[Path]:
        """Run episodes until :meth:`stop` (live) or the replayed log's end; returns the saved
        episodes' shard folders. The input log and the recorder are closed at the end."""
        try:
            self.engine.run(self._next_instance, begin=self._begin, end=self._end, act=self._act)
        finally:
            self.input_log.close()
            self.recorder.close()
        return self.saved

    # -- engine callbacks (the session's thread) -------------------------------------------------
    def _next_instance(self, w: int):
        from stages.demos.sampling import sample_instance

        if self.replay is not None:
            if not self._replay_queue:
                return None
            script = self._replay_queue.pop(0)
            seed, record, text = script.seed, True, script.instruction
        else:
            if self._stop.is_set():
                return None
            seed = self.cfg.seed + sum(e.record for e in self._episodes)
            record, text, script = self._want_record, self._task_text, None
            self._want_record = False
        inst = sample_instance(self.task, self.world, seed)
        ep = _Episode(k=len(self._episodes), seed=seed, record=record, instruction=text or inst.instruction,
                      script=script)
        self._episodes.append(ep)
        with self._lock:
            self._ep = ep
        self.input_log.write({"kind": "begin", "episode": ep.k, "task": self.task, "seed": seed, "record": record,
                              "instruction": ep.instruction})
        return inst, (self.cfg.episode_seconds if record else PREVIEW_SECONDS)

    def _begin(self, w: int, ticket):
        from stages.dataset import EpisodeInfo

        ep = self._ep
        ep.started = time.perf_counter()
        if ep.record:
            self.recorder.begin(ep.k, EpisodeInfo(task=ep.instruction, task_kind=self.task,
                                                  scene_id=self.world.scene_id, seed=ep.seed,
                                                  asset_ids=ticket.asset_ids))
        return self._on_frame

    def _on_frame(self, frame) -> None:
        ep = self._ep
        if ep.record:
            self.recorder.add_frame(frame)
        t = time.perf_counter()
        with self._lock:
            self._frame_id += 1
            fid = self._frame_id
            self._captured[fid] = t
            while len(self._captured) > 256:
                self._captured.popitem(last=False)
        self._frame_times.append(t)
        self.last_ee_pose = tuple(float(x) for x in frame.ee_pose)
        for f in self.listeners:
            f(fid, t, frame.rgb)

    def _act(self, inst, drv) -> None:
        ep = self._ep
        app = TickApplier(self.cfg, drv)
        if self.retargeter is not None:
            self.retargeter.reset()
        S, f = self.engine.steps_per_second, self.cfg.fps
        t0 = time.perf_counter()
        last = None
        timeout = self.cfg.command_timeout
        i = 0
        while True:
            if ep.script is not None:
                if i >= len(ep.script.ticks):
                    ep.outcome = ep.script.outcome
                    break
                tick = ep.script.ticks[i]
            else:
                out = self._control(ep)
                if out:
                    ep.outcome = out
                    break
                with self._lock:
                    cmd = self._cmd
                xr_tick = self._xr_tick(ep, timeout)
                if xr_tick is not None:
                    tick, cmd = xr_tick
                elif timeout is not None and cmd.received and time.perf_counter() - cmd.received > timeout:
                    tick = Tick(mode=cmd.mode, gripper=cmd.gripper)  # the page went quiet: axes released
                else:
                    tick = Tick(base=cmd.base, jog=cmd.jog, mode=cmd.mode, gripper=cmd.gripper)
            app.apply(tick)
            if ep.script is None and cmd is not last and cmd.received:
                ms = (time.perf_counter() - cmd.received) * 1000.0  # arrival -> applied [ms]
                self._recent_input.append(ms)
                if ep.record:
                    ep.input_ms.append(ms)
                last = cmd
            self.input_log.write({"kind": "tick", "episode": ep.k, "i": i, **tick.to_json()})
            ep.ticks = i = i + 1
            drv.sim.step(max(1, -(-i * S // f) - drv.sim.steps))  # to the next frame step
            if self.cfg.realtime:
                lag = t0 + i / f - time.perf_counter()
                if lag > 0:
                    time.sleep(lag)
        ep.reason = f"ik_misses={app.ik_misses}"

    def _xr_tick(self, ep: _Episode, timeout: float | None):
        """The tick of the newest WebXR poses (wrist -> end-effector target, pinch -> gripper, with
        a dexterous hand the fingers -> its joint targets) and the message it came from, or None
        when there is none (or it is older than ``timeout``)."""
        import numpy as np

        from stages.teleop.xr import pinch_gripper, wrist_to_ee_target

        xr = self.xr
        if xr is None or not xr.hands or (timeout is not None and time.perf_counter() - xr.received > timeout):
            return None
        head = np.asarray(xr.head, float)
        if ep.xr_calib is None:
            ep.xr_calib = head
        side = "right" if "right" in xr.hands else "left"
        joints = np.asarray(xr.hands[side], float)
        ep.xr_gripper = pinch_gripper(joints, ep.xr_gripper)
        ee = wrist_to_ee_target(joints[0], ep.xr_calib)
        ep.devices.add("webxr")
        if self.retargeter is not None:
            self._retarget(ep, joints, side)
        return Tick(mode=1, gripper=ep.xr_gripper, ee=tuple(float(x) for x in ee.ravel()), hand=ep.xr_hand), xr

    def _retarget(self, ep: _Episode, joints, side: str) -> None:
        """The hand's joint targets from the XR hand (kept as they were if it is refused)."""
        from stages.teleop.hand_retarget import HandPoseError

        try:
            ep.xr_hand = tuple(round(float(x), 6) for x in self.retargeter.retarget(joints, side))
        except HandPoseError as e:
            self.hand_rejected += 1
            if self.hand_rejected <= 5 or self.hand_rejected % 100 == 0:  # a bad stream: not every tick
                log.warning("teleop: %s hand joints rejected (%d so far): %s", side, self.hand_rejected, e)

    def _control(self, ep: _Episode) -> str:
        """The episode's outcome if the operator ended it ("start", "save", "discard", "stop"),
        else ""."""
        if self._stop.is_set():
            return "stop"
        while self._controls:
            c = self._controls.popleft()
            if c.action == "start" and not ep.record:
                self._want_record, self._task_text = True, c.task
                return "start"
            if c.action in ("save", "discard") and ep.record:
                return c.action
            log.info("teleop: %s ignored (%s)", c.action, "recording" if ep.record else "not recording")
        return ""

    def _end(self, w: int, ticket, res) -> None:
        ep = self._ep
        outcome = ep.outcome or "discard"
        reason = "" if ep.outcome else res.reason
        if ep.record:
            if outcome == "save":
                meta = {"session": self.name, "episode": ep.k, "task": self.task, "seed": ep.seed,
                        "input_device": "webxr" if "webxr" in ep.devices else self.cfg.input_device,
                        "input_log": str(self.log_path),
                        "ticks": ep.ticks, "frames": res.frames, "sim_seconds": round(res.sim_seconds, 4),
                        "wall_seconds": round(time.perf_counter() - ep.started, 3),
                        "task_success": bool(res.success), "task_reason": res.reason,
                        "latency": {"input_to_command": latency_stats(ep.input_ms),
                                    "render_to_display": latency_stats(ep.display_ms)}}
                if self.replay is not None:
                    meta["replay_of_episode"] = ep.script.episode
                self.saved.append(self.recorder.save(meta))
            else:
                self.recorder.discard(reason or outcome)
        self.input_log.write({"kind": "end", "episode": ep.k, "outcome": outcome, "reason": reason or ep.reason})
        self.input_log.sync()
        log.info("teleop: episode %d (%s, seed %d) %s %s", ep.k, "recorded" if ep.record else "preview", ep.seed,
                 outcome, reason)


def replay_session(script: SessionScript, world, *, out: Path, panda_root: Path | None = None,
                   world_info: dict | None = None) -> TeleopSession:
    """Run a logged session's saved episodes again, headless and as fast as the simulation runs;
    returns the finished session (``saved``: the replayed episodes' shards in ``out``)."""
    fields = {k: v for k, v in script.config.items() if k in TeleopConfig.__dataclass_fields__}
    if "cameras" in fields:
        fields["cameras"] = tuple(fields["cameras"])
    cfg = TeleopConfig(**(fields | {"realtime": False, "input_device": "replay"}))
    s = TeleopSession(world, task=script.task, out=out, config=cfg, world_seed=script.world_seed, replay=script,
                      panda_root=panda_root, world_info=world_info)
    s.run()
    return s


