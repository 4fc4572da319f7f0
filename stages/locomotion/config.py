"""Typed configuration of the humanoid (G1, H1) velocity-tracking task and its PPO training.

Plain frozen dataclasses (no heavy imports): the CLI builds them from arguments, the trainer
writes them as JSON beside each checkpoint, and ``from_dict`` reads them back. Units are in the
field docstrings; ranges are ``(low, high)`` tuples sampled uniformly.

The task follows mjlab's ``Unitree-G1-Flat`` velocity task (rewards, observation noise, action
scale 0.25 * effort / stiffness, PD gains from armature at 10 Hz / damping ratio 2, 200 Hz physics,
50 Hz control) with this project's command ranges, and the paper's arm perturbation: the arms'
joint targets are redrawn every 150 control steps and held by PD, not by the policy.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

ROBOT_NAMES = ("g1", "h1")
"""the humanoids ``EnvConfig.robot`` may name (``stages.locomotion.humanoids.ROBOTS``' keys)"""


@dataclass(frozen=True, kw_only=True)
class CommandRanges:
    """Velocity commands in the base's heading frame."""

    vx: tuple[float, float] = (-0.5, 1.0)
    """forward velocity [m/s]"""
    vy: tuple[float, float] = (-0.5, 0.5)
    """lateral velocity [m/s]"""
    yaw_rate: tuple[float, float] = (-1.0, 1.0)
    """yaw rate [rad/s]"""
    resample_s: tuple[float, float] = (3.0, 8.0)
    """time between command draws [s]"""
    standing_fraction: float = 0.1
    """share of draws that command zero velocity"""


@dataclass(frozen=True, kw_only=True)
class RewardWeights:
    """Weights of the reward terms; each term is also multiplied by the control period (mjlab)."""

    track_lin_vel: float = 1.0
    track_ang_vel: float = 1.0
    tracking_std: float = 0.5
    """std of the exponential tracking kernels [m/s, rad/s]"""
    posture: float = 1.0
    joint_limits: float = -1.0
    action_rate: float = -0.1
    lin_vel_z: float = 0.0
    ang_vel_xy: float = 0.0
    termination: float = 0.0
    foot_clearance: float = 0.0
    """swing-foot clearance: penalizes a foot that moves horizontally lower than ``clearance_height``
    over the terrain under it (legged_gym's humanoid feet clearance); 0 on flat floors, the
    terrain preset turns it on so the blind policy lifts its feet over thresholds and risers"""
    clearance_height: float = 0.10
    """target swing height of the soles over the terrain [m]"""


@dataclass(frozen=True, kw_only=True)
class Randomization:
    """Domain randomization: drawn per world at start-up (friction, mass) or during episodes."""

    foot_friction: tuple[float, float] = (0.3, 1.2)
    """sliding friction coefficient of the feet (the floor's is the lower bound)"""
    base_mass_offset: tuple[float, float] = (-1.0, 3.0)
    """mass added to the pelvis [kg]"""
    push_interval_s: tuple[float, float] = (1.0, 3.0)
    """time between pushes [s]"""
    push_velocity: float = 0.5
    """largest planar base velocity change of a push [m/s]; 0 disables pushes"""
    arm_resample_steps: int = 150
    """control steps between arm target draws (the paper's 150 frames)"""
    arm_range: float = 0.6
    """half-width of the arm targets' draw around the default pose [rad], clipped to limits"""
    arm_reach: bool = False
    """draw the arm targets uniformly in ``robot.REACH_ARM_RANGES`` instead (hands from the thigh to
    above the head: counter-height reaching), clipped to limits; ``arm_range`` is then unused"""
    obs_noise: bool = True
    """add mjlab's uniform observation noise to the policy's observations (not the critic's)"""


@dataclass(frozen=True, kw_only=True)
class TerrainConfig:
    """Per-world terrain and its curriculum (``stages.locomotion.terrain``); off: flat floors only.

    Defaults follow the layout stage: stairs up to its steepest riser (``stages.layout.model.RISE``,
    0.19 m) with its tread depths (``RUN``, 0.26-0.30 m), door thresholds of 1-4 cm.
    """

    enabled: bool = False
    kinds: tuple[float, float, float] = (0.4, 0.2, 0.4)
    """shares of worlds that are flat, have door thresholds, have stairs (up, landing, down); the flat
    worlds keep the flat task's commands (mjlab's rough G1 mix: 40 % flat), so the flat-floor tracking,
    yaw rates across the whole range included, is not forgotten while climbing is learned"""
    num_boxes: int = 6
    """static boxes per world: thresholds per lane, risers per flight"""
    num_levels: int = 10
    """difficulty levels; level l scales heights linearly from the low to the high end"""
    init_max_level: int = 2
    """worlds start at a uniform level in [0, init_max_level]"""
    stair_rise: tuple[float, float] = (0.04, 0.19)
    """riser height at level 0 and at the top level [m]"""
    stair_run: tuple[float, float] = (0.26, 0.30)
    """tread depth, drawn per world [m]"""
    landing: float = 1.0
    """top landing between the flights [m]"""
    threshold_height: tuple[float, float] = (0.01, 0.04)
    """door threshold height at level 0 and at the top level [m]"""
    threshold_depth: float = 0.06
    """threshold depth along the walk [m]"""
    threshold_spacing: float = 0.9
    """distance between thresholds [m]"""
    start_x: float = 1.0
    """distance from the spawn point to the first obstacle [m]"""
    lane_width: float = 1.6
    """width of the stairs and thresholds [m]"""
    spawn_yaw: float = 0.3
    """half-width of the spawn heading's draw around +x on thresholds and stairs [rad]"""
    vx: tuple[float, float] = (0.3, 1.0)
    """forward command on thresholds and stairs [m/s]"""
    vy: tuple[float, float] = (-0.15, 0.15)
    """lateral command on thresholds and stairs [m/s]"""
    heading_gain: float = 1.0
    """yaw-rate command per radian of heading error [1/s] (heading-hold draws: mjlab's
    ``heading_control_stiffness``), clipped to ``commands.yaw_rate``"""
    heading_range: float = 0.3
    """half-width of the heading target's draw around +x on heading-hold draws [rad]: with the spawn
    heading's spread the yaw-rate commands span about +-2 heading_range * heading_gain [rad/s] at a
    draw, then decay as the heading is reached; the lane (``lane_width``) bounds it"""
    turn_fraction: float = 0.5
    """share of the command draws on threshold worlds whose yaw rate is drawn in ``commands.yaw_rate``
    (the robot turns while it walks over the sills, as on a flat floor) instead of holding a heading;
    stairs always hold one (turning on a flight walks off its side)"""
    down_fraction: float = 0.5
    """a level down when the robot covered less than this share of its commanded distance"""
    posture_scale: float = 0.5
    """posture reward scale on thresholds and stairs (climbing bends the knees and hips)"""

    def problems(self) -> list[str]:
        """One line per inconsistency (empty when valid)."""
        out = []
        if len(self.kinds) != 3 or min(self.kinds) < 0 or sum(self.kinds) <= 0:
            out.append(f"terrain.kinds must be 3 non-negative shares (flat, threshold, stairs), got {self.kinds}")
        if self.num_boxes < 1:
            out.append(f"terrain.num_boxes must be positive, got {self.num_boxes}")
        if not 0.0 <= self.turn_fraction <= 1.0:
            out.append(f"terrain.turn_fraction must be in [0, 1], got {self.turn_fraction}")
        if self.heading_range < 0.0 or self.heading_gain < 0.0:
            out.append(f"terrain.heading_range and heading_gain must be >= 0, got {self.heading_range}, "
                       f"{self.heading_gain}")
        if not 0 <= self.init_max_level < self.num_levels:
            out.append(f"terrain levels: need 0 <= init_max_level ({self.init_max_level}) < num_levels "
                       f"({self.num_levels})")
        for name in ("stair_rise", "stair_run", "threshold_height"):
            lo, hi = getattr(self, name)
            if not 0.0 < lo <= hi:
                out.append(f"terrain.{name} must be 0 < low <= high, got {(lo, hi)}")
        return out


@dataclass(frozen=True, kw_only=True)
class EnvConfig:
    """One batched humanoid environment: N worlds in one Newton model, stepped together."""

    num_worlds: int = 4096
    device: str = "cuda:0"
    seed: int = 0
    sim_dt: float = 0.005
    """physics step [s]"""
    decimation: int = 4
    """physics steps per control step (50 Hz control at 200 Hz physics)"""
    episode_length_s: float = 20.0
    """timeout [s]"""
    solver_iterations: int = 10
    ls_iterations: int = 20
    robot: str = "g1"
    """the humanoid (``stages.locomotion.humanoids.ROBOTS``): g1 or h1"""
    fall_height: float | None = None
    """base height under which a world has fallen [m]; None: the robot's (G1 0.3, H1 0.4)"""
    fall_tilt_deg: float | None = None
    """base tilt over which a world has fallen [deg]; None: the robot's (70)"""
    use_waist: bool = True
    """the policy also drives the 3 waist joints (else they are held at the default pose)"""
    cuda_graph: bool = True
    commands: CommandRanges = field(default_factory=CommandRanges)
    rewards: RewardWeights = field(default_factory=RewardWeights)
    randomization: Randomization = field(default_factory=Randomization)
    terrain: TerrainConfig = field(default_factory=TerrainConfig)

    def __post_init__(self) -> None:
        problems = []
        if self.robot not in ROBOT_NAMES:
            problems.append(f"robot must be one of {', '.join(ROBOT_NAMES)}, got {self.robot!r}")
        if self.num_worlds < 1:
            problems.append(f"num_worlds must be positive, got {self.num_worlds}")
        if self.decimation < 1 or self.decimation % 2:
            problems.append(f"decimation must be a positive even number (state swaps), got {self.decimation}")
        if self.sim_dt <= 0.0:
            problems.append(f"sim_dt must be positive, got {self.sim_dt}")
        if self.terrain.enabled:
            problems += self.terrain.problems()
        if problems:
            raise ValueError("; ".join(problems))

    @property
    def control_dt(self) -> float:
        """control period [s]"""
        return self.sim_dt * self.decimation


@dataclass(frozen=True, kw_only=True)
class PPOConfig:
    """rsl-rl PPO hyper-parameters (mjlab's G1 velocity runner)."""

    num_steps_per_env: int = 24
    hidden_dims: tuple[int, ...] = (512, 256, 128)
    init_noise_std: float = 1.0
    learning_rate: float = 1.0e-3
    num_learning_epochs: int = 5
    num_mini_batches: int = 4
    clip_param: float = 0.2
    entropy_coef: float = 0.01
    gamma: float = 0.99
    lam: float = 0.95
    desired_kl: float = 0.01
    max_grad_norm: float = 1.0


@dataclass(frozen=True, kw_only=True)
class TrainConfig:
    """A training run: resumes from the latest checkpoint in ``checkpoint_dir`` unless ``resume`` is off."""

    env: EnvConfig = field(default_factory=EnvConfig)
    ppo: PPOConfig = field(default_factory=PPOConfig)
    iterations: int = 1000
    """PPO iterations to run in this call (added to those already done)"""
    max_wall_s: float = 0.0
    """stop after this wall time [s] (0: no limit); a checkpoint is written at the stop"""
    save_every: int = 100
    """iterations between checkpoints"""
    checkpoint_dir: str = "out/locomotion/g1_velocity"
    resume: bool = True
    init_from: str = ""
    """a checkpoint (rsl-rl ``model_<iter>.pt`` or a policy folder's ``checkpoint.pt``) to start from
    when ``checkpoint_dir`` holds none yet: its weights, optimizer and iteration count, and the
    ``curve.csv`` beside it (e.g. the committed flat-floor policy, to fine-tune on terrain)"""

    def __post_init__(self) -> None:
        if self.iterations < 0:
            raise ValueError(f"iterations must be >= 0, got {self.iterations}")


def to_dict(cfg: Any) -> dict[str, Any]:
    """JSON-ready dict of a config dataclass (tuples become lists)."""
    return dataclasses.asdict(cfg)


def _build(cls: type, data: dict[str, Any]) -> Any:
    kwargs: dict[str, Any] = {}
    hints = {f.name: f for f in dataclasses.fields(cls)}
    for key, value in data.items():
        if key not in hints:
            continue  # forward-compatible: unknown keys from newer files are ignored
        default = getattr(cls(), key)
        if dataclasses.is_dataclass(default) and isinstance(value, dict):
            value = _build(type(default), value)
        elif isinstance(default, tuple) and isinstance(value, list):
            value = tuple(value)
        kwargs[key] = value
    return cls(**kwargs)


def train_config_from_dict(data: dict[str, Any]) -> TrainConfig:
    """Inverse of ``to_dict`` for ``TrainConfig``."""
    return _build(TrainConfig, data)


def env_config_from_dict(data: dict[str, Any]) -> EnvConfig:
    """Inverse of ``to_dict`` for ``EnvConfig``."""
    return _build(EnvConfig, data)
