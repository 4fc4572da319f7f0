"""The legged-with-policy base of an embodiment spec: the humanoid runtime's configuration from a
spec (``[base] kind = "legged_policy"``, ``policy`` = a policy shipped in
``stages/locomotion/policies`` by folder name, or a path), and each control step's dataset frame
in the spec's state and action layout (``stages.embodiment.layout``): arm joints, end-effector
poses in the base frame, base pose, base velocity command, mode.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from stages.embodiment.spec import BaseKind, EmbodimentError, EmbodimentSpec
from stages.locomotion.runtime import DEFAULT_POLICY, LeggedRuntimeConfig

POLICIES = DEFAULT_POLICY.parent
"""folder of the shipped policies"""


def policy_folder(ref: str) -> Path:
    """The exported policy folder that ``ref`` names: a shipped policy's folder name, or a path."""
    for candidate in (POLICIES / ref, Path(ref)):
        if (candidate / "policy.pt").is_file() and (candidate / "policy.json").is_file():
            return candidate
    raise FileNotFoundError(f"no exported policy (policy.pt + policy.json) named {ref!r} in {POLICIES} or at {ref}")


def runtime_config_for(spec: EmbodimentSpec, **options: Any) -> LeggedRuntimeConfig:
    """The runtime configuration of a legged-with-policy spec; ``options``: other fields of
    :class:`LeggedRuntimeConfig` (device, CLIK ...). Raises EmbodimentError for another base kind
    or a spec without a policy."""
    if spec.base.kind != BaseKind.LEGGED_POLICY:
        raise EmbodimentError(f"{spec.name}: base kind {spec.base.kind.value!r} has no locomotion policy")
    if not spec.base.policy:
        raise EmbodimentError(f"{spec.name}: no locomotion policy is shipped for it ([base] policy is empty)")
    try:
        folder = policy_folder(spec.base.policy)
    except FileNotFoundError as e:
        raise EmbodimentError(f"{spec.name}: {e}") from None
    return LeggedRuntimeConfig(policy=str(folder), spec=spec.name, root_body=spec.base.root_link, **options)


def _pose7(m: np.ndarray) -> np.ndarray:
    """(K, 4, 4) poses -> (K, 7): x, y, z [m], quaternion w, x, y, z."""
    from scipy.spatial.transform import Rotation

    xyzw = Rotation.from_matrix(m[:, :3, :3]).as_quat()
    return np.concatenate([m[:, :3, 3], xyzw[:, 3:4], xyzw[:, :3]], axis=1)


def frame_vectors(runtime: Any, state: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(observation.state (N, S), action (N, A))`` of every world now, in the order of
    ``stages.embodiment.layout.state_names`` / ``action_names`` of the runtime's spec: measured arm
    joints [rad], end-effector poses (base frame) and base pose (x, y [m], yaw [rad], world);
    commanded arm joint targets, the end-effector poses they give (base frame), the base velocity
    command (vx, vy [m/s], v_theta [rad/s]; zero in manipulation mode), each hand's command (0
    open .. 1 closed; ``runtime.hands``) and the mode. End effectors of kind "none" (the G1's rubber
    hands) have no command."""
    from stages.embodiment.spec import EndEffectorKind

    spec = runtime.spec
    hands = runtime.hands
    commanded = [a.name for a in spec.arms if a.end_effector
                 and spec.end_effectors[a.end_effector].kind != EndEffectorKind.NONE]
    if any(a not in hands.arms for a in commanded):
        raise EmbodimentError(f"{spec.name}: the humanoid runtime commands hands only (end effectors of "
                              f"arms {[a for a in commanded if a not in hands.arms]} are not hands)")
    root, q = runtime._host_state(state)
    cmd_q = q.copy()
    arms = [a.name for a in spec.arms]
    for a in arms:
        cols = runtime._arm_cols[a]
        cmd_q[:, runtime._pin_cols[cols]] = runtime.arm_q[:, cols]
    yaw = np.arctan2(root[:, 1, 0], root[:, 0, 0])
    st = [q[:, runtime._pin_cols[runtime._arm_cols[a]]] for a in arms]
    st += [_pose7(runtime.clik.ee_pose(q, a)) for a in arms]
    st.append(np.stack([root[:, 0, 3], root[:, 1, 3], yaw], axis=1))
    act = [runtime.arm_q[:, runtime._arm_cols[a]] for a in arms]
    act += [_pose7(runtime.clik.ee_pose(cmd_q, a)) for a in arms]
    act.append(runtime.effective_commands().detach().cpu().double().numpy())
    act += [hands.command[:, hands.arms.index(a), None] for a in commanded]
    act.append(runtime.mode.detach().cpu().double().numpy()[:, None])
    return np.concatenate(st, axis=1), np.concatenate(act, axis=1)
