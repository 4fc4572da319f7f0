"""The table tasks' rig (:mod:`stages.demos.table_tasks`): one simulation per embodiment-task
pair (:class:`TableRig`), its control that remembers the gripper commands (the action's gripper
column), the experts' failure (:class:`TaskFailure`) and outcome (:class:`Outcome`), and the hands'
opening and hook primitives shared by the pick & place and drawer experts.

Frames: world, Z up, metres, radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


class TaskFailure(RuntimeError):
    """The expert could not finish: ``reason`` is a short category (grasp_missed, dropped, ...)."""

    def __init__(self, reason: str, detail: str = "") -> None:
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason = reason


@dataclass(frozen=True, kw_only=True)
class Outcome:
    """success; reason ("" on success); detail: what was measured (for the report)."""

    success: bool
    reason: str
    detail: dict = field(default_factory=dict)


# --------------------------------------------------------------------------------------------
# commands that remember what they were told (the action's gripper column)
# --------------------------------------------------------------------------------------------


def _remembering(cls):
    """A subclass of control class ``cls`` that keeps the last gripper command per arm."""

    class Remembering(cls):
        def __init__(self, sim) -> None:
            super().__init__(sim)
            self.commands: dict[str | None, float] = {}

        def set_gripper(self, command: float, world: int | None = None, arm: str | None = None) -> None:
            if arm is None:
                super().set_gripper(command, world)
                for k in list(self.commands) or [None]:
                    self.commands[k] = float(command)
            else:
                super().set_gripper(command, world, arm)
                self.commands[arm] = float(command)

        def reset(self) -> None:
            super().reset()
            self.commands = {k: 0.0 for k in self.commands}

    return Remembering


# --------------------------------------------------------------------------------------------
# the rigs: one simulation per pair
# --------------------------------------------------------------------------------------------


@dataclass(eq=False)
class TableRig:
    """One pair's simulation: ``sim``, its control ``ctl`` and IK ``ik``, the robot description
    ``desc``, the table scene ``scene`` (hand tasks: :class:`stages.demos.hand_scene.TableScene`;
    dual-arm: :class:`stages.demos.bimanual.TableScene`), the object's nominal position ``home_xy``."""

    pair: str
    sim: object
    ctl: object
    ik: object
    desc: object
    scene: object
    home_xy: tuple[float, float]
    asset_ids: tuple[str, ...] = ()

    @property
    def embodiment(self) -> str:
        return self.pair.split("/")[0]

    @property
    def task(self) -> str:
        return self.pair.split("/")[1]

    @property
    def body(self) -> int:
        return self.sim.body_of_path(self.scene.body)

    def reset(self, rng: np.random.Generator) -> dict:
        """Start an episode: robot at its start posture, hand / grippers open, the object at a random
        pose near ``home_xy`` (hands: +-3 cm, any yaw for the can, +-60 deg for the mug; dual-arm:
        the ranges of the bimanual slow test); let it settle 0.1 s. Returns the episode's sample
        (object xy, yaw, and a hand task's target spot)."""
        from stages.demos import bimanual as bm

        x0, y0 = self.home_xy
        if self.task in ("open_drawer", "close_drawer", "open_double_door"):
            return self.scene.reset(self, rng)
        if self.embodiment == "aloha":
            xy = (x0 + rng.uniform(-0.04, 0.04), y0 + rng.uniform(-0.03, 0.03))
            yaw = rng.uniform(-0.2, 0.2)
            bm.reset_episode(self.sim, self.ctl, self.scene, xy, yaw)
            sample = {"xy": xy, "yaw": yaw}
        else:
            xy = (x0 + rng.uniform(-0.03, 0.03), y0 + rng.uniform(-0.03, 0.03))
            # the mug's handle (mug_04's at +Y at yaw 0) within 0.8 rad of across the fingers
            yaw = rng.uniform(-math.pi, math.pi) if self.task == "pick_place_can" else \
                float(rng.choice([0.0, math.pi]) + rng.uniform(-0.8, 0.8))
            # place target: across the table's centre line, 14-20 cm to the side
            side = rng.choice([-1.0, 1.0])
            target = (xy[0] + rng.uniform(-0.03, 0.03), xy[1] + side * rng.uniform(0.14, 0.20))
            bm.reset_episode(self.sim, self.ctl, self.scene, xy, yaw)
            sample = {"xy": xy, "yaw": yaw, "target": target}
        self.sim.step(50)
        return {k: np.round(np.asarray(v, float), 4).tolist() for k, v in sample.items()}



# --------------------------------------------------------------------------------------------
# the hands' primitives
# --------------------------------------------------------------------------------------------


def open_hand(rig: TableRig, duration: float, *, hooked: bool = False) -> None:
    """Open the hand from its current command to 0 in ``duration`` [s], along the hook synergy
    (:func:`hook`) with ``hooked``."""
    sim, ctl = rig.sim, rig.ctl
    steps = max(1, int(round(duration / sim.settings.dt)))
    c0 = ctl.commands.get(None, 1.0)
    for i in range(0, steps, 10):
        c = c0 * (1.0 - min(1.0, (i + 10) / steps))
        hook(rig, c) if hooked else ctl.set_gripper(c)
        sim.step(10)


def hook(rig: TableRig, command: float) -> np.ndarray:
    """Command the hand to ``command`` in [0, 1] along its hook synergy (a bar handle gripped by
    the fingers, :meth:`stages.simulate.hands.HandInfo.synergy`); the action's gripper column
    records ``command``. Returns the finger targets (n,) [rad]."""
    q = rig.desc.gripper.hand.synergy(command, hook=True)
    rig.ctl.set_finger_targets(q)
    rig.ctl.commands[None] = float(command)
    return q
