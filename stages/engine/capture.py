"""The engine's frame capture, pipelined with the world programs.

At a frame step ``F`` the engine reads the state once per Sim and enqueues one render of every
camera in every world (:meth:`FrameCapture.launch`); the world programs then run, and once they
have answered, :meth:`FrameCapture.collect` takes each recording world's frame without its images
(robot state read at ``F``, the commands just given: the frame's action) and counts it. The images
are attached and the frames handed to the episode sinks by :meth:`FrameCapture.deliver`, called only
when the engine reaches the next frame step (before its render overwrites the read-back buffers) or
stops, so the GPU renders frame ``F`` while the programs and physics steps between ``F`` and the
next frame run on.

A step's frames are kept as columns (one (K, ...) array per field, :func:`collected`), not as K
:class:`~stages.dataset.Frame` objects; :func:`hand_over` gives the frames of a ShardPool's shards to
the pool in one call per pool and render (validated together, one message per writer), and builds a
Frame only for other sinks. On the CPU (``tests/benchmarks/bench_handoff.py``, 256 worlds, 3 cameras
240x320 RGB + depth) the engine thread's time per frame went from 0.78 ms (a Frame and an
``add_frame`` per world) to 0.26 ms, most of it the copy of the images into the writers' slots.

Episode begin and end callbacks that fall between a collect and its delivery are queued
(:meth:`FrameCapture.defer`) and run in order after the frames, so a sink receives all of its
episode's frames before the episode's ``end`` and a new episode's sink receives none of the old one's.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from stages.dataset.columns import FrameColumns, Images, frame_images
from stages.demos.record import COMMAND_ROW


@dataclass
class Collected:
    """The frames of one frame step without their images: per frame its sink (None: dropped), the
    id of the render (bank) its images come from and its row there; the numeric fields as columns."""

    sinks: list
    banks: list[int]
    rows: list[int]
    columns: FrameColumns


def collected(sinks: list, banks: list[int], rows: list[int], fields: dict[str, np.ndarray]) -> Collected:
    """The collected frames of one step: ``fields`` as :class:`FrameColumns` ((K, ...) arrays)."""
    return Collected(list(sinks), list(banks), list(rows), FrameColumns(dict(fields)))


def hand_over(c: Collected, images: dict[int, Images]) -> None:
    """Hand each collected frame with its images (``images``: render id -> camera -> RGB, depth
    stacked over the render's worlds) to its sink. Frames of a ShardPool's shards go in one
    :meth:`~stages.dataset.pool.ShardPool.add_frames` per pool and render (validated together,
    copied into the writers' slots); any other sink gets one :class:`Frame` per call, with views of
    the buffers if it ``takes_views`` (it copies before it returns), else copies."""
    from stages.dataset.pool import pool_target

    groups: dict[tuple[int, int], tuple[object, list[int], list[int]]] = {}
    for j, sink in enumerate(c.sinks):
        if sink is None:
            continue
        target = pool_target(sink)
        if target is not None:
            g = groups.setdefault((id(target[0]), c.banks[j]), (target[0], [], []))
            g[1].append(target[1])
            g[2].append(j)
            continue
        views = getattr(sink, "takes_views", False)  # the rig reuses its buffers: else copies
        sink(c.columns.frame(j, *frame_images(images.get(c.banks[j], {}), c.rows[j], copy=not views)))
    for (_, bank), (pool, shards, js) in groups.items():
        pool.add_frames(shards, c.columns.take(js), images.get(bank, {}), [c.rows[j] for j in js])


class FrameCapture:
    """Launch, collect and deliver the recorded frames of a :class:`~stages.engine.BatchEngine`.
    ``handle(kind, world, payload)`` runs a begin/end event (the engine's own handling)."""

    def __init__(self, engine, handle: Callable[[str, int, object], None]) -> None:
        self.e = engine
        self._handle = handle
        self.launched_step = self.collected_step = -1
        self.stale: set[int] = set()  # worlds reset after the render of this step was launched
        self._renders: dict[int, object] = {}  # renders in flight by bank (stages.simulate.compact)
        self._pending: Collected | None = None  # collected frames waiting for their images
        self._queued: list[tuple[str, int, object]] = []

    # -- events -------------------------------------------------------------------------------
    def defer(self, kind: str, w: int, payload) -> bool:
        """Queue a begin/end event behind the collected frames (True), or let it run now (False)."""
        if self._pending is None:
            return False
        self._queued.append((kind, w, payload))
        return True

    # -- the three steps ------------------------------------------------------------------------
    def launch(self) -> None:
        """At a frame step, before the programs run: deliver the previous frame, read the state
        (one read per Sim), enqueue one render of every world of each Sim with a recording world."""
        e = self.e
        step = e.global_step
        if step == self.launched_step or not e._is_frame_step(step):
            return
        self.deliver()
        self.launched_step = step
        self.stale.clear()
        t0 = time.perf_counter()
        banks = {id(e._where[w][0]): e._where[w][0] for w in self.recording()}
        for b in banks.values():
            b.snapshot.prefetch()
            if b.peaks.paths:
                b.peaks.host()
            if b.rig is not None:
                self._renders[id(b)] = b.rig.render_compact_async()
        e.stats.timings.rendering += time.perf_counter() - t0

    def collect(self) -> None:
        """At a frame step, after the programs: one frame (state and action) per recording world,
        as columns (:func:`collected`); its images follow at :meth:`deliver`."""
        e = self.e
        step = e.global_step
        if step == self.collected_step or not e._is_frame_step(step):
            return
        self.collected_step = step
        worlds = self.recording()
        t0 = time.perf_counter()
        for b in {id(e._where[w][0]): e._where[w][0] for w in worlds}.values():
            if id(b) not in self._renders and b.rig is not None:  # no recording world at the launch
                self._renders[id(b)] = b.rig.render_compact_async()
        if not worlds:
            return
        q_all, t_all, base_all = self.robot_state(worlds)
        ee_all = e.arm_fk.pose7(np.concatenate([q_all, t_all]))  # measured, then targets
        k = len(worlds)
        hand_q, hand_t = self.hand_state(worlds)
        base_v, grip, mode = self.commands(worlds)
        sinks, banks, rows, sub = [], [], [], []
        for w in worlds:
            rec = e.recs[w]
            bank, i = e._where[w]
            sinks.append(rec.sink)
            banks.append(id(bank))
            rows.append(i)
            sub.append(rec.subtask)
            rec.frames += 1
        self._pending = collected(sinks, banks, rows, dict(
            arm_joint_pos=q_all, ee_pose=ee_all[:k], base_pose=base_all, arm_joint_target=t_all,
            ee_target=ee_all[k:], base_velocity=base_v, gripper=np.asarray(grip, np.float64),
            mode=np.asarray(mode, np.int64), hand_joint_pos=hand_q, hand_joint_target=hand_t,
            subtask_index=np.asarray(sub, np.int64)))
        if e.config.environment_state:  # stages.engine.env_state: from the same state read
            from stages.engine.env_state import recorded_environment_state

            self._pending.columns.fields["environment_state"] = recorded_environment_state(e, worlds, base_all)
        e.stats.timings.encoding += time.perf_counter() - t0
        e.stats.timings.frames += k
        e.stats.renders += 1

    def deliver(self) -> None:
        """Wait for the renders in flight, attach the images to the collected frames, hand them to
        their sinks, then run the events queued behind them."""
        e = self.e
        t0 = time.perf_counter()
        images = {bid: r.wait() for bid, r in self._renders.items()}  # RGB uint8, depth [mm] uint16
        if not e.config.record_depth:  # RGB-only recording: the frames carry no depth
            images = {bid: {c: (im[0], None) for c, im in ims.items()} for bid, ims in images.items()}
        self._renders.clear()
        t1 = time.perf_counter()
        pending, self._pending = self._pending, None
        if pending is not None:
            hand_over(pending, images)
        tm = e.stats.timings
        tm.rendering += t1 - t0
        tm.encoding += time.perf_counter() - t1
        queued, self._queued = self._queued, []
        for kind, w, payload in queued:
            self._handle(kind, w, payload)

    @property
    def pending(self) -> bool:
        """Frames collected and waiting for their images."""
        return self._pending is not None

    def deliver_ready(self) -> bool:
        """:meth:`deliver` now if every render in flight is done and no begin/end event waits behind
        the frames (those run at the next frame step, as without this); True if it delivered."""
        if self._pending is None or self._queued or not all(r.done for r in self._renders.values()):
            return False
        self.deliver()
        return True

    def images_now(self, bank) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """The images of the current frame step for a Sim's worlds (by camera: RGB (W, H, Wd, 3)
        uint8, depth (W, H, Wd) uint16 [mm]; views: copy what you keep), for world programs that
        act on the current frame (policy evaluation). Waits for the render launched at this step,
        or launches it (then it is the one :meth:`collect` and :meth:`deliver` use)."""
        e = self.e
        if not e._is_frame_step(e.global_step) or self.collected_step == e.global_step:
            raise RuntimeError(f"engine: images_now at step {e.global_step}: only programs at a frame step")
        r = self._renders.get(id(bank))
        if r is None:
            r = self._renders[id(bank)] = bank.rig.render_compact_async()
        return r.wait()

    def close(self) -> None:
        """At the end of a run: deliver what was collected (and the queued events); a render
        launched but not collected is waited for and dropped."""
        self.deliver()

    # -- helpers ------------------------------------------------------------------------------
    def recording(self) -> list[int]:
        """Worlds that record a frame at this step: recording, within their limit, not held, and
        not reset after this step's render was launched (its images show the state before)."""
        e = self.e
        m = (e.rec_active != 0) & (e.steps <= e.rec_max) & ~e.held
        if self.stale:
            m[list(self.stale)] = False
        return np.nonzero(m)[0].tolist()

    def _rows(self, worlds: list[int], idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint positions and drive targets (K, len(idx)) at world-local coordinates ``idx`` of
        ``worlds``: one fancy index of each Sim's state read and command buffer."""
        e = self.e
        c = e.banks[0].sim.coords_per_world
        if len(e.banks) == 1:  # the batched layout: every world in one Sim
            bank = e.banks[0]
            at = np.asarray(worlds)[:, None] * c + idx
            return bank.snapshot.get("joint_q")[at], bank.ctl._targets[at]
        q, t = [], []
        for w in worlds:
            bank, i = e._where[w]
            q.append(bank.snapshot.get("joint_q")[i * c + idx])
            t.append(bank.ctl._targets[i * c + idx])
        return np.asarray(q).reshape(len(worlds), len(idx)), np.asarray(t).reshape(len(worlds), len(idx))

    def robot_state(self, worlds: list[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Arm joint positions (K, 7), arm joint targets (K, 7) and base poses (K, 3) (x, y, theta
        in the world [m, rad], as ``record.base_pose``) of ``worlds``, from one state read per Sim."""
        import math

        sim = self.e.banks[0].sim
        desc = sim.desc
        arm = np.array([sim.robot.coord[n] for n in desc.arm_joints])
        base = np.array([sim.robot.coord[n] for n in desc.base_joints])
        q, t = self._rows(worlds, arm)
        lb = self._rows(worlds, base)[0].astype(float)
        x0, y0, yaw0 = sim.spawn
        cs, sn = math.cos(yaw0), math.sin(yaw0)
        th = (yaw0 + lb[:, 2] + math.pi) % (2 * math.pi) - math.pi
        poses = np.stack([x0 + cs * lb[:, 0] - sn * lb[:, 1], y0 + sn * lb[:, 0] + cs * lb[:, 1], th], axis=1)
        return q, t, poses

    def hand_state(self, worlds: list[int]) -> tuple[np.ndarray, np.ndarray]:
        """A dexterous hand's joint positions and targets (K, n) [rad] of ``worlds`` (n = 0 for a
        parallel gripper: its command is the frame's ``gripper``), from the same state read."""
        e = self.e
        names = e.config.hand_joints()
        if not names:
            return np.zeros((len(worlds), 0)), np.zeros((len(worlds), 0))
        sim = e.banks[0].sim
        q, t = self._rows(worlds, np.array([sim.robot.coord[n] for n in names]))
        return q.astype(float), t.astype(float)

    def _command_rows(self, worlds: list[int]) -> np.ndarray:
        """The commands in force of ``worlds`` as records (K, :data:`~stages.demos.record.COMMAND_ROW`)
        (:meth:`~stages.demos.record.Commands.row`): from the worker processes' shared record in
        one read, or from the threads' :class:`~stages.demos.record.Commands`."""
        e = self.e
        if e.config.program_procs:
            return e.lockstep.a["cmdrec"][worlds]  # one copy of the rows
        return np.array([e.side.cmds[w].row() for w in worlds], np.float64).reshape(len(worlds), COMMAND_ROW)

    def commands(self, worlds: list[int]) -> tuple[np.ndarray, list[float], list[int]]:
        """The commands in force of ``worlds``: base velocities (K, 3) [m/s, m/s, rad/s], gripper
        commands and modes (K each)."""
        c = self._command_rows(worlds)
        return c[:, :3], c[:, 3].tolist(), c[:, 4].astype(int).tolist()

    def noise_inputs(self, worlds: list[int]) -> tuple[np.ndarray, list[int], list[bool], np.ndarray]:
        """What the execution noise (:func:`~stages.engine.action_noise.apply_noise`) reads of
        ``worlds``' commands in force, in one read: base velocities (K, 3) [m/s, m/s, rad/s], modes
        (K), whether the expert asks for execution without noise now (K;
        :attr:`~stages.demos.record.Commands.steady`) and the base's distance to the end of the path
        it follows (K,) [m] (inf when not following one; ``Commands.stop_distance``)."""
        c = self._command_rows(worlds)
        return c[:, :3], c[:, 4].astype(int).tolist(), (c[:, 5] != 0).tolist(), c[:, 6]
