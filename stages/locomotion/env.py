"""Batched humanoid velocity-tracking environment (``EnvConfig.robot``: G1, H1; its
``robot.HumanoidDescription``): N worlds in one Newton model, torch tensors on the device.

The Newton state's arrays are viewed as torch tensors (``wp.to_torch``, shared memory): observation,
reward, termination and reset logic run as torch operations on the device; the physics of one
control step (``decimation`` SolverMuJoCo steps) is one CUDA graph launch on the GPU.

Shapes: ``N`` worlds, ``J`` joints (G1 29, H1 19), ``A`` policy actions (legs + waist by default:
G1 12 + 3, H1 10 + 1 torso),
``O = 12 + 2 J + A`` observations: base linear velocity (3, body frame, m/s), base angular velocity
(3, body frame, rad/s), projected gravity (3), command (vx m/s, vy m/s, yaw rate rad/s), joint
positions relative to the default pose (J, rad), joint velocities (J, rad/s), last actions (A).
"""

from __future__ import annotations

import math
from typing import Any

import torch

from stages.locomotion.config import EnvConfig
from stages.locomotion.humanoids import humanoid
from stages.locomotion.robot import G1Layout, build_humanoid_model
from stages.locomotion import rewards as R
from stages.locomotion.terrain import FLAT, THRESHOLD, TerrainWorlds, build_terrain_model

OBS_NOISE = {"lin_vel": 0.1, "ang_vel": 0.2, "gravity": 0.05, "joint_pos": 0.01, "joint_vel": 1.5}
"""half-widths of mjlab's uniform observation noise"""
SOFT_LIMIT_FACTOR = 0.9


def quat_rotate_inverse(q_xyzw: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Rotate world vectors into the frame of unit quaternions: (N, 4) xyzw, (N, 3) -> (N, 3)."""
    qv, w = q_xyzw[:, :3], q_xyzw[:, 3:4]
    t = 2.0 * torch.linalg.cross(qv, v, dim=1)
    return v - w * t + torch.linalg.cross(qv, t, dim=1)


class G1VelocityEnv:
    """N humanoid worlds (``cfg.robot``) tracking planar velocity commands; arms follow random PD targets.

    ``step(actions)`` takes (N, A) actions, advances one control step, resets the worlds that fell or
    timed out and returns ``(obs, critic_obs, reward, terminated, timed_out)``: (N, O), (N, O), (N,),
    (N,) bool, (N,) bool; the observations of reset worlds are their first of the new episode.
    """

    def __init__(self, cfg: EnvConfig) -> None:
        import newton
        import warp as wp

        wp.config.quiet = True
        self.cfg = cfg
        self.device = torch.device(cfg.device)
        self.wp_device = wp.get_device(cfg.device)
        self.num_worlds = n = cfg.num_worlds
        self.robot = desc = humanoid(cfg.robot)
        self.fall_height = cfg.fall_height if cfg.fall_height is not None else desc.fall_height
        self.fall_tilt_deg = cfg.fall_tilt_deg if cfg.fall_tilt_deg is not None else desc.fall_tilt_deg
        self.gen = torch.Generator(device=self.device)
        self.gen.manual_seed(cfg.seed)

        self.terrain: TerrainWorlds | None = None
        """per-world terrain and curriculum (``cfg.terrain.enabled``), else flat floors only"""
        if cfg.terrain.enabled:
            self.terrain = TerrainWorlds(cfg.terrain, n, self.device, self.gen)
            self.model, self.layout = build_terrain_model(n, self.wp_device, self.terrain, robot=desc)
        else:
            self.model, self.layout = build_humanoid_model(desc, n, self.wp_device)
        lay: G1Layout = self.layout
        self.joint_names = lay.joint_names
        self.policy_joints = desc.leg_joints + (desc.waist_joints if cfg.use_waist else ())
        self.num_actions = len(self.policy_joints)
        self.num_obs = 12 + 2 * len(self.joint_names) + self.num_actions
        self.max_episode_length = int(round(cfg.episode_length_s / cfg.control_dt))
        dev = self.device
        tensor = lambda x, dt=torch.float32: torch.as_tensor(x, dtype=dt, device=dev)  # noqa: E731
        self.act_idx = tensor(lay.index(self.policy_joints), torch.long)
        self.arm_idx = tensor(lay.index(desc.arm_joints), torch.long)
        self.default_q = tensor([desc.default_pose.get(j, 0.0) for j in self.joint_names])
        self.action_scale = tensor([desc.joint_action_scale(j) for j in self.policy_joints])
        self.posture_std = tensor([desc.joint_posture_std(j) for j in self.policy_joints])
        self.reach_lo, self.reach_hi = tensor([[desc.reach_range(j)[i] for j in desc.arm_joints]
                                               for i in (0, 1)])
        lo = self.model.joint_limit_lower.numpy()[6:6 + len(self.joint_names)]
        hi = self.model.joint_limit_upper.numpy()[6:6 + len(self.joint_names)]
        mid, half = (lo + hi) / 2, (hi - lo) / 2 * SOFT_LIMIT_FACTOR
        self.soft_lo, self.soft_hi = tensor(mid - half), tensor(mid + half)

        self._randomize_model()
        contacts = dict(nconmax=40, njmax=240) if self.terrain is not None else dict(nconmax=24, njmax=160)
        self.solver = newton.solvers.SolverMuJoCo(
            self.model, iterations=cfg.solver_iterations, ls_iterations=cfg.ls_iterations, **contacts)
        if self.terrain is not None:
            self.terrain.notify(self.solver)
        self.state_0, self.state_1 = self.model.state(), self.model.state()
        self.control = self.model.control()
        self.q = wp.to_torch(self.state_0.joint_q).view(n, lay.coords_per_world)
        self.qd = wp.to_torch(self.state_0.joint_qd).view(n, lay.dofs_per_world)
        self.target_q = wp.to_torch(self.control.joint_target_q).view(n, lay.coords_per_world)
        self.init_q = self.q[0].clone()

        f32 = dict(dtype=torch.float32, device=dev)
        self.actions = torch.zeros(n, self.num_actions, **f32)
        self.prev_actions = torch.zeros_like(self.actions)
        self.commands = torch.zeros(n, 3, **f32)
        self.arm_targets = self.default_q[self.arm_idx].repeat(n, 1)
        self.episode_length_buf = torch.zeros(n, dtype=torch.long, device=dev)
        self.command_timer = torch.zeros(n, dtype=torch.long, device=dev)
        self.arm_timer = torch.zeros(n, dtype=torch.long, device=dev)
        self.push_timer = torch.zeros(n, dtype=torch.long, device=dev)
        self.fixed_commands = False
        """when set, commands are never resampled (evaluation sets them)"""
        on_terrain = self.terrain.kind != FLAT if self.terrain is not None else torch.zeros(n, dtype=torch.bool)
        self.on_terrain = on_terrain.to(dev)
        """worlds with thresholds or stairs (N,) bool: spawned facing about +x, commanded forward"""
        self.heading_hold = torch.zeros(n, dtype=torch.bool, device=dev)
        """worlds whose yaw-rate command holds ``heading_target`` (N,) bool"""
        self.heading_target = torch.zeros(n, dtype=torch.float32, device=dev)
        """heading the heading-hold worlds turn to and hold (N,) [rad], 0 along +x"""
        self.commanded_x = torch.zeros(n, **f32)
        """distance along +x the commands asked for in this episode (N,) [m] (terrain curriculum)"""
        self.body_q = wp.to_torch(self.state_0.body_q).view(n, lay.bodies_per_world, 7)
        self.foot_idx = tensor(lay.foot_bodies, torch.long)
        self.prev_foot_xy = self.body_q[:, self.foot_idx, 0:2].clone()
        self.feet_fresh = torch.ones(n, dtype=torch.bool, device=dev)
        """worlds reset since the last clearance term: their feet's speed is not known yet (N,) bool"""
        self.posture_scale = torch.where(self.on_terrain, cfg.terrain.posture_scale, 1.0).float()
        self.metrics = R.RewardMetrics(n, dev)
        self._down = torch.tensor([0.0, 0.0, -1.0], device=dev)
        nj = len(self.joint_names)
        self._noise_widths = torch.cat([
            torch.full((3,), OBS_NOISE["lin_vel"]), torch.full((3,), OBS_NOISE["ang_vel"]),
            torch.full((3,), OBS_NOISE["gravity"]), torch.zeros(3), torch.full((nj,), OBS_NOISE["joint_pos"]),
            torch.full((nj,), OBS_NOISE["joint_vel"]), torch.zeros(self.num_actions)]).to(dev)
        self._graph: Any = None
        self.reset_worlds(torch.arange(n, device=dev))
        self._physics()  # compiles the kernels before any capture
        self.reset_worlds(torch.arange(n, device=dev))
        if cfg.cuda_graph and self.wp_device.is_cuda:
            with wp.ScopedCapture(device=self.wp_device) as capture:
                self._simulate()
            self._graph = capture.graph
        self.obs, self.critic_obs = self._observations()

    # ------------------------------------------------------------------ randomization and reset
    def _uniform(self, shape: tuple[int, ...], lo: float, hi: float) -> torch.Tensor:
        return lo + (hi - lo) * torch.rand(shape, generator=self.gen, device=self.device)

    def _randomize_model(self) -> None:
        """Per-world foot friction and base mass (start-up randomization, before the solver is built)."""
        import warp as wp

        rnd, lay, n = self.cfg.randomization, self.layout, self.num_worlds
        mu = wp.to_torch(self.model.shape_material_mu)
        feet = (torch.arange(n, device=self.device)[:, None] * lay.shapes_per_world
                + torch.as_tensor(lay.foot_shapes, device=self.device)[None, :])
        mu[feet.reshape(-1)] = self._uniform((n, 1), *rnd.foot_friction).expand(n, len(lay.foot_shapes)).reshape(-1)
        mass = wp.to_torch(self.model.body_mass)
        inv_mass = wp.to_torch(self.model.body_inv_mass)
        base = torch.arange(n, device=self.device) * lay.bodies_per_world + lay.base_body
        mass[base] += self._uniform((n,), *rnd.base_mass_offset)
        inv_mass[base] = 1.0 / mass[base]

    def _resample_commands(self, ids: torch.Tensor) -> None:
        """New commands for worlds ``ids`` (K,): uniform in ``cfg.commands`` (a ``standing_fraction`` share
        zero). With terrain, thresholds and stairs walk forward (``terrain.vx``, ``terrain.vy``); their
        yaw rate holds a heading drawn within ``terrain.heading_range`` of +x (``_hold_heading``), except
        a ``terrain.turn_fraction`` share of the threshold worlds' draws, which keep the uniform yaw rate."""
        c, k = self.cfg.commands, len(ids)
        if k == 0 or self.fixed_commands:
            return
        cmd = torch.stack([self._uniform((k,), *c.vx), self._uniform((k,), *c.vy),
                           self._uniform((k,), *c.yaw_rate)], dim=1)
        standing = torch.rand(k, generator=self.gen, device=self.device) < c.standing_fraction
        if self.terrain is not None:
            t = self.cfg.terrain
            terr = self.on_terrain[ids]
            cmd[:, 0] = torch.where(terr, self._uniform((k,), *t.vx), cmd[:, 0])
            cmd[:, 1] = torch.where(terr, self._uniform((k,), *t.vy), cmd[:, 1])
            turn = (self.terrain.kind[ids] == THRESHOLD) & (
                torch.rand(k, generator=self.gen, device=self.device) < t.turn_fraction)
            self.heading_hold[ids] = terr & ~standing & ~turn
            self.heading_target[ids] = self._uniform((k,), -t.heading_range, t.heading_range)
        self.commands[ids] = torch.where(standing[:, None], torch.zeros_like(cmd), cmd)
        self._hold_heading()
        steps = self._uniform((k,), *c.resample_s) / self.cfg.control_dt
        self.command_timer[ids] = steps.long().clamp(min=1)

    def base_yaw(self) -> torch.Tensor:
        """Heading of each world's base (N,) [rad] in (-pi, pi], 0 along +x."""
        q = self.q[:, 3:7]
        return torch.atan2(2 * (q[:, 3] * q[:, 2] + q[:, 0] * q[:, 1]), 1 - 2 * (q[:, 1] ** 2 + q[:, 2] ** 2))

    def _hold_heading(self) -> None:
        """Yaw-rate command of the heading-hold worlds: heading_gain * (heading target - yaw), the
        error wrapped to (-pi, pi], clipped to the yaw-rate range (mjlab's heading command)."""
        if self.terrain is None:
            return
        err = self.heading_target - self.base_yaw()
        err = torch.atan2(torch.sin(err), torch.cos(err))
        lo, hi = self.cfg.commands.yaw_rate
        rate = (self.cfg.terrain.heading_gain * err).clamp(lo, hi)
        self.commands[:, 2] = torch.where(self.heading_hold, rate, self.commands[:, 2])

    def _resample_arms(self, ids: torch.Tensor) -> None:
        k = len(ids)
        if k == 0:
            return
        if self.cfg.randomization.arm_reach:
            u = torch.rand((k, len(self.arm_idx)), generator=self.gen, device=self.device)
            target = self.reach_lo + (self.reach_hi - self.reach_lo) * u
        else:
            r = self.cfg.randomization.arm_range
            target = self.default_q[self.arm_idx] + self._uniform((k, len(self.arm_idx)), -r, r)
        self.arm_targets[ids] = torch.maximum(torch.minimum(target, self.soft_hi[self.arm_idx]),
                                              self.soft_lo[self.arm_idx])
        self.arm_timer[ids] = self.cfg.randomization.arm_resample_steps

    def _reset_push_timer(self, ids: torch.Tensor) -> None:
        steps = self._uniform((len(ids),), *self.cfg.randomization.push_interval_s) / self.cfg.control_dt
        self.push_timer[ids] = steps.long().clamp(min=1)

    def reset_worlds(self, ids: torch.Tensor) -> None:
        """Put worlds ``ids`` (K,) long back at the default pose with random yaw; others are untouched."""
        if len(ids) == 0:
            return
        k = len(ids)
        q = self.init_q.repeat(k, 1)
        q[:, 2] = self.robot.base_height
        yaw = self._uniform((k,), -math.pi, math.pi)
        if self.terrain is not None:
            spread = self.cfg.terrain.spawn_yaw
            yaw = torch.where(self.on_terrain[ids], self._uniform((k,), -spread, spread), yaw)
        q[:, 3:7] = torch.stack([torch.zeros_like(yaw), torch.zeros_like(yaw), torch.sin(yaw / 2),
                                 torch.cos(yaw / 2)], dim=1)
        q[:, 7:] = self.default_q
        self.q[ids] = q
        self.qd[ids] = 0.0
        self.actions[ids] = 0.0
        self.prev_actions[ids] = 0.0
        self.episode_length_buf[ids] = 0
        self.commanded_x[ids] = 0.0
        self.feet_fresh[ids] = True
        self._resample_commands(ids)
        self._resample_arms(ids)
        self._reset_push_timer(ids)
        self.target_q[ids, 7:] = self.default_q
        self.target_q[ids[:, None], 7 + self.arm_idx[None, :]] = self.arm_targets[ids]

    # ------------------------------------------------------------------ physics
    def _simulate(self) -> None:
        s0, s1 = self.state_0, self.state_1
        for _ in range(self.cfg.decimation):
            self.solver.step(s0, s1, self.control, None, self.cfg.sim_dt)
            s0, s1 = s1, s0

    def _physics(self) -> None:
        import warp as wp

        if self._graph is not None:
            torch.cuda.current_stream(self.device).synchronize()
            wp.capture_launch(self._graph)
            wp.synchronize_device(self.wp_device)
        else:
            if self.device.type == "cuda":
                torch.cuda.current_stream(self.device).synchronize()
            self._simulate()
            wp.synchronize_device(self.wp_device)

    # ------------------------------------------------------------------ MDP
    def base_velocities(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(lin_vel_b (N,3) m/s, ang_vel_b (N,3) rad/s, projected gravity (N,3)) of each world's base."""
        quat = self.q[:, 3:7]
        lin_b = quat_rotate_inverse(quat, self.qd[:, 0:3])
        ang_b = quat_rotate_inverse(quat, self.qd[:, 3:6])
        grav = quat_rotate_inverse(quat, self._down.expand_as(lin_b))
        return lin_b, ang_b, grav

    def _observations(self) -> tuple[torch.Tensor, torch.Tensor]:
        lin_b, ang_b, grav = self.base_velocities()
        jpos = self.q[:, 7:] - self.default_q
        jvel = self.qd[:, 6:]
        clean = torch.cat([lin_b, ang_b, grav, self.commands, jpos, jvel, self.actions], dim=1)
        if not self.cfg.randomization.obs_noise:
            return clean, clean
        noise = (2.0 * torch.rand(clean.shape, generator=self.gen, device=self.device) - 1.0) * self._noise_widths
        return clean + noise, clean

    def _foot_clearance(self) -> torch.Tensor:
        """Swing-foot clearance term (N,) (``rewards.foot_clearance``); zeros when its weight is 0."""
        w = self.cfg.rewards
        if w.foot_clearance == 0.0:
            return torch.zeros(self.num_worlds, device=self.device)
        feet = self.body_q[:, self.foot_idx, 0:3]                                    # (N, 2, 3)
        speed = torch.linalg.norm(feet[..., 0:2] - self.prev_foot_xy, dim=2) / self.cfg.control_dt
        speed = speed * (~self.feet_fresh).float()[:, None]
        self.feet_fresh[:] = False
        self.prev_foot_xy.copy_(feet[..., 0:2])
        ground = torch.stack([self.terrain.height_at(feet[:, i, 0:2]) if self.terrain is not None
                              else torch.zeros(self.num_worlds, device=self.device)
                              for i in range(feet.shape[1])], dim=1)
        sole = feet[..., 2] - self.robot.sole_below_ankle
        return R.foot_clearance(sole - ground, speed, w.clearance_height)

    def step(self, actions: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor,
                                                      torch.Tensor]:
        """Advance one control step with actions (N, A); see the class docstring for the returns."""
        cfg, n = self.cfg, self.num_worlds
        self.prev_actions.copy_(self.actions)
        self.actions.copy_(actions.clamp(-100.0, 100.0))
        self.target_q[:, 7 + self.act_idx] = self.default_q[self.act_idx] + self.action_scale * self.actions
        self.target_q[:, 7 + self.arm_idx] = self.arm_targets
        self._physics()
        self.episode_length_buf += 1

        lin_b, ang_b, grav = self.base_velocities()
        jpos = self.q[:, 7:]
        height = self.q[:, 2] if self.terrain is None else self.q[:, 2] - self.terrain.height_at(self.q[:, 0:2])
        fell = (height < self.fall_height) | (grav[:, 2] > -math.cos(math.radians(self.fall_tilt_deg)))
        fell |= ~torch.isfinite(self.q).all(dim=1) | ~torch.isfinite(self.qd).all(dim=1)
        timed_out = (self.episode_length_buf >= self.max_episode_length) & ~fell
        terms = R.reward_terms(
            cfg.rewards, lin_b=lin_b, ang_b=ang_b, commands=self.commands,
            joint_pos=jpos[:, self.act_idx], default_pos=self.default_q[self.act_idx], posture_std=self.posture_std,
            soft_lo=self.soft_lo[self.act_idx], soft_hi=self.soft_hi[self.act_idx],
            actions=self.actions, prev_actions=self.prev_actions, fell=fell,
            planar_tracking=self.terrain is not None)
        terms["posture"] = terms["posture"] * self.posture_scale
        terms["foot_clearance"] = self._foot_clearance()
        reward = R.weighted_sum(cfg.rewards, terms, cfg.control_dt)
        reward = torch.nan_to_num(reward, nan=0.0, posinf=0.0, neginf=0.0)
        done = fell | timed_out
        self.metrics.add(terms, reward, done, fell, self.episode_length_buf)

        # timers: commands, arm targets, pushes
        self.command_timer -= 1
        self._resample_commands(torch.nonzero(self.command_timer <= 0).flatten())
        self.arm_timer -= 1
        self._resample_arms(torch.nonzero(self.arm_timer <= 0).flatten())
        if cfg.randomization.push_velocity > 0.0:
            self.push_timer -= 1
            pushed = torch.nonzero(self.push_timer <= 0).flatten()
            if len(pushed):
                v = cfg.randomization.push_velocity
                self.qd[pushed, 0:2] += self._uniform((len(pushed), 2), -v, v)
                self._reset_push_timer(pushed)
        if self.terrain is not None:  # the commanded velocity's +x component (a turning world asks for less)
            yaw = self.base_yaw()
            vx_world = self.commands[:, 0] * torch.cos(yaw) - self.commands[:, 1] * torch.sin(yaw)
            self.commanded_x += vx_world.clamp(min=0.0) * cfg.control_dt
        done_ids = torch.nonzero(done).flatten()
        if self.terrain is not None and len(done_ids):
            if self.terrain.update_levels(done_ids, self.q[done_ids, 0], self.commanded_x[done_ids]):
                self.terrain.notify(self.solver)
        self.reset_worlds(done_ids)
        self._hold_heading()
        self.obs, self.critic_obs = self._observations()
        return self.obs, self.critic_obs, reward, fell, timed_out


HumanoidVelocityEnv = G1VelocityEnv
"""the same class under a robot-neutral name"""
