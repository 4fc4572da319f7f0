"""One world of a batched simulation, seen as a single-world simulation.

A world's program (a scripted expert written against :class:`~stages.simulate.world.Sim` with
world 0) runs unchanged on a :class:`WorldView`: indices are world-local, state arrays are that
world's slices of one batched host read (:class:`Snapshot`, taken at most once per engine step and
shared by all worlds), ``step(n)`` blocks until the engine has advanced every world, and time is
the world's episode time. :class:`WorldControl` is the matching view of
:class:`~stages.simulate.control.RobotControl`: commands land in the engine's per-world host
buffers, uploaded in one copy before the next physics step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


class Snapshot:
    """Host copies of the batched state (joint_q (W*C,), joint_qd (W*D,), body_q (W*B, 7)), read
    on first use after each engine step (one device-to-host copy per array for all worlds)."""

    def __init__(self, sim) -> None:
        self.sim = sim
        self._cache: dict[str, np.ndarray] = {}
        self.reads = 0

    def invalidate(self) -> None:
        self._cache.clear()

    def prefetch(self) -> None:
        """Read every array now (before work is enqueued that a later read would wait for)."""
        for name in ("joint_q", "joint_qd", "body_q"):
            self.get(name)

    def get(self, name: str) -> np.ndarray:
        a = self._cache.get(name)
        if a is None:
            a = self._cache[name] = getattr(self.sim.state_0, name).numpy()
            self.reads += 1
        return a


class _Array:
    """A host array with the ``.numpy()`` of a Warp array (a copy: callers may modify it);
    ``src``: the array, or a function returning it."""

    def __init__(self, src) -> None:
        self._src = src

    def numpy(self) -> np.ndarray:
        return np.array(self._src() if callable(self._src) else self._src)


class _WorldState:
    def __init__(self, view: WorldView) -> None:
        v = view
        self.joint_q = _Array(lambda: v._snap.get("joint_q")[v._c0:v._c0 + v.coords_per_world])
        self.joint_qd = _Array(lambda: v._snap.get("joint_qd")[v._d0:v._d0 + v.dofs_per_world])
        self.body_q = _Array(lambda: v._snap.get("body_q")[v._b0:v._b0 + v.bodies_per_world])


class _WorldModel:
    """World 0's slices of the model's per-joint arrays (world-local indices, as in world 0)."""

    def __init__(self, sim) -> None:
        m = sim.model
        nw = sim.world_count
        nj = m.joint_count // nw
        self.device = m.device
        self.world_count = 1
        self.joint_q_start = _Array(m.joint_q_start.numpy()[:nj])
        self.joint_qd_start = _Array(m.joint_qd_start.numpy()[:nj])
        self.joint_child = _Array(m.joint_child.numpy()[:nj])
        self.joint_label = list(m.joint_label)[:nj]
        d = sim.dofs_per_world
        self.joint_limit_lower = _Array(m.joint_limit_lower.numpy()[:d])
        self.joint_limit_upper = _Array(m.joint_limit_upper.numpy()[:d])

    def __getstate__(self) -> dict:
        d = dict(self.__dict__)
        d["device"] = str(d["device"])
        return d


@dataclass(frozen=True, eq=False)
class SimInfo:
    """What a world view needs of a Sim, without its device arrays (picklable: world programs
    in other processes get it)."""

    desc: object
    robot: object
    scene: object
    spawn: tuple
    settings: object
    solver_settings: object
    bodies_per_world: int
    shapes_per_world: int
    dofs_per_world: int
    coords_per_world: int
    shape_label: np.ndarray

    @classmethod
    def of(cls, sim) -> SimInfo:
        return cls(desc=sim.desc, robot=sim.robot, scene=sim.scene, spawn=tuple(sim.spawn), settings=sim.settings,
                   solver_settings=sim.solver_settings, bodies_per_world=sim.bodies_per_world,
                   shapes_per_world=sim.shapes_per_world, dofs_per_world=sim.dofs_per_world,
                   coords_per_world=sim.coords_per_world, shape_label=np.asarray(sim.shape_label))


class WorldView:
    """World ``world`` of an engine (world ``local`` of its Sim ``bank.sim``) with the attributes
    and methods of a one-world :class:`~stages.simulate.world.Sim` that programs use (``world``
    arguments must be 0)."""

    def __init__(self, engine, world: int, bank, local: int, model: _WorldModel, steps: np.ndarray) -> None:
        sim = bank.sim
        self._engine, self.world, self._steps = engine, world, steps
        self._snap: Snapshot = bank.snapshot
        self.desc, self.robot, self.scene, self.spawn = sim.desc, sim.robot, sim.scene, sim.spawn
        self.settings, self.solver_settings = sim.settings, sim.solver_settings
        self.bodies_per_world, self.shapes_per_world = sim.bodies_per_world, sim.shapes_per_world
        self.dofs_per_world, self.coords_per_world = sim.dofs_per_world, sim.coords_per_world
        self.shape_label = sim.shape_label[local * sim.shapes_per_world:(local + 1) * sim.shapes_per_world]
        self._c0, self._d0 = local * sim.coords_per_world, local * sim.dofs_per_world
        self._b0 = local * sim.bodies_per_world
        self.model = model
        self.state_0 = _WorldState(self)
        self.world_count = 1
        self.pipeline = self.contacts = None
        self.pre_step: list = []  # engine-side work is batched; per-world callbacks are not run
        self._joint_coord = {p: int(model.joint_q_start.numpy()[j]) for j, p in sim.scene.joint_path.items()}

    @property
    def steps(self) -> int:
        """Physics steps since this world's episode started."""
        return int(self._steps[self.world])

    @property
    def time(self) -> float:
        """This world's episode time [s]."""
        return self.steps * self.settings.dt

    def step(self, n: int = 1) -> None:
        """Advance ``n`` physics steps (all worlds advance together; blocks this world's program)."""
        self._engine.request_steps(self.world, n)

    # -- world-local indices (as Sim's with world 0) ---------------------------------------
    def _local(self, world: int) -> None:
        if world != 0:
            raise ValueError(f"a world view has one world (0); got {world}")

    def world_dof(self, name: str, world: int = 0) -> int:
        self._local(world)
        return self.robot.dof[name]

    def world_coord(self, name: str, world: int = 0) -> int:
        self._local(world)
        return self.robot.coord[name]

    def world_body(self, name: str, world: int = 0) -> int:
        self._local(world)
        return self.robot.body[name]

    def body_of_path(self, path: str, world: int = 0) -> int:
        self._local(world)
        for b, p in self.scene.body_path.items():
            if p == path:
                return b
        raise KeyError(path)

    def joint_q_of_path(self, path: str, world: int = 0) -> float:
        """Position of a one-dof scene joint (by prim path) [m or rad]."""
        self._local(world)
        return float(self._snap.get("joint_q")[self._c0 + self._joint_coord[path]])


class WorldControl:
    """World ``world``'s view of the engine's command buffers
    (:class:`~stages.simulate.control.CommandBuffers`, e.g. its ``RobotControl``)."""

    def __init__(self, ctl, world: int) -> None:
        self._ctl, self.world = ctl, world
        self.desc, self.arm_lower, self.arm_upper = ctl.desc, ctl.arm_lower, ctl.arm_upper

    def set_base_velocity(self, vx: float, vy: float, vtheta: float, world: int | None = None) -> None:
        self._ctl.set_base_velocity(vx, vy, vtheta, world=self.world)

    def set_arm_targets(self, q, world: int | None = None) -> None:
        self._ctl.set_arm_targets(q, world=self.world)

    def set_gripper(self, command: float, world: int | None = None) -> None:
        self._ctl.set_gripper(command, world=self.world)

    def set_finger_targets(self, q, world: int | None = None) -> None:
        self._ctl.set_finger_targets(q, world=self.world)

    def arm_targets(self, world: int = 0) -> np.ndarray:
        return self._ctl.arm_targets(self.world)
