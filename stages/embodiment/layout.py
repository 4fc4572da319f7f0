"""State and action layout of an embodiment's frames (the paper's: arm joints, end-effector poses,
base pose, base velocity command, end-effector commands, mode), as feature names.

- ``observation.state``: per arm its joint positions [rad], then per arm its end-effector pose
  (x, y, z [m], quaternion w, x, y, z) in the robot base frame, then the base pose (x, y [m],
  theta [rad]) in the world;
- ``action``: per arm its joint targets [rad], per arm its end-effector target pose, the base
  velocity command (vx, vy [m/s], vtheta [rad/s], base frame), one command per end effector
  (0 open .. 1 closed; a hand's joints follow its open -> closed synergy; none for kind "none"),
  and the mode (0 locomotion / 1 manipulation).
- ``hand_targets=True`` (teleoperation with retargeted dexterous hands, ``stages.teleop``): a hand
  end effector records its joints instead of its one command: the state ends with their positions
  [rad] and the action has their targets (``<joint>_target``) where the hand's command was.

One arm with one gripper gives exactly ``stages.dataset.schema.DatasetSpec``'s names (``arm_q0``,
``ee_x``, ..., ``gripper``, ``mode``); several arms prefix each arm's names with the arm's name
(``left_q0``, ``left_ee_x``, ``left_gripper``).
"""

from __future__ import annotations

from stages.embodiment.spec import EmbodimentSpec, EndEffectorKind

_POSE = ("x", "y", "z", "qw", "qx", "qy", "qz")


def _prefixes(spec: EmbodimentSpec) -> list[tuple[str, str]]:
    """(joint prefix, end-effector prefix) per arm."""
    if len(spec.arms) == 1:
        return [("arm_", "")]
    return [(f"{a.name}_", f"{a.name}_") for a in spec.arms]


def _hand_joints(spec: EmbodimentSpec, arm) -> tuple[str, ...]:
    """The joints of ``arm``'s end effector if it is a hand, else ()."""
    ee = spec.end_effectors.get(arm.end_effector) if arm.end_effector else None
    return tuple(ee.joints) if ee is not None and ee.kind == EndEffectorKind.HAND else ()


def state_names(spec: EmbodimentSpec, *, hand_targets: bool = False) -> list[str]:
    pre = _prefixes(spec)
    names = [f"{jp}q{i}" for (jp, _), a in zip(pre, spec.arms, strict=True) for i in range(len(a.joints))]
    names += [f"{ep}ee_{c}" for _, ep in pre for c in _POSE]
    names += ["base_x", "base_y", "base_theta"]
    return names + ([j for a in spec.arms for j in _hand_joints(spec, a)] if hand_targets else [])


def action_names(spec: EmbodimentSpec, *, hand_targets: bool = False) -> list[str]:
    pre = _prefixes(spec)
    names = [f"{jp}q{i}_target" for (jp, _), a in zip(pre, spec.arms, strict=True) for i in range(len(a.joints))]
    names += [f"{ep}ee_{c}_target" for _, ep in pre for c in _POSE]
    names += ["base_vx", "base_vy", "base_vtheta"]
    for (_, ep), a in zip(pre, spec.arms, strict=True):
        if hand_targets and _hand_joints(spec, a):
            names += [f"{j}_target" for j in _hand_joints(spec, a)]
        elif a.end_effector and spec.end_effectors[a.end_effector].kind != EndEffectorKind.NONE:
            names.append(f"{ep}gripper")
    return names + ["mode"]
