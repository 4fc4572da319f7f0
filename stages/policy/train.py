"""Train ACT or Diffusion Policy on one of our datasets with ``lerobot-train`` (issue 17).

:func:`train_policy` runs lerobot's training entry point in a subprocess
(:mod:`stages.policy.lerobot_train_run`: ``lerobot-train`` with a hook that records the training
curve) on a dataset folder as the project writes it (no conversion: depth is ``depth.<camera>``,
which no policy takes as an input). Output folder ``OUT``:

- ``OUT/lerobot/``: lerobot's ``output_dir`` (checkpoints; the policy to evaluate is
  ``OUT/lerobot/checkpoints/last/pretrained_model``, see :func:`checkpoint_of`);
- ``OUT/curve.csv`` / ``OUT/curve.png``: loss (and ACT's l1 / kld terms), gradient norm and
  learning rate against the step;
- ``OUT/train.json``: configuration, the exact lerobot-train command, wall time [s], last loss;
- ``OUT/train.log``: lerobot's output.

Settings (the AgentWorld paper trains lerobot's implementations with action chunks of 20 for basic
tasks, 40 for multistage ones, temporal ensembling and batch 16): ACT with ``chunk_size`` 20,
``n_action_steps`` 1 and ``temporal_ensemble_coeff`` 0.01 (lerobot's ensembling needs one action
per step); Diffusion Policy with lerobot's defaults (horizon 16, 2 observation steps, 8 actions per
chunk: its U-Net needs a horizon divisible by 8, and lerobot has no ensembling for it); batch 16;
every other setting lerobot's default for the policy. The vision backbone starts from scratch
(``pretrained_backbone_weights`` unset): ImageNet weights cannot be downloaded on these machines.
``extra_args`` passes further ``--key=value`` arguments to lerobot-train as they are (a tiny model
for tests, a crop for small images).
"""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

POLICIES = ("act", "diffusion")
CHECKPOINT = Path("lerobot") / "checkpoints" / "last" / "pretrained_model"


@dataclass(frozen=True, kw_only=True)
class TrainConfig:
    """policy: "act" or "diffusion"; dataset: a LeRobot dataset folder written by the project;
    out: the output folder (must not exist); steps: optimizer steps; batch_size: samples per step;
    chunk_size: ACT's action chunk [frames] (20 basic, 40 multistage tasks); temporal_ensemble:
    ACT's temporal ensembling coefficient (None: no ensembling, ``n_action_steps`` = chunk);
    device: "cuda", "cuda:N" or "cpu"; seed: lerobot's seed; num_workers: data loader workers;
    log_freq: steps per curve point; save_freq: steps per checkpoint; extra_args: more
    lerobot-train arguments (``--policy.dim_model=64``); max_seconds: stop after this wall time [s]
    (from the start of :func:`train_policy`), saving the checkpoint of the step reached (None: run
    all ``steps``; the learning-rate schedule is still that of ``steps``); frame_cache: a folder where
    the RGB videos are decoded once and read from by the data loader (:mod:`stages.policy.frame_cache`;
    None: lerobot's per-sample decoding; runs on one dataset may share it); init: a checkpoint
    (``pretrained_model`` folder, or a train-policy output folder) of the same policy whose weights
    the training starts from (lerobot's ``--policy.pretrained_path``: fresh optimizer and learning-rate
    schedule, normalization from ``dataset``), so training can go on across machines; cameras: the
    dataset's RGB cameras the policy takes (None: all; (): none, the policy then takes the state and
    ``observation.environment_state``, which the dataset must have; only these videos are decoded);
    state_drop: ``observation.state`` entries the policy does not take (``base_x,base_y,base_theta``:
    the base pose in the world), trained on a state view of the dataset written to ``OUT/dataset``
    (:mod:`stages.dataset.view`); every checkpoint records its state names (:data:`~stages.policy.runner.POLICY_INFO`),
    which the evaluator feeds it; memory_frames: the data loader reads samples from the dataset's
    columns held in memory (:mod:`stages.policy.memory_frames`: the same samples, ~25x fewer CPU
    seconds each; False: lerobot's reads)."""

    policy: str
    dataset: Path
    out: Path
    steps: int = 100_000
    batch_size: int = 16
    chunk_size: int = 20
    temporal_ensemble: float | None = 0.01
    device: str = "cuda"
    seed: int = 1000
    num_workers: int = 4
    log_freq: int = 100
    save_freq: int = 20_000
    extra_args: tuple[str, ...] = field(default_factory=tuple)
    max_seconds: float | None = None
    frame_cache: Path | None = None
    init: Path | None = None
    cameras: tuple[str, ...] | None = None
    state_drop: tuple[str, ...] = ()
    memory_frames: bool = True

    def __post_init__(self) -> None:
        problems = []
        if self.init is not None:
            init = Path(self.init)
            ck = resolve_checkpoint(init)
            if not ((ck / "config.json").is_file() and (ck / "model.safetensors").is_file()):
                problems.append(f"init {init}: not a checkpoint (no config.json and model.safetensors)")
            else:
                import json

                kind = json.loads((ck / "config.json").read_text()).get("type")
                if kind != self.policy:
                    problems.append(f"init {init}: a {kind} checkpoint, not {self.policy}")
        if self.policy not in POLICIES:
            problems.append(f"policy must be one of {POLICIES}, got {self.policy!r}")
        for name in ("steps", "batch_size", "chunk_size", "log_freq", "save_freq"):
            if getattr(self, name) < 1:
                problems.append(f"{name} must be >= 1, got {getattr(self, name)}")
        if self.max_seconds is not None and not self.max_seconds > 0:
            problems.append(f"max_seconds must be > 0 [s] or None, got {self.max_seconds}")
        if self.num_workers < 0:
            problems.append(f"num_workers must be >= 0, got {self.num_workers}")
        bad = [a for a in self.extra_args if not a.startswith("--")]
        if bad:
            problems.append(f"extra_args must be --key=value arguments, got {bad}")
        if problems:
            raise ValueError("train-policy: " + "; ".join(problems))


@dataclass(frozen=True)
class TrainResult:
    """checkpoint: the last checkpoint's ``pretrained_model`` folder; curve_csv / curve_png;
    wall_seconds: the training subprocess's wall time [s]; steps; last_loss (the last curve
    point's loss, None without one); command: the lerobot-train arguments; stopped: training was
    stopped at ``max_seconds`` (``steps`` is then the step reached)."""

    checkpoint: Path
    curve_csv: Path
    curve_png: Path
    wall_seconds: float
    steps: int
    last_loss: float | None
    command: tuple[str, ...]
    stopped: bool = False


def lerobot_args(cfg: TrainConfig) -> list[str]:
    """The lerobot-train arguments of ``cfg`` (see the module docstring for the settings)."""
    ds = Path(cfg.dataset).resolve()
    args = [
        f"--dataset.repo_id=agentworld/{ds.name}", f"--dataset.root={ds}", "--dataset.video_backend=pyav",
        f"--policy.type={cfg.policy}", f"--policy.device={cfg.device}", "--policy.push_to_hub=false",
        f"--output_dir={Path(cfg.out).resolve() / 'lerobot'}", f"--job_name={cfg.policy}_{ds.name}",
        f"--steps={cfg.steps}", f"--batch_size={cfg.batch_size}", f"--num_workers={cfg.num_workers}",
        f"--log_freq={cfg.log_freq}", f"--save_freq={min(cfg.save_freq, cfg.steps)}", f"--seed={cfg.seed}",
        "--wandb.enable=false", "--policy.pretrained_backbone_weights=null",
    ]  # fmt: skip
    if cfg.policy == "act":
        args += [f"--policy.chunk_size={cfg.chunk_size}"]
        if cfg.temporal_ensemble is not None:
            args += ["--policy.n_action_steps=1", f"--policy.temporal_ensemble_coeff={cfg.temporal_ensemble}"]
        else:
            args += [f"--policy.n_action_steps={cfg.chunk_size}"]
    if cfg.init is not None:
        args += [f"--policy.pretrained_path={resolve_checkpoint(Path(cfg.init).resolve())}"]
    norm = env_state_normalization(ds, cfg.policy)
    if norm and not any(a.startswith("--policy.normalization_mapping=") for a in cfg.extra_args):
        args += [f"--policy.normalization_mapping={json.dumps(norm)}"]
    return args + list(cfg.extra_args)


def env_state_normalization(dataset: Path, policy: str) -> dict[str, str] | None:
    """The policy's normalization mapping with ``ENV`` normalized as its ``STATE`` is, when
    ``dataset`` has ``observation.environment_state`` (lerobot 0.6.1's defaults map nothing to ENV,
    which would feed the task objects' positions raw, metres up to ~4 in a kitchen); None otherwise."""
    try:
        feats = json.loads((Path(dataset) / "meta" / "info.json").read_text())["features"]
    except (OSError, KeyError, json.JSONDecodeError):
        return None
    if "observation.environment_state" not in feats:
        return None
    import dataclasses

    import lerobot.policies  # noqa: F401  (registers the policies' config classes)
    from lerobot.configs.policies import PreTrainedConfig

    field = next(f for f in dataclasses.fields(PreTrainedConfig.get_choice_class(policy))
                 if f.name == "normalization_mapping")  # the default, without building a config (its device probe)
    mapping = {k: getattr(v, "value", v) for k, v in field.default_factory().items()}
    return {**mapping, "ENV": mapping["STATE"]}


def check_cameras(cfg: TrainConfig) -> None:
    """ValueError (one line, naming the dataset) when ``cfg.cameras`` names a camera the dataset has
    not, or is empty on a dataset without ``observation.environment_state`` (no policy input but the
    robot state: lerobot's ACT and Diffusion Policy need an image or the environment state)."""
    if cfg.cameras is None:
        return
    feats = json.loads((Path(cfg.dataset) / "meta" / "info.json").read_text())["features"]
    have = [k.removeprefix("observation.images.") for k, v in feats.items()
            if k.startswith("observation.images.") and v.get("dtype") in ("video", "image")]
    bad = [c for c in cfg.cameras if c not in have]
    if bad:
        raise ValueError(f"train-policy: {cfg.dataset}: no cameras {bad} (it has {have})")
    if not cfg.cameras and "observation.environment_state" not in feats:
        raise ValueError(f"train-policy: {cfg.dataset}: no camera and no observation.environment_state: "
                         "the policy would see only the robot state")


def checkpoint_of(out: Path) -> Path:
    """The evaluable checkpoint (``pretrained_model`` folder) of a train-policy output folder."""
    return Path(out) / CHECKPOINT


def resolve_checkpoint(path: Path) -> Path:
    """``path`` when it is a checkpoint folder (has config.json), else the checkpoint of the
    train-policy output folder ``path`` when there is one, else ``path``."""
    path = Path(path)
    if not (path / "config.json").is_file() and checkpoint_of(path).is_dir():
        return checkpoint_of(path)
    return path


def train_policy(cfg: TrainConfig, *, timeout: float | None = None) -> TrainResult:
    """Run lerobot-train for ``cfg`` (see the module docstring); raises ``RuntimeError`` naming the
    log when it fails."""
    out = Path(cfg.out).resolve()
    if out.exists():
        raise FileExistsError(f"train-policy: {out} exists (choose a new output folder)")
    if not (Path(cfg.dataset) / "meta" / "info.json").is_file():
        raise FileNotFoundError(f"train-policy: {cfg.dataset}: no meta/info.json (not a LeRobot dataset)")
    check_cameras(cfg)
    if cfg.state_drop:  # checked before the output folder is made
        from stages.dataset.view import kept_names

        try:
            kept_names(Path(cfg.dataset), cfg.state_drop)
        except ValueError as e:
            raise ValueError(f"train-policy: cannot drop state entries {list(cfg.state_drop)}: {e}") from None
    out.mkdir(parents=True)
    source = Path(cfg.dataset)
    if cfg.state_drop:
        from dataclasses import replace

        from stages.dataset.view import write_state_view

        write_state_view(source, out / "dataset", cfg.state_drop)
        cfg = replace(cfg, dataset=out / "dataset")
    args = lerobot_args(cfg)
    wrapper = ["--memory-frames"] if cfg.memory_frames else []
    if cfg.max_seconds is not None:
        wrapper += ["--deadline", f"{time.time() + cfg.max_seconds:.3f}"]
    if cfg.frame_cache is not None:
        wrapper += ["--frame-cache", str(Path(cfg.frame_cache).resolve())]
    if cfg.cameras is not None:
        wrapper += ["--cameras", ",".join(cfg.cameras)]
    cmd = [sys.executable, "-m", "stages.policy.lerobot_train_run", str(out / "curve.csv"), *wrapper, "--", *args]
    env = dict(os.environ, HF_HUB_OFFLINE="1", TQDM_DISABLE="1", HF_DATASETS_DISABLE_PROGRESS_BARS="1")
    repo = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = os.pathsep.join([repo, *filter(None, [env.get("PYTHONPATH")])])
    t0 = time.perf_counter()
    with (out / "train.log").open("w") as log:
        proc = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, env=env, timeout=timeout)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"train-policy: lerobot-train failed (exit {proc.returncode}); see {out / 'train.log'}")
    ckpt = checkpoint_of(out)
    if not (ckpt / "model.safetensors").is_file():
        raise RuntimeError(f"train-policy: no checkpoint in {ckpt}; see {out / 'train.log'}")
    from .runner import write_policy_info

    for model in sorted((out / "lerobot" / "checkpoints").glob("*/pretrained_model")):
        write_policy_info(model, Path(cfg.dataset))
    rows = list(csv.DictReader((out / "curve.csv").open())) if (out / "curve.csv").is_file() else []
    from .curve import plot_curve

    png = plot_curve(out / "curve.csv", out / "curve.png")
    last = float(rows[-1]["loss"]) if rows and rows[-1].get("loss") else None
    stop = out / "stopped.json"
    steps = int(json.loads(stop.read_text())["step"]) if stop.is_file() else cfg.steps
    res = TrainResult(checkpoint=ckpt, curve_csv=out / "curve.csv", curve_png=png, wall_seconds=round(wall, 2),
                      steps=steps, last_loss=last, command=("lerobot-train", *args), stopped=stop.is_file())
    summary = {"config": {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(cfg).items()},
               "source_dataset": str(source),
               "checkpoint": str(ckpt), "wall_seconds": res.wall_seconds, "steps": steps,
               "steps_planned": cfg.steps, "stopped_at_max_seconds": res.stopped,
               "curve_points": len(rows), "last_loss": last, "command": list(res.command)}
    (out / "train.json").write_text(json.dumps(summary, indent=2) + "\n")
    return res
