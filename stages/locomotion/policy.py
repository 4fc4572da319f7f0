"""Export of a trained humanoid (G1, H1) velocity policy (TorchScript + metadata) and its batched runtime.

An exported policy folder holds:
- ``policy.pt``: TorchScript module, observations (N, O) float32 -> actions (N, A) (deterministic mean)
- ``policy.json``: what the runtime needs: joint order, the policy's joints, default pose [rad],
  action scale [rad], PD gains, observation layout, control period [s], training iteration and seed
- ``train_config.json``, ``curve.csv`` and ``curve.png`` (reward curve) of the run it came from
- ``checkpoint.pt``: the rsl-rl checkpoint (actor, critic, optimizer) training resumes from
"""

from __future__ import annotations

import csv
import json
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch

OBS_LAYOUT = ("base_lin_vel_b[3] m/s", "base_ang_vel_b[3] rad/s", "projected_gravity[3]",
              "command[3] (vx m/s, vy m/s, yaw rate rad/s)", "joint_pos - default[29] rad", "joint_vel[29] rad/s",
              "last_action[A]")


def actor_from_state_dict(state: dict[str, torch.Tensor], num_obs: int, num_actions: int,
                          hidden_dims: tuple[int, ...]) -> Any:
    """The rsl-rl actor (MLPModel with Gaussian head) with a checkpoint's weights, on the CPU."""
    from rsl_rl.models import MLPModel
    from tensordict import TensorDict

    obs = TensorDict({"policy": torch.zeros(1, num_obs)}, batch_size=[1])
    actor = MLPModel(obs, {"actor": ["policy"]}, "actor", num_actions, hidden_dims=tuple(hidden_dims),
                     activation="elu", obs_normalization=False,
                     distribution_cfg={"class_name": "GaussianDistribution", "init_std": 1.0})
    actor.load_state_dict(state)
    return actor.eval()


def policy_metadata(env_cfg: Any, *, iteration: int) -> dict[str, Any]:
    """The runtime's metadata of a policy trained on ``env_cfg`` (an EnvConfig); ``humanoid`` is
    the robot's registry name (``stages.locomotion.humanoids``) the runtime and evaluation build."""
    from stages.locomotion.humanoids import humanoid

    desc = humanoid(env_cfg.robot)
    joints = desc.joints
    policy_joints = desc.leg_joints + (desc.waist_joints if env_cfg.use_waist else ())
    nj = len(joints)
    return {
        "robot": desc.label, "humanoid": desc.name,
        "iteration": iteration, "seed": env_cfg.seed,
        "control_dt": env_cfg.control_dt, "sim_dt": env_cfg.sim_dt, "decimation": env_cfg.decimation,
        "num_obs": 12 + 2 * nj + len(policy_joints), "num_actions": len(policy_joints),
        "obs_layout": [line.replace("[29]", f"[{nj}]") for line in OBS_LAYOUT],
        "policy_joints": list(policy_joints),
        "default_pos": {j: desc.default_pose.get(j, 0.0) for j in joints},
        "action_scale": {j: desc.joint_action_scale(j) for j in policy_joints},
        "stiffness": {j: desc.gains(j).stiffness for j in joints},
        "damping": {j: desc.gains(j).damping for j in joints},
        "command_ranges": {"vx": list(env_cfg.commands.vx), "vy": list(env_cfg.commands.vy),
                           "yaw_rate": list(env_cfg.commands.yaw_rate)},
    }


def policy_humanoid(folder_or_file: Path | str) -> str:
    """The humanoid an exported policy (folder or ``policy.pt``) or a training checkpoint was
    trained on (``policy.json``'s ``humanoid``, the checkpoint config's ``env.robot``; "g1" for
    files from before the H1)."""
    path = Path(folder_or_file)
    js = (path if path.is_dir() else path.parent) / "policy.json"
    if path.suffix == ".pt" and path.name != "policy.pt":
        data = torch.load(path, map_location="cpu", weights_only=False)
        return str(data.get("infos", {}).get("config", {}).get("env", {}).get("robot", "g1"))
    if not js.is_file():
        raise FileNotFoundError(f"{js}: no policy.json beside the policy")
    return str(json.loads(js.read_text()).get("humanoid", "g1"))


def export_policy(checkpoint: Path, out_dir: Path) -> list[Path]:
    """Write ``policy.pt`` and ``policy.json`` for a training checkpoint; returns the paths."""
    from stages.locomotion.config import train_config_from_dict

    data = torch.load(checkpoint, map_location="cpu", weights_only=False)
    cfg = train_config_from_dict(data["infos"]["config"])
    meta = policy_metadata(cfg.env, iteration=int(data["iter"]))
    actor = actor_from_state_dict(data["actor_state_dict"], meta["num_obs"], meta["num_actions"],
                                  cfg.ppo.hidden_dims)
    out_dir.mkdir(parents=True, exist_ok=True)
    scripted = torch.jit.script(actor.as_jit().cpu().eval())
    pt, js = out_dir / "policy.pt", out_dir / "policy.json"
    scripted.save(str(pt))
    js.write_text(json.dumps(meta, indent=2) + "\n")
    return [pt, js]


def plot_curve(csv_path: Path, png_path: Path, *, columns: tuple[str, ...] = (
        "reward_per_step", "term_track_lin_vel", "term_track_ang_vel")) -> Path:
    """Reward curve PNG (PIL, no plotting library): one panel per column against the iteration."""
    from PIL import Image, ImageDraw

    rows = list(csv.DictReader(csv_path.open()))
    w, h, pad = 900, 220, 48
    img = Image.new("RGB", (w, h * len(columns)), "white")
    draw = ImageDraw.Draw(img)
    its = [int(r["iteration"]) for r in rows]
    for k, col in enumerate(columns):
        ys = [float(r[col]) for r in rows if r.get(col) not in ("", "nan")]
        xs = [it for it, r in zip(its, rows) if r.get(col) not in ("", "nan")]
        top = k * h
        draw.rectangle([pad, top + 10, w - 10, top + h - 30], outline="black")
        if len(ys) >= 2:
            lo, hi = min(ys), max(ys)
            hi = hi if hi > lo else lo + 1.0
            x0, x1 = min(xs), max(xs) if max(xs) > min(xs) else min(xs) + 1
            pts = [(pad + (x - x0) / (x1 - x0) * (w - 10 - pad), top + h - 30 - (y - lo) / (hi - lo) * (h - 40))
                   for x, y in zip(xs, ys)]
            draw.line(pts, fill=(30, 90, 200), width=2)
            draw.text((pad + 4, top + 12), f"{col}  [{lo:.4g}, {hi:.4g}]", fill="black")
            draw.text((pad, top + h - 26), f"iteration {x0}", fill="black")
            draw.text((w - 140, top + h - 26), f"iteration {x1}", fill="black")
        else:
            draw.text((pad + 4, top + 12), f"{col}: too few points", fill="black")
    img.save(png_path)
    return png_path


def export_from_checkpoint_dir(directory: Path, out_dir: Path) -> list[Path]:
    """Export the newest checkpoint of a training directory with its config, curve CSV and PNG."""
    from stages.locomotion.train import latest_checkpoint

    ckpt = latest_checkpoint(directory)
    if ckpt is None:
        raise FileNotFoundError(f"no model_<iteration>.pt in {directory}")
    written = export_policy(ckpt, out_dir)
    for name in ("train_config.json", "curve.csv"):
        if (directory / name).exists():
            shutil.copyfile(directory / name, out_dir / name)
            written.append(out_dir / name)
    if (out_dir / "curve.csv").exists():
        written.append(plot_curve(out_dir / "curve.csv", out_dir / "curve.png"))
    if ckpt.resolve() != (out_dir / "checkpoint.pt").resolve():
        shutil.copyfile(ckpt, out_dir / "checkpoint.pt")
    written.append(out_dir / "checkpoint.pt")
    return written


@dataclass
class PolicyRuntime:
    """A loaded exported policy, batched over worlds on one device.

    ``act(obs)`` maps observations (N, O) to actions (N, A); ``joint_targets(actions)`` gives the PD
    position targets (N, A) [rad] of ``meta["policy_joints"]``.
    """

    module: torch.jit.ScriptModule
    meta: dict[str, Any]
    device: torch.device

    @classmethod
    def load(cls, folder_or_file: Path | str, device: str = "cpu") -> "PolicyRuntime":
        path = Path(folder_or_file)
        pt = path / "policy.pt" if path.is_dir() else path
        meta = json.loads(pt.with_name("policy.json").read_text())
        module = torch.jit.load(str(pt), map_location=device).eval()
        return cls(module, meta, torch.device(device))

    @torch.inference_mode()
    def act(self, obs: torch.Tensor) -> torch.Tensor:
        return self.module(obs.to(self.device, torch.float32))

    def joint_targets(self, actions: torch.Tensor) -> torch.Tensor:
        joints = self.meta["policy_joints"]
        default = torch.tensor([self.meta["default_pos"][j] for j in joints], device=actions.device)
        scale = torch.tensor([self.meta["action_scale"][j] for j in joints], device=actions.device)
        return default + scale * actions
