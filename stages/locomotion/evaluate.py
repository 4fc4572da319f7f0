"""Evaluation of a G1 velocity policy: velocity-tracking error and falls over R rollouts of T seconds.

Each world is one rollout: it draws one command uniformly in the configured ranges (no standing
draws) and holds it for the whole rollout, while the arms move to random targets every 150 control
steps (as in training). Errors are measured after a settling time at the start of each rollout:
planar speed error |v_cmd - v_xy| [m/s] and yaw-rate error |w_cmd - w_z| [rad/s], averaged over
time and rollouts. A rollout that falls counts one fall and stops contributing samples.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import torch

from stages.locomotion.config import EnvConfig, Randomization


@dataclass(frozen=True, kw_only=True)
class EvalConfig:
    env: EnvConfig = field(default_factory=lambda: EnvConfig(num_worlds=100))
    policy: str = "stages/locomotion/policies/g1_velocity"
    """exported policy folder or ``policy.pt``"""
    seconds: float = 20.0
    """rollout length [s]"""
    settle_s: float = 1.0
    """time after the start that is not measured [s]"""


def evaluate(cfg: EvalConfig, *, act: Any = None) -> dict[str, Any]:
    """Run ``cfg.env.num_worlds`` rollouts; ``act(obs) -> actions`` overrides the exported policy."""
    from stages.locomotion.env import G1VelocityEnv
    from stages.locomotion.policy import PolicyRuntime

    env_cfg = replace(cfg.env, episode_length_s=cfg.seconds + 1.0,
                      randomization=replace(cfg.env.randomization, push_velocity=0.0, obs_noise=False),
                      commands=replace(cfg.env.commands, standing_fraction=0.0))
    env = G1VelocityEnv(env_cfg)
    if act is None:
        runtime = PolicyRuntime.load(cfg.policy, device=str(env.device))
        act = runtime.act
    c = env_cfg.commands
    g = env.gen
    n = env.num_worlds
    env.commands[:] = torch.stack([
        c.vx[0] + (c.vx[1] - c.vx[0]) * torch.rand(n, generator=g, device=env.device),
        c.vy[0] + (c.vy[1] - c.vy[0]) * torch.rand(n, generator=g, device=env.device),
        c.yaw_rate[0] + (c.yaw_rate[1] - c.yaw_rate[0]) * torch.rand(n, generator=g, device=env.device)], dim=1)
    env.fixed_commands = True
    env.obs, env.critic_obs = env._observations()
    steps = int(round(cfg.seconds / env_cfg.control_dt))
    settle = int(round(cfg.settle_s / env_cfg.control_dt))
    alive = torch.ones(n, dtype=torch.bool, device=env.device)
    lin_sum = torch.zeros(n, device=env.device)
    ang_sum = torch.zeros(n, device=env.device)
    count = torch.zeros(n, device=env.device)
    commands = env.commands.clone()
    obs = env.obs
    for k in range(steps):
        obs, _, _, fell, _ = env.step(act(obs))
        alive &= ~fell
        if k >= settle:
            lin_b, ang_b, _ = env.base_velocities()
            m = alive.float()
            lin_sum += m * torch.linalg.norm(commands[:, :2] - lin_b[:, :2], dim=1)
            ang_sum += m * (commands[:, 2] - ang_b[:, 2]).abs()
            count += m
    total = count.sum().clamp(min=1.0)
    return {
        "rollouts": n, "seconds": cfg.seconds, "device": str(env.device),
        "falls": int((~alive).sum()),
        "lin_vel_error_mps": float(lin_sum.sum() / total),
        "yaw_rate_error_radps": float(ang_sum.sum() / total),
        "per_rollout_lin_error_max_mps": float((lin_sum / count.clamp(min=1.0)).max()),
    }
