"""One simulated world running episodes: build once, reset per episode, record through a sink.

::

    kitchen = write_kitchen(dir, library, scene_id="w0", rng=rng)
    world = DemoWorld(kitchen, panda_root=None, work_dir=dir, settings=DemoSettings())
    inst = sample_instance("press_button", kitchen, seed=7)
    result = world.run_episode(inst, sink=shard.add_frame)   # EpisodeResult
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from stages.demos.experts import EXPERTS, Driver, ExpertFailure, timed_clik
from stages.demos.record import Commands, EpisodeTimeout, Recorder, Timings
from stages.demos.kitchen import FREE_ROLES, KitchenWorld, watched_joints
from stages.demos.sampling import TaskInstance, object_coords
from stages.demos.tasks import task

log = logging.getLogger(__name__)

CAMERAS = ("wrist", "head", "third_person")


@dataclass(frozen=True, kw_only=True)
class DemoSettings:
    """width, height: image size of every camera [px]; fps; record_images: render cameras (False:
    state/action only, for success-rate runs); device: "cpu" or "cuda"."""

    width: int = 128
    height: int = 96
    fps: int = 30
    record_images: bool = True
    device: str = "cpu"

    def dataset_spec(self):
        """The dataset spec: 3 cameras (RGB + depth) when images are recorded, else state/action only."""
        from stages.dataset import CameraSpec, DatasetSpec

        cams = CAMERAS if self.record_images else ()
        return DatasetSpec(fps=self.fps, cameras=tuple(CameraSpec(c, height=self.height, width=self.width)
                                                       for c in cams))


@dataclass
class EpisodeResult:
    """success; reason: failure category ("" on success); detail: message; frames recorded;
    sim_seconds: simulated time [s]; wall_seconds; timings: per stage."""

    success: bool
    reason: str
    detail: str
    frames: int
    sim_seconds: float
    wall_seconds: float
    timings: Timings = field(default_factory=Timings)


def _free_joint_coords(sim, body_path: str) -> int:
    """First coordinate index of the free joint of scene body ``body_path`` (world 0)."""
    body = sim.body_of_path(body_path)
    child = sim.model.joint_child.numpy()
    j = int(np.nonzero(child == body)[0][0])
    return int(sim.model.joint_q_start.numpy()[j])


def set_coords(sim, values: dict[int, float]) -> None:
    """Overwrite joint coordinates (model indices -> value) of the current state and re-run FK."""
    import newton
    import warp as wp

    q = sim.state_0.joint_q.numpy().copy()
    for i, v in values.items():
        q[i] = v
    q_wp = wp.array(q, dtype=wp.float32, device=sim.model.device)
    sim.state_0.joint_q.assign(q_wp)
    newton.eval_fk(sim.model, q_wp, sim.state_0.joint_qd, sim.state_0)
    sim.state_1.assign(sim.state_0)


class JointPeaks:
    """Pre-step callback: the largest value [m or rad] each watched scene joint (prim path) reached
    during an episode (sampled every ``every`` physics steps), for predicates of momentary
    events (a pressed button)."""

    def __init__(self, sim, paths, every: int = 5) -> None:
        qs = sim.model.joint_q_start.numpy()
        self.index = {p: int(qs[j]) for j, p in sim.scene.joint_path.items() if p in set(paths)}
        self.peak: dict[str, float] = {}
        self.every, self.active = every, False
        sim.pre_step.append(self)

    def start(self) -> None:
        self.peak = {p: -math.inf for p in self.index}
        self.active = True

    def stop(self) -> None:
        self.active = False

    def __call__(self, sim) -> None:
        if not self.active or not self.index or sim.steps % self.every:
            return
        q = sim.state_0.joint_q.numpy()
        for p, i in self.index.items():
            self.peak[p] = max(self.peak[p], float(q[i]))


class DemoWorld:
    """A simulation of one :class:`~stages.demos.kitchen.KitchenWorld` with the robot, controllers,
    cameras and a recorder. ``panda_root``: the Panda description's package root (None: the pip
    package example-robot-data)."""

    def __init__(self, world: KitchenWorld, *, panda_root: Path | None, work_dir: Path,
                 settings: DemoSettings, seed: int = 0) -> None:
        from stages.simulate.control import RobotControl
        from stages.simulate.robot import find_panda_description, write_robot_urdf
        from stages.simulate.world import SimConfig, build_sim

        self.world, self.settings = world, settings
        t0 = time.perf_counter()
        desc = write_robot_urdf(Path(work_dir) / "robot", panda_root=find_panda_description(panda_root))
        self.sim = build_sim(SimConfig(scenes=(world.usd,), spawn=world.spawn, device=settings.device),
                             desc, np.random.default_rng(seed))
        self.ctl = RobotControl(self.sim)
        self.ik = timed_clik(desc)
        self.cmd = Commands()
        self.rig = self._rig(desc) if settings.record_images else None
        self.recorder = Recorder(self.sim, self.ik, self.ctl, self.cmd, rig=self.rig, fps=settings.fps)
        self.build_seconds = time.perf_counter() - t0
        self._free = {p.body(): _free_joint_coords(self.sim, p.body())
                      for k, p in world.placed.items() if k in FREE_ROLES}
        self.peaks = JointPeaks(self.sim, watched_joints(world))
        qs = self.sim.model.joint_q_start.numpy()
        self._scene_joint = {p: int(qs[j]) for j, p in self.sim.scene.joint_path.items()}

    def _rig(self, desc):
        from stages.simulate.sensors import CameraRig, CameraSpec, look_at

        s = self.settings
        cams = [CameraSpec(name=n, width=s.width, height=s.height, vertical_fov=desc.cameras[n].vertical_fov,
                           link=desc.cameras[n].link) for n in ("wrist", "head")]
        sx, sy = self.world.size
        eye, target = (0.3, 0.3, 2.3), (0.6 * sx, 0.6 * sy, 0.6)
        cams.append(CameraSpec(name="third_person", width=s.width, height=s.height, vertical_fov=1.0,
                               pose=look_at(eye, target)))
        return CameraRig(self.sim, cams, segmentation=False)

    def reset(self, inst: TaskInstance) -> None:
        """Robot at the instance's start pose, objects and scene joints at their initial values."""
        sim = self.sim
        sim.reset(base=inst.start_base)
        self.ctl.reset()
        values = {}
        for body, pose in inst.objects.items():
            # free joint: position, then quaternion x, y, z, w
            values.update(dict(enumerate(object_coords(pose), start=self._free[body])))
        for path, v in inst.joints.items():
            values[self._scene_joint[path]] = v
        set_coords(sim, values)
        self.cmd.base_velocity = np.zeros(3)
        self.cmd.gripper, self.cmd.mode = 0.0, 0

    def run_episode(self, inst: TaskInstance, sink=None, *,
                    max_seconds: float | None = None) -> EpisodeResult:
        """Reset, run the task's expert while recording into ``sink``, evaluate the predicate.
        ``max_seconds``: time limit [s] (default: the task's)."""
        from stages.simulate.state import read_state

        spec = task(inst.task)
        self.reset(inst)
        rec = self.recorder
        rec.sink, rec.timings = sink, Timings()
        self.ik.seconds = 0.0
        drv = Driver(self.sim, self.ctl, self.ik, self.cmd, rec, np.random.default_rng(inst.seed))
        t0 = time.perf_counter()
        rec.start(spec.max_seconds if max_seconds is None else max_seconds)
        self.peaks.start()
        reason = detail = ""
        try:
            EXPERTS[inst.task](inst, drv)
            drv.step(0.3)
        except ExpertFailure as e:
            reason, detail = e.reason, str(e)
        except EpisodeTimeout as e:
            reason, detail = "timeout", str(e)
        finally:
            rec.stop()
            self.peaks.stop()
            self.ctl.set_base_velocity(0.0, 0.0, 0.0)
        wall = time.perf_counter() - t0
        state = read_state(self.sim)
        if not reason:
            ok, reason = spec.success(inst, state, peaks=dict(self.peaks.peak))
            detail = reason
        tm = rec.timings
        tm.control += self.ik.seconds + drv.plan_seconds
        tm.simulation += max(0.0, wall - tm.control - tm.rendering - tm.encoding)
        res = EpisodeResult(success=not reason, reason=reason, detail=detail, frames=rec.frames,
                            sim_seconds=self.sim.time, wall_seconds=wall, timings=tm)
        log.info("%s seed %d: %s %s (%d frames, %.1f s sim, %.1f s wall)", inst.task, inst.seed,
                 "success" if res.success else "FAILED", detail, res.frames, res.sim_seconds, wall)
        return res
