"""Evaluation through the humanoid runtime: velocity tracking, falls and hand tracking of N G1 worlds
walking on random commands while CLIK moves both hands to random reachable targets.

This is issue 13's evaluation run the way demonstrations will run the robot (the runtime's
observations, policy, CLIK and gravity feed-forward; no training noise, pushes or randomization):
each world draws one command uniformly in the ranges (vx, vy [m/s], yaw rate [rad/s]) and holds
it for the rollout; every ``arm_resample_s`` both hands get new targets in the base frame, the
forward kinematics of arm joints drawn within ``arm_range`` of the default pose (the training
distribution of the arm targets, clipped to the joint limits). Errors after ``settle_s``: planar
speed error |v_cmd - v_xy| [m/s] and yaw-rate error |w_cmd - w_z| [rad/s] in the base frame,
averaged over time and worlds; hand position error [m] from ``hand_settle_s`` after each draw. A
world whose pelvis falls under ``fall_height`` or tilts over ``fall_tilt_deg`` counts one fall and
stops contributing. Deterministic for a seed (numpy Generator).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass(frozen=True, kw_only=True)
class RuntimeEvalConfig:
    num_worlds: int = 8
    device: str = "cpu"
    seed: int = 0
    seconds: float = 20.0
    """rollout length [s]"""
    settle_s: float = 1.0
    """start of the velocity measurement [s]"""
    vx: tuple[float, float] = (-0.5, 1.0)
    """forward command range [m/s]"""
    vy: tuple[float, float] = (-0.5, 0.5)
    """lateral command range [m/s]"""
    yaw_rate: tuple[float, float] = (-1.0, 1.0)
    """yaw rate command range [rad/s]"""
    arm_resample_s: float = 3.0
    """time between hand target draws [s] (training: 150 control steps)"""
    arm_range: float = 0.6
    """half-width of the arm joints' draw around the default pose [rad] (training's)"""
    hand_settle_s: float = 1.5
    """time after a draw before the hand error is measured [s] (the CLIK goal travels at the
    runtime's ``ee_speed``, 0.3 m/s: a new target can be 0.4 m away)"""
    fall_height: float = 0.3
    """[m]"""
    fall_tilt_deg: float = 70.0
    """[deg]"""
    arms: bool = True
    """move the hands (else they hold the default pose)"""
    worlds: Any = field(default=None, repr=False)
    """an existing ``HumanoidWorlds`` to use (reset first), else one is built"""

    def __post_init__(self) -> None:
        problems = []
        if self.num_worlds < 1:
            problems.append(f"num_worlds must be positive, got {self.num_worlds}")
        if self.seconds <= self.settle_s:
            problems.append(f"seconds ({self.seconds}) must exceed settle_s ({self.settle_s})")
        if problems:
            raise ValueError("; ".join(problems))


def _hand_targets(rt: Any, arm: str, count: int, rng: np.random.Generator, half_width: float) -> np.ndarray:
    """Base-frame poses (count, 4, 4) of ``arm``'s end effector at arm joints drawn uniformly
    within ``half_width`` [rad] of the runtime's default pose, clipped to the joint limits."""
    a = rt.clik.arms[arm]
    q = np.zeros((count, rt.pin_model.nq))
    q[:, rt._pin_cols] = rt.default_q.cpu().numpy()
    mid = q[0, a.q_idx]
    q[:, a.q_idx] = np.clip(mid + rng.uniform(-half_width, half_width, (count, len(a.q_idx))), a.lower, a.upper)
    return rt.clik.ee_pose(q, arm)


def evaluate_runtime(cfg: RuntimeEvalConfig) -> dict[str, Any]:
    """Run ``cfg.num_worlds`` rollouts of ``cfg.seconds``; returns the figures (see the module docstring)."""
    import torch

    from stages.locomotion.runtime import HumanoidWorlds, HumanoidWorldsConfig, quat_rotate_inverse

    t0 = time.perf_counter()
    worlds = cfg.worlds or HumanoidWorlds(HumanoidWorldsConfig(num_worlds=cfg.num_worlds, device=cfg.device))
    rt = worlds.runtime
    n = rt.num_worlds
    rng = np.random.default_rng(cfg.seed)
    worlds.reset()
    cmd = np.stack([rng.uniform(*cfg.vx, n), rng.uniform(*cfg.vy, n), rng.uniform(*cfg.yaw_rate, n)], axis=1)
    rt.set_command(cmd)
    cmd_t = rt.commands.clone()
    steps = int(round(cfg.seconds / rt.control_dt))
    settle = int(round(cfg.settle_s / rt.control_dt))
    every = max(1, int(round(cfg.arm_resample_s / rt.control_dt)))
    hand_settle = int(round(cfg.hand_settle_s / rt.control_dt))
    alive = torch.ones(n, dtype=torch.bool, device=rt.device)
    lin_sum, ang_sum, count = (torch.zeros(n, device=rt.device) for _ in range(3))
    hand_err: list[np.ndarray] = []
    cos_tilt = math.cos(math.radians(cfg.fall_tilt_deg))
    build_s = time.perf_counter() - t0
    for k in range(steps):
        if cfg.arms and k % every == 0:
            for arm in rt.arm_names:
                rt.set_ee_target(arm, _hand_targets(rt, arm, n, rng, cfg.arm_range), frame="base")
        worlds.step()
        pos, quat, lin, ang = rt.base_state(worlds.state)
        lin_b, ang_b = quat_rotate_inverse(quat, lin), quat_rotate_inverse(quat, ang)
        grav_z = quat_rotate_inverse(quat, torch.tensor([[0.0, 0.0, -1.0]], device=rt.device).expand_as(lin))[:, 2]
        fell = (pos[:, 2] < cfg.fall_height) | (grav_z > -cos_tilt) | ~torch.isfinite(pos).all(dim=1)
        alive &= ~fell
        if k >= settle:
            m = alive.float()
            lin_sum += m * torch.linalg.norm(cmd_t[:, :2] - lin_b[:, :2], dim=1)
            ang_sum += m * (cmd_t[:, 2] - ang_b[:, 2]).abs()
            count += m
        if cfg.arms and k % every >= hand_settle:
            root, q = rt._host_state(worlds.state)
            ok = alive.cpu().numpy()
            for arm in rt.arm_names:
                got = rt.clik.ee_pose(q[ok], arm)
                hand_err.append(np.linalg.norm(got[:, :3, 3] - rt.ee_targets[arm][ok, :3, 3], axis=1))
    total = count.sum().clamp(min=1.0)
    sim_s = time.perf_counter() - t0 - build_s
    hands = np.concatenate(hand_err) if hand_err else np.zeros(0)
    return {
        "rollouts": n, "seconds": cfg.seconds, "device": str(rt.device), "seed": cfg.seed,
        "falls": int((~alive).sum()),
        "lin_vel_error_mps": round(float(lin_sum.sum() / total), 4),
        "yaw_rate_error_radps": round(float(ang_sum.sum() / total), 4),
        "per_rollout_lin_error_max_mps": round(float((lin_sum / count.clamp(min=1.0)).max()), 4),
        "hand_error_mean_m": round(float(hands.mean()), 4) if len(hands) else None,
        "hand_error_p95_m": round(float(np.percentile(hands, 95)), 4) if len(hands) else None,
        "build_s": round(build_s, 1), "sim_s": round(sim_s, 1),
        "realtime_factor": round(cfg.seconds * n / max(sim_s, 1e-9), 2),
    }
