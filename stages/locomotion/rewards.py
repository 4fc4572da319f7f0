"""Reward terms of the velocity-tracking task (mjlab's G1 velocity rewards), as torch functions.

Every term is a (N,) tensor per control step; ``weighted_sum`` multiplies each by its weight and the
control period [s] (mjlab's and IsaacLab's convention, so the PPO settings transfer).
"""

from __future__ import annotations

import torch

from stages.locomotion.config import RewardWeights

TERMS = ("track_lin_vel", "track_ang_vel", "posture", "joint_limits", "action_rate", "lin_vel_z", "ang_vel_xy",
         "termination", "foot_clearance")


def reward_terms(w: RewardWeights, *, lin_b: torch.Tensor, ang_b: torch.Tensor, commands: torch.Tensor,
                 joint_pos: torch.Tensor, default_pos: torch.Tensor, posture_std: torch.Tensor,
                 soft_lo: torch.Tensor, soft_hi: torch.Tensor, actions: torch.Tensor, prev_actions: torch.Tensor,
                 fell: torch.Tensor, planar_tracking: bool = False) -> dict[str, torch.Tensor]:
    """Unweighted terms, each (N,).

    lin_b, ang_b: (N, 3) base velocities in the body frame [m/s, rad/s]; commands (N, 3) (vx, vy, yaw rate);
    joint_pos (N, A) [rad] of the policy's joints with default_pos, posture_std, soft_lo, soft_hi (A,);
    actions, prev_actions (N, A); fell (N,) bool. ``planar_tracking`` (terrain): the linear tracking
    error leaves out the vertical velocity and the angular one the roll and pitch rates (legged_gym's
    terms; ``ang_vel_xy`` penalizes those instead). On stairs the base rises, sinks and pitches by
    design: with them in the kernel (mjlab's flat terms, roll and pitch rates of 1-2 rad^2/s^2 on a
    flight) the yaw-rate term saturates near 0 and no longer rewards turning.
    """
    lin_err = (commands[:, 0] - lin_b[:, 0]) ** 2 + (commands[:, 1] - lin_b[:, 1]) ** 2
    ang_err = (commands[:, 2] - ang_b[:, 2]) ** 2
    if not planar_tracking:
        lin_err = lin_err + lin_b[:, 2] ** 2
        ang_err = ang_err + ang_b[:, 0] ** 2 + ang_b[:, 1] ** 2
    std2 = w.tracking_std ** 2
    posture = torch.exp(-torch.mean(((joint_pos - default_pos) / posture_std) ** 2, dim=1))
    over = (soft_lo - joint_pos).clamp(min=0.0) + (joint_pos - soft_hi).clamp(min=0.0)
    return {
        "track_lin_vel": torch.exp(-lin_err / std2),
        "track_ang_vel": torch.exp(-ang_err / std2),
        "posture": posture,
        "joint_limits": over.sum(dim=1),
        "action_rate": ((actions - prev_actions) ** 2).sum(dim=1),
        "lin_vel_z": lin_b[:, 2] ** 2,
        "ang_vel_xy": (ang_b[:, :2] ** 2).sum(dim=1),
        "termination": fell.float(),
    }


def foot_clearance(height: torch.Tensor, speed: torch.Tensor, target: float) -> torch.Tensor:
    """sum over feet of max(target - height, 0) * speed, (N,): height (N, F) [m] of each sole over
    the terrain under it, speed (N, F) [m/s] its horizontal speed, target [m]."""
    return ((target - height).clamp(min=0.0) * speed).sum(dim=1)


def weighted_sum(w: RewardWeights, terms: dict[str, torch.Tensor], control_dt: float) -> torch.Tensor:
    """sum_k weight_k * term_k * control_dt, (N,)"""
    total = torch.zeros_like(terms["track_lin_vel"])
    for name in TERMS:
        weight = getattr(w, name)
        if weight != 0.0:
            total = total + weight * control_dt * terms[name]
    return total


class RewardMetrics:
    """Running sums on the device for the training log: per-term means, episode returns, falls.

    ``pop()`` reads them (one host sync) and starts over.
    """

    def __init__(self, n: int, device: torch.device) -> None:
        self.device = device
        self.episode_return = torch.zeros(n, device=device)
        self._zero()

    def _zero(self) -> None:
        z = lambda: torch.zeros((), device=self.device)  # noqa: E731
        self.term_sums = {name: z() for name in TERMS}
        self.reward_sum, self.steps = z(), 0
        self.done_return, self.done_length, self.dones, self.falls = z(), z(), z(), z()

    def add(self, terms: dict[str, torch.Tensor], reward: torch.Tensor, done: torch.Tensor, fell: torch.Tensor,
            episode_length: torch.Tensor) -> None:
        for name in TERMS:
            self.term_sums[name] += terms[name].mean()
        self.reward_sum += reward.mean()
        self.steps += 1
        self.episode_return += reward
        d = done.float()
        self.done_return += (self.episode_return * d).sum()
        self.done_length += (episode_length.float() * d).sum()
        self.dones += d.sum()
        self.falls += fell.float().sum()
        self.episode_return *= 1.0 - d

    def pop(self) -> dict[str, float]:
        steps = max(self.steps, 1)
        dones = float(self.dones)
        out = {"reward_per_step": float(self.reward_sum) / steps,
               "episode_return": float(self.done_return) / dones if dones else float("nan"),
               "episode_length": float(self.done_length) / dones if dones else float("nan"),
               "episodes": dones, "falls": float(self.falls)}
        out.update({f"term_{k}": float(v) / steps for k, v in self.term_sums.items()})
        self._zero()
        return out
