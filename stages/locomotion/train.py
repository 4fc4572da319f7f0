"""PPO training of the G1 velocity policy with rsl-rl-lib, resumable from checkpoints.

``train(cfg)`` builds the batched environment, wraps it as an rsl-rl ``VecEnv`` (torch tensors on
the device, shared with Newton's Warp arrays), resumes from the newest ``model_<iter>.pt`` in
``cfg.checkpoint_dir`` and appends one row per PPO iteration to ``curve.csv`` there (iteration,
wall time [s], mean reward per step, mean episode return and length, falls, per-term means).
"""

from __future__ import annotations

import csv
import json
import logging
import math
import re
import time
from pathlib import Path
from typing import Any

import torch

from stages.locomotion.config import TrainConfig, to_dict
from stages.locomotion.env import G1VelocityEnv

log = logging.getLogger(__name__)

CURVE_FIELDS = ("iteration", "wall_s", "iter_s", "reward_per_step", "episode_return", "episode_length", "episodes",
                "falls", "action_std", "term_track_lin_vel", "term_track_ang_vel", "term_posture",
                "term_joint_limits", "term_action_rate", "term_lin_vel_z", "term_ang_vel_xy", "term_termination",
                "term_foot_clearance", "terrain_level")


def _vec_env_class() -> type:
    from rsl_rl.env import VecEnv
    from tensordict import TensorDict

    class RslVecEnv(VecEnv):
        """rsl-rl view of a ``G1VelocityEnv``: observation groups ``policy`` (noisy) and ``critic`` (clean)."""

        def __init__(self, env: G1VelocityEnv) -> None:
            self.env = env
            self.num_envs = env.num_worlds
            self.num_actions = env.num_actions
            self.max_episode_length = env.max_episode_length
            self.device = env.device
            self.cfg = to_dict(env.cfg)

        @property
        def episode_length_buf(self) -> torch.Tensor:  # type: ignore[override]
            return self.env.episode_length_buf

        @episode_length_buf.setter
        def episode_length_buf(self, value: torch.Tensor) -> None:
            self.env.episode_length_buf.copy_(value)

        def _td(self, obs: torch.Tensor, critic: torch.Tensor) -> Any:
            return TensorDict({"policy": obs, "critic": critic}, batch_size=[self.num_envs], device=self.device)

        def get_observations(self) -> Any:
            return self._td(self.env.obs, self.env.critic_obs)

        def step(self, actions: torch.Tensor) -> tuple[Any, torch.Tensor, torch.Tensor, dict]:
            obs, critic, reward, fell, timed_out = self.env.step(actions)
            dones = (fell | timed_out).long()
            return self._td(obs, critic), reward, dones, {"time_outs": timed_out}

    return RslVecEnv


def runner_config(cfg: TrainConfig) -> dict[str, Any]:
    """The rsl-rl OnPolicyRunner configuration dict of a training config."""
    p = cfg.ppo
    model = {"class_name": "MLPModel", "hidden_dims": list(p.hidden_dims), "activation": "elu",
             "obs_normalization": False}
    return {
        "num_steps_per_env": p.num_steps_per_env, "save_interval": 10**9, "check_for_nan": False,
        "obs_groups": {"actor": ["policy"], "critic": ["critic"]},
        "actor": {**model, "distribution_cfg": {"class_name": "GaussianDistribution", "init_std": p.init_noise_std}},
        "critic": dict(model),
        "algorithm": {"class_name": "PPO", "value_loss_coef": 1.0, "use_clipped_value_loss": True,
                      "clip_param": p.clip_param, "entropy_coef": p.entropy_coef,
                      "num_learning_epochs": p.num_learning_epochs, "num_mini_batches": p.num_mini_batches,
                      "learning_rate": p.learning_rate, "schedule": "adaptive", "gamma": p.gamma, "lam": p.lam,
                      "desired_kl": p.desired_kl, "max_grad_norm": p.max_grad_norm},
    }


def latest_checkpoint(directory: Path) -> Path | None:
    """The ``model_<iter>.pt`` with the highest iteration in ``directory``, or None."""
    found = [(int(m.group(1)), p) for p in directory.glob("model_*.pt") if (m := re.fullmatch(r"model_(\d+)\.pt", p.name))]
    return max(found)[1] if found else None


def make_runner(cfg: TrainConfig, env: G1VelocityEnv) -> Any:
    """An rsl-rl OnPolicyRunner over the environment (no tensorboard: the CSV curve is the log)."""
    import contextlib
    import io

    from rsl_rl.runners import OnPolicyRunner

    torch.manual_seed(cfg.env.seed)
    with contextlib.redirect_stdout(io.StringIO()):  # rsl-rl prints the model summaries
        return OnPolicyRunner(_vec_env_class()(env), runner_config(cfg), log_dir=None, device=str(env.device))


def _save(runner: Any, cfg: TrainConfig, directory: Path, iteration: int) -> Path:
    path = directory / f"model_{iteration}.pt"
    tmp = path.with_suffix(".tmp")
    runner.current_learning_iteration = iteration
    runner.save(str(tmp), infos={"config": to_dict(cfg)})
    tmp.replace(path)
    older = sorted((int(m.group(1)), p) for p in directory.glob("model_*.pt")
                   if (m := re.fullmatch(r"model_(\d+)\.pt", p.name)) and int(m.group(1)) < iteration)
    for _, stale in older[:-1]:  # keep this checkpoint and the one before it
        stale.unlink()
    return path


def _seed_from(source: Path, directory: Path) -> Path:
    """Copy checkpoint ``source`` into ``directory`` as ``model_<iter>.pt`` (and the ``curve.csv``
    beside it when ``directory`` has none); returns the copy."""
    import shutil

    if not source.is_file():
        raise FileNotFoundError(f"{source}: no such checkpoint (init_from)")
    iteration = int(torch.load(source, map_location="cpu", weights_only=False)["iter"])
    target = directory / f"model_{iteration}.pt"
    shutil.copyfile(source, target)
    curve = source.parent / "curve.csv"
    if curve.is_file() and not (directory / "curve.csv").exists():
        shutil.copyfile(curve, directory / "curve.csv")
    log.info("initialised from %s (iteration %d)", source, iteration)
    return target


def train(cfg: TrainConfig, *, progress: Any = None, stop: Any = None) -> dict[str, Any]:
    """Run ``cfg.iterations`` PPO iterations (or until ``cfg.max_wall_s``); returns a summary dict.

    ``progress(row)`` is called with each curve row (a dict of CURVE_FIELDS) when given; ``stop()``
    returning True ends the run after the current iteration (a checkpoint is written either way).
    """
    directory = Path(cfg.checkpoint_dir)
    directory.mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    env = G1VelocityEnv(cfg.env)
    runner = make_runner(cfg, env)
    start_it = 0
    ckpt = latest_checkpoint(directory) if cfg.resume else None
    if ckpt is None and cfg.init_from:
        ckpt = _seed_from(Path(cfg.init_from), directory)
    if ckpt is not None:
        runner.load(str(ckpt), map_location=str(env.device))
        start_it = int(runner.current_learning_iteration)
        log.info("resumed from %s (iteration %d)", ckpt, start_it)
    (directory / "train_config.json").write_text(json.dumps(to_dict(cfg), indent=2))
    setup_s = time.time() - t0
    curve_path = directory / "curve.csv"
    new_file = not curve_path.exists() or ckpt is None
    wall_before = 0.0
    if not new_file:
        rows = list(csv.DictReader(curve_path.open()))
        rows = [r for r in rows if int(r["iteration"]) <= start_it]  # drop rows past the checkpoint
        wall_before = float(rows[-1]["wall_s"]) if rows else 0.0
        with curve_path.open("w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=CURVE_FIELDS)
            w.writeheader()
            w.writerows({k: r.get(k, "") for k in CURVE_FIELDS} for r in rows)
    it = start_it
    t_train = time.time()
    with curve_path.open("w" if new_file else "a", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=CURVE_FIELDS)
        if new_file:
            writer.writeheader()
        first = True
        while it < start_it + cfg.iterations:
            if (cfg.max_wall_s and time.time() - t0 > cfg.max_wall_s) or (stop is not None and stop()):
                break
            t_it = time.time()
            runner.current_learning_iteration = it
            runner.learn(1, init_at_random_ep_len=first and ckpt is None)
            first = False
            it += 1
            row = {"iteration": it, "iter_s": round(time.time() - t_it, 4),
                   "wall_s": round(wall_before + time.time() - t_train, 2),
                   "action_std": float(runner.alg.get_policy().output_std.mean())}
            row.update({k: (round(v, 6) if isinstance(v, float) and math.isfinite(v) else v)
                        for k, v in env.metrics.pop().items()})
            if env.terrain is not None:
                row["terrain_level"] = round(env.terrain.mean_level(), 3)
            writer.writerow({k: row.get(k, "") for k in CURVE_FIELDS})
            f.flush()
            if progress is not None:
                progress(row)
            if it % cfg.save_every == 0:
                _save(runner, cfg, directory, it)
    last = _save(runner, cfg, directory, it)
    return {"iterations_done": it - start_it, "iteration": it, "checkpoint": str(last), "setup_s": round(setup_s, 1),
            "train_s": round(time.time() - t_train, 1), "num_worlds": cfg.env.num_worlds, "device": cfg.env.device}
