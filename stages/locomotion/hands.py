"""The hands of a legged-with-policy embodiment (the G1 with Dex3 hands, spec ``g1_29dof_dex3``):
the simulated humanoid with its hand joints, and the hands' commands in the humanoid runtime.

- :func:`humanoid_for_spec`: the trained humanoid (``robot.G1``) with the spec's description file
  and its hand joints as PD-held joints (the spec's drives); the policy's 29 body joints, default
  pose and gains are unchanged, so the policy's observations stay those of training.
- :class:`HandCommands`: one command per hand and world, 0 (open) .. 1 (closed); the hand's
  joints get PD targets ``open + command * (closed - open)`` from the spec's end effector
  (a closing synergy; the fingers stop on the object they close on).

Shapes: N worlds, H hands, K = all hand joints (in arm order, each hand's in the spec's order).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from stages.embodiment.spec import EmbodimentError, EmbodimentSpec, EndEffectorKind
from stages.locomotion.robot import G1, HumanoidDescription, JointGains

HAND_ARMATURE = 1.0e-3
"""[kg m^2] armature of a hand joint whose spec drive gives none: the Dex3's finger links weigh
20-60 g, so kp = 3 N m/rad on the bare link inertia (about 2e-5 kg m^2) is unstable at 200 Hz
physics; the motors' reflected inertia (not published) makes it stable"""


def hand_arms(spec: EmbodimentSpec) -> tuple[str, ...]:
    """The arms of ``spec`` whose end effector is a hand with joints."""
    return tuple(a.name for a in spec.arms if a.end_effector
                 and spec.end_effectors[a.end_effector].kind == EndEffectorKind.HAND
                 and spec.end_effectors[a.end_effector].joints)


def humanoid_for_spec(spec: EmbodimentSpec, desc: HumanoidDescription = G1) -> HumanoidDescription:
    """The humanoid the engine simulates for ``spec``: ``desc`` (the G1 the policy was trained on)
    as it is when the spec has no hand joints, else with the spec's description file
    (example-robot-data's G1 with Dex3 hands: 29 + 14 joints) and the hand joints held by PD with
    the spec's drives (kp [N m/rad], kd [N m s/rad], armature [kg m^2] or ``HAND_ARMATURE``,
    effort limit or the hand's ``max_force`` [N m]). Raises EmbodimentError for a hand
    description the stack cannot build or a hand joint without a drive."""
    import dataclasses
    import re

    hand = spec.end_effector_joints
    if not hand:
        return desc
    if spec.description.format != "urdf" or spec.description.package != "example-robot-data":
        raise EmbodimentError(f"{spec.name}: the humanoid engine builds hands from example-robot-data URDFs "
                              f"only (description {spec.description.file})")
    drives = []
    for name in hand:
        drive = spec.drive_for(name)
        if drive is None:
            raise EmbodimentError(f"{spec.name}: no drive matches hand joint {name!r}")
        ee = next(e for e in spec.end_effectors.values() if name in e.joints)
        effort = drive.effort_limit or ee.max_force or 1.0
        gains = JointGains(drive.armature or HAND_ARMATURE, drive.kp, drive.kd, effort)
        drives.append((re.escape(name), gains))
    return dataclasses.replace(desc, name=f"{desc.name}_{spec.name}", source_file=spec.description.file,
                               num_joints=desc.num_joints + len(hand), arm_joints=desc.arm_joints + hand,
                               drives=desc.drives + tuple(drives))


class HandCommands:
    """The hand commands of N worlds (module docstring). ``index``: where the hand joints sit in
    the model (``runtime.index_worlds`` of ``names``), None without hands; ``pin_cols``: their
    Pinocchio configuration columns."""

    def __init__(self, spec: EmbodimentSpec, index: Any, pin_cols: np.ndarray, num_worlds: int,
                 device: torch.device) -> None:
        self.arms: tuple[str, ...] = hand_arms(spec)
        ees = [spec.end_effectors[spec.arm(a).end_effector] for a in self.arms]
        self.names: tuple[str, ...] = tuple(j for e in ees for j in e.joints)
        self.index, self.pin_cols, self.device = index, pin_cols, device
        self.open = np.concatenate([np.asarray(e.open, float) for e in ees]) if ees else np.zeros(0)
        self.closed = np.concatenate([np.asarray(e.closed, float) for e in ees]) if ees else np.zeros(0)
        ends = np.cumsum([len(e.joints) for e in ees], dtype=int)
        self._cols = {a: np.arange(e - len(ee.joints), e)
                      for a, e, ee in zip(self.arms, ends, ees, strict=True)}
        self.command = np.zeros((num_worlds, len(self.arms)))
        """(N, H) hand commands, 0 open .. 1 closed"""

    def set(self, arm: str, value: Any, worlds: Any = None) -> None:
        """Command ``value`` (0 open .. 1 closed; scalar or (K,)) for ``arm``'s hand in worlds (K,)
        (default: all); ValueError for an arm without a hand."""
        if arm not in self.arms:
            raise ValueError(f"arm {arm!r} has no hand (hands: {list(self.arms)})")
        sel = slice(None) if worlds is None else np.asarray(worlds, int)
        self.command[sel, self.arms.index(arm)] = np.clip(np.asarray(value, float), 0.0, 1.0)

    def targets(self) -> np.ndarray:
        """(N, K) joint targets [rad] of the commands."""
        out = np.empty((len(self.command), len(self.names)))
        for h, arm in enumerate(self.arms):
            c = self._cols[arm]
            out[:, c] = self.open[c] + self.command[:, h:h + 1] * (self.closed[c] - self.open[c])
        return out

    def positions(self, joint_q: torch.Tensor) -> np.ndarray:
        """(N, K) measured hand joint positions [rad] from the state's ``joint_q`` (torch view)."""
        return joint_q[self.index.joint_q].detach().cpu().double().numpy()

    def write(self, joint_target_q: torch.Tensor) -> None:
        """The commands' targets into the control's ``joint_target_q`` (torch view)."""
        if self.names:
            joint_target_q[self.index.joint_q] = torch.as_tensor(self.targets(), dtype=joint_target_q.dtype,
                                                                 device=self.device)

    def reset(self, worlds: np.ndarray, views: list[tuple[torch.Tensor, torch.Tensor]],
              joint_target_q: torch.Tensor) -> None:
        """Worlds (K,) open: command 0, hand joints at the open pose and at rest in every
        (joint_q, joint_qd) view, targets open."""
        self.command[worlds] = 0.0
        if not self.names:
            return
        ids = torch.as_tensor(worlds, dtype=torch.long, device=self.device)
        for q, qd in views:
            q[self.index.joint_q[ids]] = torch.as_tensor(self.open, dtype=q.dtype, device=self.device)
            qd[self.index.joint_qd[ids]] = 0.0
        joint_target_q[self.index.joint_q[ids]] = torch.as_tensor(self.open, dtype=joint_target_q.dtype,
                                                                  device=self.device)
