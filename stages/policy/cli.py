"""``agentworld train-policy`` and ``agentworld eval``: lerobot policies on our datasets (issue 17).

Each ``*_main(argv) -> int`` parses its own arguments (registered in ``stages.commands``). The
console shows our lines only; third-party output goes to ``OUT/train.log`` (lerobot-train's) or
``OUT/eval.log`` (everything, each distinct message once).
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import time
from pathlib import Path


def _ints(text: str) -> tuple[int, ...]:
    """"1,2,5-7" -> (1, 2, 5, 6, 7)."""
    out: list[int] = []
    for part in text.split(","):
        part = part.strip()
        if "-" in part[1:]:
            a, b = part.split("-", 1) if not part.startswith("-") else (part, part)
            out += range(int(a), int(b) + 1)
        elif part:
            out.append(int(part))
    return tuple(out)


def camera_list(text: str | None) -> tuple[str, ...] | None:
    """``--cameras``: None (all), "none" or "" (no camera), or comma-separated names."""
    if text is None:
        return None
    return () if text.strip() in ("", "none") else tuple(c.strip() for c in text.split(",") if c.strip())


def train_main(argv: list[str]) -> int:
    from .train import POLICIES, TrainConfig, train_policy

    p = argparse.ArgumentParser(prog="agentworld train-policy",
                                description="train ACT or Diffusion Policy on a dataset with lerobot-train")
    p.add_argument("dataset", type=Path, help="a LeRobot dataset folder written by the project")
    p.add_argument("--policy", choices=POLICIES, required=True)
    p.add_argument("--out", type=Path, required=True, help="output folder (must not exist)")
    p.add_argument("--steps", type=int, default=100_000)
    p.add_argument("--batch-size", type=int, default=16)
    p.add_argument("--chunk-size", type=int, default=20, help="ACT's action chunk (20 basic, 40 multistage tasks)")
    p.add_argument("--no-ensemble", action="store_true", help="ACT without temporal ensembling")
    p.add_argument("--device", default="cuda")
    p.add_argument("--seed", type=int, default=1000)
    p.add_argument("--num-workers", type=int, default=4)
    p.add_argument("--log-freq", type=int, default=100)
    p.add_argument("--save-freq", type=int, default=20_000)
    p.add_argument("--max-seconds", type=float, default=None,
                   help="stop after this wall time [s], saving the step reached (default: all --steps)")
    p.add_argument("--frame-cache", type=Path, default=None,
                   help="decode the RGB videos once into this folder and train from it (shared by runs on one dataset)")
    p.add_argument("--cameras", default=None, metavar="LIST",
                   help="the dataset's RGB cameras the policy takes, comma-separated, 'none' for none (state and "
                        "environment state only); default all")
    p.add_argument("--init", type=Path, default=None,
                   help="start from this checkpoint's weights (same policy; pretrained_model or train-policy folder)")
    p.add_argument("--lerobot-arg", action="append", default=[], metavar="--KEY=VALUE",
                   help="a further lerobot-train argument (repeatable), e.g. --lerobot-arg=--policy.dim_model=256")
    p.add_argument("--lerobot-frames", action="store_true",
                   help="read samples through lerobot's own dataset reads (default: from columns held in memory, "
                        "the same samples, faster)")
    p.add_argument("--state-drop", default="", metavar="LIST",
                   help="observation.state entries the policy does not take, comma-separated (e.g. "
                        "base_x,base_y,base_theta: the base pose in the world); trains on a state view in OUT/dataset")
    a = p.parse_args(argv)
    try:
        cfg = TrainConfig(policy=a.policy, dataset=a.dataset, out=a.out, steps=a.steps, batch_size=a.batch_size,
                          chunk_size=a.chunk_size, temporal_ensemble=None if a.no_ensemble else 0.01,
                          device=a.device, seed=a.seed, num_workers=a.num_workers, log_freq=a.log_freq,
                          save_freq=a.save_freq, extra_args=tuple(a.lerobot_arg), max_seconds=a.max_seconds,
                          frame_cache=a.frame_cache, init=a.init, cameras=camera_list(a.cameras),
                          state_drop=tuple(n.strip() for n in a.state_drop.split(",") if n.strip()),
                          memory_frames=not a.lerobot_frames)
        print(f"train-policy: {a.policy} on {a.dataset} ({a.steps} steps, {a.device}); log {a.out / 'train.log'}",
              flush=True)
        res = train_policy(cfg)
    except (ValueError, FileExistsError, FileNotFoundError, RuntimeError) as e:
        print(f"agentworld train-policy: {e}", file=sys.stderr)
        return 2
    print(f"train-policy: {res.steps} steps{' (stopped at --max-seconds)' if res.stopped else ''} in "
          f"{res.wall_seconds:.0f} s wall, last loss {res.last_loss}; "
          f"checkpoint {res.checkpoint}; curve {res.curve_png}")
    return 0


def _eval_logging(out: Path, verbose: bool):
    """Everything to ``out/eval.log``; the console (returned) shows our warnings and the result."""
    from pipeline._src.chatter import DedupFilter, capture_process_output

    os.environ.setdefault("TQDM_DISABLE", "1")
    out.mkdir(parents=True, exist_ok=True)
    root = logging.getLogger()
    root.setLevel(logging.INFO)
    fh = logging.FileHandler(out / "eval.log")
    fh.setFormatter(logging.Formatter("%(asctime)s %(name)s %(levelname)s %(message)s"))
    fh.addFilter(DedupFilter())
    root.addHandler(fh)
    sys.stdout.flush()
    console = os.fdopen(os.dup(1), "w", buffering=1)
    if not verbose:
        capture_process_output()
    return console


def eval_main(argv: list[str]) -> int:
    from .evaluate import EvalConfig, evaluate
    from .train import resolve_checkpoint

    p = argparse.ArgumentParser(prog="agentworld eval",
                                description="evaluate a lerobot policy closed-loop in held-out task kitchens")
    p.add_argument("checkpoint", type=Path, help="a pretrained_model folder, or a train-policy output folder")
    p.add_argument("--tasks", required=True, help="comma-separated basic tasks")
    p.add_argument("--scenes", default="101", help="kitchen world seeds, e.g. 101,102 or 101-110 (held out)")
    p.add_argument("--seeds", default="1000000", help="episode seeds, e.g. 1000000-1000049")
    p.add_argument("--worlds", type=int, default=4, help="engine worlds run together")
    p.add_argument("--device", default="cpu", help="cpu or cuda[:n] (simulation and policy)")
    p.add_argument("--max-seconds", type=float, default=None, help="episode time limit [s] (default: the task's)")
    p.add_argument("--videos", type=int, default=2, help="rollout videos per task")
    p.add_argument("--training-dataset", type=Path, default=None,
                   help="the training dataset (default: from the checkpoint's train_config.json)")
    p.add_argument("--allow-seen", action="store_true", help="run kitchens / seeds the training data holds")
    p.add_argument("--out", type=Path, required=True, help="output folder: eval.json, videos/, eval.log")
    p.add_argument("--work", type=Path, default=None, help="where kitchens are built (default OUT/.work; reused)")
    p.add_argument("--action-steps", type=int, default=None,
                   help="actions run from each predicted chunk (default: the checkpoint's; for ACT it turns "
                        "temporal ensembling off)")
    p.add_argument("--arm-command", choices=("joints", "ee"), default="joints",
                   help="the arm follows the action's joint targets, or its end-effector target (through CLIK)")
    p.add_argument("--ensemble-coeff", type=float, default=None,
                   help="ACT's temporal ensembling coefficient (default: the checkpoint's)")
    p.add_argument("--verbose", action="store_true")
    a = p.parse_args(argv)
    ckpt = resolve_checkpoint(a.checkpoint)
    try:
        cfg = EvalConfig(checkpoint=ckpt, tasks=tuple(t for t in a.tasks.split(",") if t), scenes=_ints(a.scenes),
                         seeds=_ints(a.seeds), worlds=a.worlds, device=a.device, max_seconds=a.max_seconds,
                         videos=a.videos, training_dataset=a.training_dataset, allow_seen=a.allow_seen,
                         action_steps=a.action_steps, ensemble_coeff=a.ensemble_coeff,
                         arm_command=a.arm_command)
    except ValueError as e:
        print(f"agentworld eval: {e}", file=sys.stderr)
        return 2
    console = _eval_logging(a.out, a.verbose)
    total, done, t0 = len(cfg.tasks) * len(cfg.seeds) * len(cfg.scenes), [0, 0], time.perf_counter()

    def progress(rec) -> None:  # one console line per finished episode (eval.log has the same)
        done[0] += 1
        done[1] += rec.success
        print(f"eval: [{done[0]}/{total}] {rec.task} seed {rec.seed} {rec.scene}: "
              f"{'success' if rec.success else 'failed ' + (rec.reason or '')} ({rec.sim_seconds:.1f} s simulated; "
              f"{done[1]} successes so far; {time.perf_counter() - t0:.0f} s)", file=console, flush=True)

    try:
        res = evaluate(cfg, a.out, work_dir=a.work, episode_listeners=[progress])
    except (ValueError, FileNotFoundError) as e:
        print(f"agentworld eval: {e}", file=console)
        return 2
    r = res.report
    for t, row in r["tasks"].items():
        print(f"{t:24s} {row['successes']}/{row['episodes']}  failures {json.dumps(row['failures'])}", file=console)
    print(f"eval: {r['overall']['successes']}/{r['overall']['episodes']} successes in {r['wall_seconds']:.0f} s; "
          f"report {a.out / 'eval.json'}", file=console)
    return 0
