"""``agentworld loco-train`` / ``loco-eval`` / ``loco-export``: the humanoid (G1, H1) velocity policies'
commands.

Each ``*_main(argv) -> int`` parses its own arguments (registered in ``stages.commands``). Logs go to
``<checkpoint dir>/locomotion.log``; the console gets one line per progress report.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from pathlib import Path

from stages.locomotion.config import (ROBOT_NAMES, EnvConfig, PPOConfig, Randomization, RewardWeights, TerrainConfig,
                                      TrainConfig)

DEFAULT_DIR = "out/locomotion/g1_velocity"


def _quiet_logs(directory: Path) -> None:
    directory.mkdir(parents=True, exist_ok=True)
    handler = logging.FileHandler(directory / "locomotion.log")
    handler.setFormatter(logging.Formatter("%(asctime)s %(name)s %(levelname)s %(message)s"))
    root = logging.getLogger()
    root.addHandler(handler)
    root.setLevel(logging.INFO)
    import warnings
    warnings.filterwarnings("ignore", category=UserWarning)


def _env_args(p: argparse.ArgumentParser, *, worlds: int) -> None:
    p.add_argument("--num-worlds", type=int, default=worlds)
    p.add_argument("--device", default="cuda:0", help="cuda:0 or cpu")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--no-graph", action="store_true", help="no CUDA graph capture of the physics step")


def _report(result: dict, json_path: str) -> None:
    """Print ``result`` as JSON and also write it to ``json_path`` when one is given."""
    text = json.dumps(result, indent=2)
    print(text)
    if json_path:
        Path(json_path).write_text(text + "\n")


def train_main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="agentworld loco-train",
                                description="train a humanoid's (G1, H1) velocity-tracking policy with PPO; "
                                            "resumes from the "
                                            "latest checkpoint in --checkpoint-dir")
    _env_args(p, worlds=4096)
    p.add_argument("--robot", default="g1", choices=ROBOT_NAMES, help="the humanoid to train")
    p.add_argument("--iterations", type=int, default=1000, help="PPO iterations to add in this run")
    p.add_argument("--max-wall-s", type=float, default=0.0, help="stop after this many seconds (0: no limit)")
    p.add_argument("--save-every", type=int, default=100)
    p.add_argument("--checkpoint-dir", default="",
                   help=f"default {DEFAULT_DIR} (out/locomotion/<robot>_velocity)")
    p.add_argument("--no-resume", action="store_true")
    p.add_argument("--print-every", type=int, default=25)
    p.add_argument("--init-from", default="", help="checkpoint to start from when --checkpoint-dir has none "
                                                   "(e.g. stages/locomotion/policies/g1_velocity/checkpoint.pt)")
    p.add_argument("--terrain", action="store_true",
                   help="per-world door thresholds and stairs with a level curriculum, swing-foot clearance reward")
    p.add_argument("--foot-clearance", type=float, default=-1.0, help="clearance reward weight with --terrain")
    p.add_argument("--ang-vel-xy", type=float, default=-0.05,
                   help="roll/pitch rate penalty weight with --terrain (legged_gym's; the yaw-rate kernel "
                        "leaves them out there)")
    p.add_argument("--arm-reach", action="store_true", help="arm targets over the wide reach ranges "
                                                            "(counter-height reaching) instead of +-0.6 rad")
    p.add_argument("--track-lin-vel", type=float, default=1.0, help="linear velocity tracking reward weight")
    p.add_argument("--track-ang-vel", type=float, default=1.0, help="yaw rate tracking reward weight")
    p.add_argument("--tracking-std", type=float, default=0.5,
                   help="std of the tracking reward kernels [m/s, rad/s]: smaller rewards small errors' removal more")
    p.add_argument("--terrain-kinds", default="0.4,0.2,0.4",
                   help="shares of flat / threshold / stairs worlds with --terrain")
    a = p.parse_args(argv)
    try:
        kinds = tuple(float(x) for x in a.terrain_kinds.split(","))
    except ValueError:
        p.error(f"--terrain-kinds must be 3 comma-separated numbers, got {a.terrain_kinds!r}")
    a.checkpoint_dir = a.checkpoint_dir or f"out/locomotion/{a.robot}_velocity"
    env = EnvConfig(robot=a.robot, num_worlds=a.num_worlds, device=a.device, seed=a.seed,
                    cuda_graph=not a.no_graph,
                    terrain=TerrainConfig(enabled=a.terrain, kinds=kinds),
                    rewards=RewardWeights(track_lin_vel=a.track_lin_vel, track_ang_vel=a.track_ang_vel,
                                          tracking_std=a.tracking_std,
                                          foot_clearance=a.foot_clearance if a.terrain else 0.0,
                                          ang_vel_xy=a.ang_vel_xy if a.terrain else 0.0),
                    randomization=Randomization(arm_reach=a.arm_reach))
    cfg = TrainConfig(env=env, ppo=PPOConfig(), iterations=a.iterations, max_wall_s=a.max_wall_s,
                      save_every=a.save_every, checkpoint_dir=a.checkpoint_dir, resume=not a.no_resume,
                      init_from=a.init_from)
    _quiet_logs(Path(a.checkpoint_dir))
    from stages.locomotion.train import train

    def progress(row: dict) -> None:
        if row["iteration"] % a.print_every == 0:
            print(f"it {row['iteration']:5d}  {row['iter_s']:.3f} s/it  reward/step {row['reward_per_step']:+.4f}  "
                  f"return {row['episode_return']}  len {row['episode_length']}  falls {row['falls']:.0f}  "
                  f"lin {row['term_track_lin_vel']:.3f} ang {row['term_track_ang_vel']:.3f}  "
                  f"std {row['action_std']:.3f}"
                  + (f"  level {row['terrain_level']:.2f}" if "terrain_level" in row else ""), flush=True)

    import signal

    stopping: list[int] = []
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda signum, frame: stopping.append(signum))
    summary = train(cfg, progress=progress, stop=lambda: bool(stopping))
    print(json.dumps(summary), flush=True)
    return 0


def eval_main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="agentworld loco-eval",
                                description="evaluate a humanoid velocity policy (the robot comes from its "
                                            "policy.json): tracking error and falls over R rollouts")
    _env_args(p, worlds=100)
    p.add_argument("--policy", required=True, help="exported TorchScript policy (.pt) or a training checkpoint")
    p.add_argument("--seconds", type=float, default=20.0, help="length of each rollout [s]")
    p.add_argument("--json", default="", help="also write the result here")
    a = p.parse_args(argv)
    from stages.locomotion.evaluate import EvalConfig, evaluate
    from stages.locomotion.policy import policy_humanoid

    try:
        robot = policy_humanoid(a.policy)
    except FileNotFoundError as e:
        print(f"agentworld loco-eval: {e}", file=sys.stderr)
        return 2
    env = EnvConfig(robot=robot, num_worlds=a.num_worlds, device=a.device, seed=a.seed,
                    cuda_graph=not a.no_graph)
    t0 = time.time()
    result = evaluate(EvalConfig(env=env, policy=a.policy, seconds=a.seconds))
    result["wall_s"] = round(time.time() - t0, 1)
    _report(result, a.json)
    return 0


def runtime_main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="agentworld loco-runtime",
                                description="N G1 worlds walking on random commands through the humanoid runtime "
                                            "(trained policy, CLIK hands to random targets, gravity feed-forward): "
                                            "velocity tracking error, hand error and falls")
    p.add_argument("--num-worlds", type=int, default=8)
    p.add_argument("--device", default="cpu", help="cpu or cuda:0")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--seconds", type=float, default=20.0, help="length of each rollout [s]")
    p.add_argument("--no-arms", action="store_true", help="hands hold the default pose")
    p.add_argument("--json", default="", help="also write the result here")
    a = p.parse_args(argv)
    import warnings

    import warp as wp

    wp.config.log_level = wp.LOG_WARNING
    warnings.filterwarnings("ignore", category=DeprecationWarning)
    from stages.locomotion.runtime_eval import RuntimeEvalConfig, evaluate_runtime

    result = evaluate_runtime(RuntimeEvalConfig(num_worlds=a.num_worlds, device=a.device, seed=a.seed,
                                                seconds=a.seconds, arms=not a.no_arms))
    _report(result, a.json)
    return 0


def house_main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="agentworld loco-house",
                                description="a G1 walks through a doorway with a threshold and up the stairs of a "
                                            "generated two-floor house (trained policy through the humanoid runtime): "
                                            "success and falls per trial")
    p.add_argument("--device", default="cpu", help="cpu or cuda:0")
    p.add_argument("--seed", type=int, default=0, help="the house layout's seed")
    p.add_argument("--policy", default="stages/locomotion/policies/g1_velocity", help="exported policy folder")
    p.add_argument("--threshold", type=float, default=0.03, help="door threshold height [m]")
    p.add_argument("--timeout-s", type=float, default=25.0, help="time limit of each trial [s]")
    p.add_argument("--trials", default="door,stairs", help="comma-separated: door, stairs")
    p.add_argument("--json", default="", help="also write the result here")
    a = p.parse_args(argv)
    import warnings

    import warp as wp

    wp.config.quiet = True
    wp.config.log_level = wp.LOG_WARNING
    warnings.filterwarnings("ignore", category=DeprecationWarning)
    from stages.locomotion.house_eval import HouseEvalConfig, evaluate_house

    try:
        cfg = HouseEvalConfig(device=a.device, seed=a.seed, policy=a.policy, threshold_height=a.threshold,
                              timeout_s=a.timeout_s, trials=tuple(t for t in a.trials.split(",") if t))
    except ValueError as e:
        print(f"agentworld loco-house: {e}", file=sys.stderr)
        return 2
    if not (Path(a.policy) / "policy.pt").is_file() and not Path(a.policy).is_file():
        print(f"agentworld loco-house: {a.policy}: no exported policy (policy.pt) there", file=sys.stderr)
        return 2
    _report(evaluate_house(cfg), a.json)
    return 0


def export_main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="agentworld loco-export",
                                description="export a training checkpoint's policy as TorchScript with its metadata, "
                                            "training config, reward curve CSV and PNG")
    p.add_argument("--checkpoint-dir", default=DEFAULT_DIR)
    p.add_argument("--out", default="", help="default stages/locomotion/policies/<robot>_velocity (the "
                                             "checkpoint's robot)")
    a = p.parse_args(argv)
    from stages.locomotion.policy import export_from_checkpoint_dir, policy_humanoid
    from stages.locomotion.train import latest_checkpoint

    ckpt = latest_checkpoint(Path(a.checkpoint_dir))
    if ckpt is None:
        print(f"agentworld loco-export: {a.checkpoint_dir}: no model_<iteration>.pt there", file=sys.stderr)
        return 2
    out = a.out or f"stages/locomotion/policies/{policy_humanoid(ckpt)}_velocity"
    written = export_from_checkpoint_dir(Path(a.checkpoint_dir), Path(out))
    for path in written:
        print(path)
    return 0


if __name__ == "__main__":
    commands = {"train": train_main, "eval": eval_main, "export": export_main, "runtime": runtime_main,
                "house": house_main}
    sys.exit(commands[sys.argv[1]](sys.argv[2:]))
