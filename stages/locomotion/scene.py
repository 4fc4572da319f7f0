"""G1 humanoids in a scene: a scene USD (e.g. a task kitchen of ``stages.demos.kitchen``) with one
G1 per world, as trained (``robot.g1_builder``: the URDF's inertials, sole spheres as its only
collision shapes, mjlab's drives), driven by the humanoid runtime.

The scene is loaded as the demonstration engine loads it (``stages.simulate.world.load_scene``,
the engine's contact stiffness for the scene's shapes); the G1 keeps the training's shape
settings. MuJoCo-Warp's contact buffers are sized for the scene's resting contacts like the
engine's. Until the G1 gets hand and body colliders it walks through furniture and cannot push or
grasp: this is the place to add them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from stages.locomotion.runtime import LeggedRuntimeConfig


@dataclass(frozen=True, kw_only=True)
class HumanoidSceneConfig:
    """One scene replicated to ``num_worlds`` worlds, a G1 standing in each at ``spawn``."""

    scene: Path
    """scene USD"""
    spawn: tuple[float, float, float]
    """base (x [m], y [m], yaw [rad]) in the scene"""
    num_worlds: int = 1
    device: str = "cpu"
    runtime: LeggedRuntimeConfig = field(default_factory=LeggedRuntimeConfig)
    foot_mu: float = 0.6
    """the feet's friction coefficient"""
    contact_ke: float = 4.0e4
    """the scene shapes' contact stiffness (the engine's ``SimConfig.contact_ke``)"""
    contact_kd: float = 400.0
    """the scene shapes' contact damping (the engine's ``SimConfig.contact_kd``)"""


def build_humanoid_scene(cfg: HumanoidSceneConfig) -> Any:
    """A ``runtime.HumanoidWorlds`` of ``cfg.num_worlds`` copies of the scene, each with its G1."""
    import newton
    import warp as wp

    from stages.locomotion.robot import g1_builder
    from stages.locomotion.runtime import HumanoidWorlds, HumanoidWorldsConfig
    from stages.simulate.contacts import size_contact_buffers
    from stages.simulate.world import load_scene

    world = newton.ModelBuilder()
    world.default_shape_cfg.ke = cfg.contact_ke
    world.default_shape_cfg.kd = cfg.contact_kd
    newton.solvers.SolverMuJoCo.register_custom_attributes(world)
    load_scene(world, Path(cfg.scene))
    robot, layout = g1_builder(foot_mu=cfg.foot_mu, base_pose=cfg.spawn)
    world.add_builder(robot)
    main = newton.ModelBuilder()
    newton.solvers.SolverMuJoCo.register_custom_attributes(main)
    main.replicate(world, cfg.num_worlds)
    model = main.finalize(device=wp.get_device(cfg.device))
    capacity = size_contact_buffers(model, model.body_q.numpy(), robot_shapes=len(layout.foot_shapes),
                                    dofs_per_world=world.joint_dof_count)
    return HumanoidWorlds(HumanoidWorldsConfig(num_worlds=cfg.num_worlds, device=cfg.device, runtime=cfg.runtime,
                                               foot_mu=cfg.foot_mu),
                          model=model, solver_options={"nconmax": capacity.nconmax, "njmax": capacity.njmax})


@dataclass(frozen=True, kw_only=True)
class ReachConfig:
    """Walk a G1 to a stance and reach a hand to a point: gains and tolerances of the go-to."""

    arm: str = "right"
    gain: float = 2.0
    """base command per metre of position error [1/s]"""
    yaw_gain: float = 1.5
    """yaw-rate command per radian of heading error [1/s]"""
    max_speed: tuple[float, float, float] = (0.6, 0.3, 0.8)
    """largest |vx| [m/s], |vy| [m/s], |v_theta| [rad/s] commanded"""
    arrive_tol: float = 0.05
    """position tolerance of the stance [m]"""
    arrive_yaw_tol: float = 0.1
    """heading tolerance of the stance [rad]"""
    walk_timeout_s: float = 20.0
    reach_s: float = 3.0
    """time given to the hand after the stance is reached [s]"""


@dataclass(frozen=True)
class ReachResult:
    """Per world: arrived (N,) bool, walk_s (N,) [s], stance_error (N,) [m] when the reach began,
    hand_error (N,) [m] at the end (mean over the last second), fell (N,) bool, min_height (N,) [m]."""

    arrived: Any
    walk_s: Any
    stance_error: Any
    hand_error: Any
    fell: Any
    min_height: Any


def go_to_and_reach(worlds: Any, stance: Any, hand_point: Any, cfg: ReachConfig | None = None) -> ReachResult:
    """Every world walks (locomotion mode, a proportional go-to through the base interface) to its
    ``stance`` (N, 3) = (x [m], y [m], yaw [rad]), switches to manipulation mode and moves its
    hand to ``hand_point`` (N, 3) [m], world frame, keeping the hand's orientation at the switch."""
    import numpy as np

    from stages.locomotion.runtime import Mode

    cfg = cfg or ReachConfig()
    rt = worlds.runtime
    n = rt.num_worlds
    stance, hand_point = np.asarray(stance, float).reshape(n, 3), np.asarray(hand_point, float).reshape(n, 3)
    walking = np.ones(n, bool)
    walk_s, stance_err = np.full(n, np.nan), np.full(n, np.nan)
    reach_left = np.full(n, int(round(cfg.reach_s / rt.control_dt)))
    last_second = int(round(1.0 / rt.control_dt))
    hand_err = [[] for _ in range(n)]
    min_h = np.full(n, np.inf)
    limit = np.asarray(cfg.max_speed)
    steps = int(round((cfg.walk_timeout_s + cfg.reach_s) / rt.control_dt))
    for k in range(steps):
        pos, quat, _, _ = (t.detach().cpu().double().numpy() for t in rt.base_state(worlds.state))
        x, y, z, w = quat.T
        yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        d = stance[:, :2] - pos[:, :2]
        c, s = np.cos(yaw), np.sin(yaw)
        e_b = np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], axis=1)
        e_yaw = (stance[:, 2] - yaw + np.pi) % (2 * np.pi) - np.pi
        cmd = np.clip(np.concatenate([cfg.gain * e_b, cfg.yaw_gain * e_yaw[:, None]], axis=1), -limit, limit)
        arrived = walking & (np.linalg.norm(d, axis=1) < cfg.arrive_tol) & (np.abs(e_yaw) < cfg.arrive_yaw_tol)
        for wi in np.flatnonzero(arrived):
            walking[wi] = False
            walk_s[wi], stance_err[wi] = k * rt.control_dt, float(np.linalg.norm(d[wi]))
            rt.set_mode([int(Mode.MANIPULATION)], [wi])
            target = rt.ee_pose_world(worlds.state, cfg.arm)[wi]
            target[:3, 3] = hand_point[wi]
            rt.set_ee_target(cfg.arm, target[None], [wi])
        rt.set_command(np.where(walking[:, None], cmd, 0.0))
        if not walking.any() and (reach_left <= 0).all():
            break
        worlds.step()
        min_h = np.minimum(min_h, rt.base_state(worlds.state)[0][:, 2].cpu().numpy())
        reaching = ~walking & (reach_left > 0)
        if reaching.any():
            got = rt.ee_pose_world(worlds.state, cfg.arm)[:, :3, 3]
            for wi in np.flatnonzero(reaching):
                if reach_left[wi] <= last_second:
                    hand_err[wi].append(float(np.linalg.norm(got[wi] - hand_point[wi])))
            reach_left[reaching] -= 1
    return ReachResult(arrived=~walking, walk_s=walk_s, stance_error=stance_err,
                       hand_error=np.array([np.mean(e) if e else np.nan for e in hand_err]),
                       fell=min_h < 0.3, min_height=min_h)
