"""Humanoid runtime: the trained velocity policy drives the legs and waist, CLIK drives the arms,
batched over the worlds of one Newton model (CPU or CUDA).

Per control step (``policy.json``'s ``control_dt``, 0.02 s: every ``decimation`` physics steps):

1. observations from the simulation state, built exactly as in training (``env.G1VelocityEnv``,
   without the training noise): base linear and angular velocity in the base frame, projected
   gravity, the command, joint positions relative to the policy's default pose and joint
   velocities (29 joints in ``policy.json``'s order) and the last actions;
2. the policy's actions (N, A) -> PD position targets of its joints: ``default + scale * action``
   [rad] (legs and waist);
3. the arms: for each world and arm with an end-effector target (world or base frame), the CLIK
   goal moves from the hand's pose towards the target at most ``ee_speed`` / ``ee_turn_rate``
   (a jump of the arm pushes the body: the policy steps); ``UpperBodyClik`` solves for it from the
   measured configuration (legs and waist as simulated, extrapolated ``clik_lookahead_s``; arms
   warm-started from the last solution) in the pelvis frame, a world-frame goal being moved into
   the measured pelvis frame every step; the solution becomes the arm joints' PD targets. Arms without a target hold the policy's
   default pose. Optional gravity feed-forward (``Control.joint_f``) on the arm joints: the
   Pinocchio gravity torques of the arms for the measured pelvis orientation, so that the PD
   targets are reached without sag.

4. the hands (a spec whose end effectors are hands, e.g. ``g1_29dof_dex3``: the model holds the
   G1 with its 14 Dex3 joints, ``hands.humanoid_for_spec``): PD targets from each hand's command,
   0 open .. 1 closed, between the spec's open and closed poses (``hands.HandCommands``); the
   policy's observations stay the 29 body joints'.

The base interface is the wheeled base's: a command (vx, vy, v_theta) per world in the base frame
[m/s, m/s, rad/s], clipped to the policy's training ranges; and a mode per world:
``Mode.LOCOMOTION`` tracks the command, ``Mode.MANIPULATION`` commands zero velocity so the policy
holds the legs' posture while the arms reach.

Shapes: N worlds, J = 29 joints, A = 15 policy actions, O = 12 + 2 J + A observations.
:class:`HumanoidWorlds` wires the runtime to a model of N G1 worlds (by default built as in
training, ``robot.build_g1_model``; ``scene.build_humanoid_scene`` puts them in a scene USD) with
its solver and states: the loop the tests, ``runtime_eval`` and the kitchen reach run.
The policy was trained with arm targets within 0.6 rad of the default pose; reaches far outside
that (the hand at chest height) make it step while standing (measured: 20 cm).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import IntEnum
from pathlib import Path
from typing import Any

import numpy as np
import torch

from stages.embodiment.clik import ClikConfig
from stages.locomotion.hands import HandCommands, hand_arms

DEFAULT_POLICY = Path(__file__).resolve().parent / "policies" / "g1_velocity"
GRAVITY = np.array([0.0, 0.0, -9.81])
"""[m/s^2], the Newton model's default gravity"""


class Mode(IntEnum):
    """The action's last value: what the base does."""

    LOCOMOTION = 0
    MANIPULATION = 1


@dataclass(frozen=True, kw_only=True)
class LeggedRuntimeConfig:
    """A legged-with-policy base and its upper body."""

    policy: str = str(DEFAULT_POLICY)
    """exported policy folder (``policy.pt`` + ``policy.json``)"""
    spec: str = "g1_29dof"
    """embodiment spec whose arms CLIK solves (its Pinocchio model gives the arms' gravity torques)"""
    device: str = "cpu"
    """torch device of the policy and the observation tensors; the model's device must agree"""
    root_body: str = "pelvis"
    """the floating base's body (its free joint's child)"""
    clik: ClikConfig = field(default_factory=lambda: ClikConfig(max_iters=30))
    """CLIK per control step (warm-started: a few iterations track a moving target)"""
    ee_speed: float = 0.3
    """largest speed of the CLIK goal towards an end-effector target [m/s]"""
    ee_turn_rate: float = 1.0
    """largest turn rate of the CLIK goal towards an end-effector target [rad/s]"""
    clik_lookahead_s: float = 0.08
    """CLIK solves for the base pose and leg/waist joints extrapolated this far ahead [s] at their
    measured velocities: the arms' PD (10 Hz, damping ratio 2) lags its targets by about 60 ms and
    the policy sways the standing body by about a centimetre (measured, G1 standing, two worlds:
    mean hand error 8.8 / 12.3 mm with 0, 4.1 / 10.0 mm with 0.08 s)"""
    arm_gravity_feedforward: bool = True
    """add the arms' gravity torques [N m] to ``Control.joint_f`` (else the PD sags under the arms' weight)"""
    clip_commands: bool = True
    """clip commands to the policy's training ranges (``policy.json`` ``command_ranges``)"""


@dataclass(frozen=True)
class WorldIndex:
    """Where each world's humanoid sits in the model's flat arrays (torch long tensors).

    root_q (N,): first coordinate of the free joint (position xyz [m], quaternion xyzw);
    root_qd (N,): first DoF (linear velocity then angular velocity, world frame [m/s, rad/s]);
    joint_q (N, J) / joint_qd (N, J): coordinate / DoF index of each named joint."""

    root_q: torch.Tensor
    root_qd: torch.Tensor
    joint_q: torch.Tensor
    joint_qd: torch.Tensor


def index_worlds(model: Any, joint_names: Sequence[str], root_body: str = "pelvis",
                 device: str = "cpu") -> WorldIndex:
    """Find, in every world of ``model``, the free joint whose child is ``root_body`` and the named
    joints (matched by the last component of their labels). Raises ValueError listing every world
    that lacks one of them."""
    labels = [lbl.rsplit("/", 1)[-1] for lbl in model.joint_label]
    body_labels = [lbl.rsplit("/", 1)[-1] for lbl in model.body_label]
    jworld = model.joint_world.numpy()
    jtype = model.joint_type.numpy()
    child = model.joint_child.numpy()
    q_start, qd_start = model.joint_q_start.numpy(), model.joint_qd_start.numpy()
    free = 4  # newton.JointType.FREE
    worlds = model.world_count
    root_q, root_qd = np.zeros(worlds, np.int64), np.zeros(worlds, np.int64)
    jq, jqd = np.zeros((worlds, len(joint_names)), np.int64), np.zeros((worlds, len(joint_names)), np.int64)
    problems = []
    for w in range(worlds):
        in_world = np.flatnonzero(jworld == w)
        roots = [j for j in in_world if jtype[j] == free and body_labels[child[j]] == root_body]
        by_name = {}
        for j in in_world:
            by_name.setdefault(labels[j], j)
        missing = [n for n in joint_names if n not in by_name]
        if len(roots) != 1 or missing:
            problems.append(f"world {w}: {len(roots)} free joints with child {root_body!r}, missing {missing}")
            continue
        root_q[w], root_qd[w] = q_start[roots[0]], qd_start[roots[0]]
        jq[w] = [q_start[by_name[n]] for n in joint_names]
        jqd[w] = [qd_start[by_name[n]] for n in joint_names]
    if problems:
        raise ValueError("humanoid runtime: " + "; ".join(problems))
    t = lambda a: torch.as_tensor(a, dtype=torch.long, device=device)  # noqa: E731
    return WorldIndex(t(root_q), t(root_qd), t(jq), t(jqd))


def quat_rotate_inverse(q_xyzw: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Rotate world vectors into the frame of unit quaternions: (N, 4) xyzw, (N, 3) -> (N, 3)."""
    qv, w = q_xyzw[:, :3], q_xyzw[:, 3:4]
    t = 2.0 * torch.linalg.cross(qv, v, dim=1)
    return v - w * t + torch.linalg.cross(qv, t, dim=1)


def pose_matrices(pos: np.ndarray, quat_xyzw: np.ndarray) -> np.ndarray:
    """4x4 poses (N, 4, 4) from positions (N, 3) [m] and unit quaternions (N, 4) xyzw."""
    x, y, z, w = (quat_xyzw[:, k] for k in range(4))
    m = np.zeros((len(pos), 4, 4))
    m[:, 0, 0], m[:, 0, 1], m[:, 0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)
    m[:, 1, 0], m[:, 1, 1], m[:, 1, 2] = 2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)
    m[:, 2, 0], m[:, 2, 1], m[:, 2, 2] = 2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)
    m[:, :3, 3], m[:, 3, 3] = pos, 1.0
    return m


class LeggedPolicyRuntime:
    """The policy and CLIK of N humanoid worlds in one Newton model.

    Call :meth:`control_step` once per control period (``control_dt`` [s]) before the model's
    ``decimation`` physics steps; it reads ``state`` and writes ``control.joint_target_q`` (the
    humanoid's 29 joints) and, with gravity feed-forward, ``control.joint_f`` (arm DoFs).
    Commands, modes and end-effector targets persist until changed.
    """

    def __init__(self, model: Any, cfg: LeggedRuntimeConfig | None = None) -> None:
        from stages.embodiment import load_spec
        from stages.embodiment.clik import UpperBodyClik
        from stages.embodiment.kinematics import build_model
        from stages.embodiment.sources import resolve_description
        from stages.locomotion.policy import PolicyRuntime

        self.cfg = cfg = cfg or LeggedRuntimeConfig()
        self.device = dev = torch.device(cfg.device)
        if bool(model.device.is_cuda) != (dev.type == "cuda"):
            raise ValueError(f"humanoid runtime: model on {model.device}, runtime on {cfg.device}")
        self.model = model
        self.policy = PolicyRuntime.load(cfg.policy, device=cfg.device)
        meta = self.policy.meta
        self.control_dt: float = float(meta["control_dt"])
        """control period [s]"""
        self.joint_names: tuple[str, ...] = tuple(meta["default_pos"])
        self.policy_joints: tuple[str, ...] = tuple(meta["policy_joints"])
        self.num_worlds = n = model.world_count
        self.index = index_worlds(model, self.joint_names, cfg.root_body, cfg.device)
        f32 = dict(dtype=torch.float32, device=dev)
        self.default_q = torch.tensor([meta["default_pos"][j] for j in self.joint_names], **f32)
        self.act_cols = torch.tensor([self.joint_names.index(j) for j in self.policy_joints], device=dev)
        self.action_scale = torch.tensor([meta["action_scale"][j] for j in self.policy_joints], **f32)
        lo, hi = zip(*(meta["command_ranges"][k] for k in ("vx", "vy", "yaw_rate")), strict=True)
        self.command_low, self.command_high = torch.tensor(lo, **f32), torch.tensor(hi, **f32)
        self.num_actions = len(self.policy_joints)
        self.num_obs = int(meta["num_obs"])
        if self.num_obs != 12 + 2 * len(self.joint_names) + self.num_actions:
            raise ValueError(f"{cfg.policy}: num_obs {self.num_obs} does not match its joints")

        self.commands = torch.zeros(n, 3, **f32)
        """commanded (vx [m/s], vy [m/s], v_theta [rad/s]) in the base frame, (N, 3)"""
        self.mode = torch.full((n,), int(Mode.LOCOMOTION), dtype=torch.long, device=dev)
        self.actions = torch.zeros(n, self.num_actions, **f32)
        """last actions (N, A), part of the next observation"""

        # upper body: Pinocchio model of the spec, CLIK, arm columns
        self.spec = load_spec(cfg.spec)
        self.pin_model = build_model(self.spec, resolve_description(self.spec.description).path)
        self.clik = UpperBodyClik(self.spec, self.pin_model, cfg.clik)
        kin = self.clik.kin
        hand_names = [j for a in hand_arms(self.spec)
                      for j in self.spec.end_effectors[self.spec.arm(a).end_effector].joints]
        missing = [j for j in (*self.joint_names, *hand_names) if j not in kin.idx_q]
        if missing or self.pin_model.nq != len(self.joint_names) + len(hand_names):
            raise ValueError(f"humanoid runtime: spec {cfg.spec!r} does not have the policy's and hands' "
                             f"joints {missing}")
        self._pin_cols = np.array([kin.idx_q[j] for j in self.joint_names])   # sim order -> Pinocchio q
        self.hands = HandCommands(self.spec, index_worlds(model, hand_names, cfg.root_body, cfg.device)
                                  if hand_names else None,
                                  np.array([kin.idx_q[j] for j in hand_names], int), n, dev)
        """the hands' commands (0 open .. 1 closed per world and hand): PD targets of the hand joints"""
        self.arm_names: tuple[str, ...] = tuple(self.clik.arms)
        self._arm_cols = {a: np.array([self.joint_names.index(j) for j in self.spec.arm(a).joints])
                          for a in self.arm_names}
        self.ee_targets = {a: np.tile(np.eye(4), (n, 1, 1)) for a in self.arm_names}
        """per arm: end-effector target poses (N, 4, 4) [m], world or base frame (``ee_in_base``)"""
        self.ee_in_base = {a: np.zeros(n, bool) for a in self.arm_names}
        """per arm: (N,) whether the world's target is in the base frame (else the world frame)"""
        self.ee_active = {a: np.zeros(n, bool) for a in self.arm_names}
        self.ee_goals = {a: np.tile(np.eye(4), (n, 1, 1)) for a in self.arm_names}
        """per arm: the poses (N, 4, 4) CLIK solves for, in the target's frame: they move from the hand's
        pose when the target was set towards the target at ``ee_speed`` / ``ee_turn_rate``"""
        self._ee_fresh = {a: np.zeros(n, bool) for a in self.arm_names}
        """per arm: (N,) whether the world's arm follows its target (else it holds the default pose)"""
        self.arm_q = np.tile(self.default_q.cpu().numpy().astype(float), (n, 1))
        """arm joint targets (N, J) [rad] in sim order (only the arms' columns are used)"""
        self.last_clik: dict[str, Any] = {}
        """per arm: the ClikResult of the last control step that solved it (for diagnostics)"""
        self._pin_data = self.pin_model.createData()
        self._all_arm_cols = np.concatenate([self._arm_cols[a] for a in self.arm_names])
        self._all_arm_cols_t = torch.as_tensor(self._all_arm_cols, device=dev)
        self._arm_v = np.array([kin.idx_v[self.joint_names[c]] for c in self._all_arm_cols])

    # ------------------------------------------------------------------ the shared base interface
    def set_command(self, commands: Any, worlds: Any = None) -> None:
        """Base-frame velocity commands (K, 3) or (3,) [m/s, m/s, rad/s] for worlds (K,) (default: all)."""
        c = torch.as_tensor(np.asarray(commands, np.float32), device=self.device)
        sel = slice(None) if worlds is None else torch.as_tensor(worlds, dtype=torch.long, device=self.device)
        if self.cfg.clip_commands:
            c = torch.maximum(torch.minimum(c, self.command_high), self.command_low)
        self.commands[sel] = c

    def set_mode(self, mode: Any, worlds: Any = None) -> None:
        """Mode per world (K,) or one for all: ``Mode.LOCOMOTION`` (0) or ``Mode.MANIPULATION`` (1)."""
        sel = slice(None) if worlds is None else torch.as_tensor(worlds, dtype=torch.long, device=self.device)
        self.mode[sel] = torch.as_tensor(np.asarray(mode, np.int64), device=self.device)

    def set_ee_target(self, arm: str, poses: np.ndarray, worlds: Any = None, *, frame: str = "world") -> None:
        """End-effector target poses of ``arm``, (K, 4, 4) or (4, 4) [m], for worlds (K,) (default:
        all); those worlds' arm then follows it. ``frame``: "world" (a fixed place: re-expressed in
        the measured base frame every control step) or "base" (relative to the base's root link:
        carried along while walking)."""
        if frame not in ("world", "base"):
            raise ValueError(f"frame must be 'world' or 'base', got {frame!r}")
        sel = np.arange(self.num_worlds) if worlds is None else np.asarray(worlds, int)
        self.ee_targets[arm][sel] = np.asarray(poses, float)
        self.ee_in_base[arm][sel] = frame == "base"
        self.ee_active[arm][sel] = True
        self._ee_fresh[arm][sel] = True

    def release_arm(self, arm: str, worlds: Any = None) -> None:
        """Stop following ``arm``'s target in worlds (K,) (default: all): back to the default pose."""
        sel = np.arange(self.num_worlds) if worlds is None else np.asarray(worlds, int)
        self.ee_active[arm][sel] = False
        self.arm_q[np.ix_(sel, self._arm_cols[arm])] = self.default_q.cpu().numpy()[self._arm_cols[arm]]

    def reset(self, worlds: Any = None) -> None:
        """Forget the last actions and arm targets of worlds (K,) (default: all), e.g. after a reset."""
        sel = slice(None) if worlds is None else torch.as_tensor(worlds, dtype=torch.long, device=self.device)
        self.actions[sel] = 0.0
        self.hands.command[sel if worlds is None else np.asarray(worlds, int)] = 0.0
        for a in self.arm_names:
            self.release_arm(a, None if worlds is None else np.asarray(worlds, int))

    # ------------------------------------------------------------------ reading the state
    def _views(self, state: Any) -> tuple[torch.Tensor, torch.Tensor]:
        import warp as wp

        return wp.to_torch(state.joint_q), wp.to_torch(state.joint_qd)

    def base_state(self, state: Any) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """(position (N, 3) [m], quaternion (N, 4) xyzw, linear velocity (N, 3) [m/s] and angular
        velocity (N, 3) [rad/s] in the world frame) of each world's base."""
        q, qd = self._views(state)
        ix = self.index
        pos = q[ix.root_q[:, None] + torch.arange(3, device=self.device)]
        quat = q[ix.root_q[:, None] + 3 + torch.arange(4, device=self.device)]
        lin = qd[ix.root_qd[:, None] + torch.arange(3, device=self.device)]
        ang = qd[ix.root_qd[:, None] + 3 + torch.arange(3, device=self.device)]
        return pos, quat, lin, ang

    def base_velocity_b(self, state: Any) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(linear velocity (N, 3) [m/s], angular velocity (N, 3) [rad/s], projected gravity (N, 3))
        in each world's base frame."""
        _, quat, lin, ang = self.base_state(state)
        down = torch.tensor([0.0, 0.0, -1.0], device=self.device).expand_as(lin)
        return quat_rotate_inverse(quat, lin), quat_rotate_inverse(quat, ang), quat_rotate_inverse(quat, down)

    def joint_state(self, state: Any) -> tuple[torch.Tensor, torch.Tensor]:
        """Joint positions (N, J) [rad] and velocities (N, J) [rad/s] in the policy's joint order."""
        q, qd = self._views(state)
        return q[self.index.joint_q], qd[self.index.joint_qd]

    def effective_commands(self) -> torch.Tensor:
        """The commands the policy sees (N, 3): zero in manipulation mode."""
        manip = (self.mode == int(Mode.MANIPULATION))[:, None]
        return torch.where(manip, torch.zeros_like(self.commands), self.commands)

    def observations(self, state: Any) -> torch.Tensor:
        """The policy's observations (N, O), as ``env.G1VelocityEnv`` builds them (without noise)."""
        lin_b, ang_b, grav = self.base_velocity_b(state)
        jq, jqd = self.joint_state(state)
        return torch.cat([lin_b, ang_b, grav, self.effective_commands(), jq - self.default_q, jqd, self.actions],
                         dim=1)

    def ee_pose_world(self, state: Any, arm: str) -> np.ndarray:
        """Measured end-effector poses of ``arm`` (N, 4, 4), world frame [m]."""
        root, q = self._host_state(state)
        return root @ self.clik.ee_pose(q, arm)

    def _host_state(self, state: Any, lookahead: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Base poses (N, 4, 4) and Pinocchio configurations (N, nq) on the host, extrapolated
        ``lookahead`` [s] ahead at the current velocities (base and non-arm joints; 0: as measured)."""
        pos, quat, lin, ang = (t.detach().cpu().double().numpy() for t in self.base_state(state))
        jq, jqd = (t.detach().cpu().double().numpy() for t in self.joint_state(state))
        root = pose_matrices(pos, quat)
        if lookahead > 0.0:
            from scipy.spatial.transform import Rotation

            root[:, :3, 3] += lookahead * lin
            root[:, :3, :3] = Rotation.from_rotvec(lookahead * ang).as_matrix() @ root[:, :3, :3]
            moving = np.ones(jq.shape[1], bool)
            moving[self._all_arm_cols] = False
            jq[:, moving] += lookahead * jqd[:, moving]
        q = np.empty((self.num_worlds, self.pin_model.nq))
        q[:, self._pin_cols] = jq
        if self.hands.names:
            q[:, self.hands.pin_cols] = self.hands.positions(self._views(state)[0])
        return root, q

    # ------------------------------------------------------------------ one control step
    @torch.inference_mode()
    def control_step(self, state: Any, control: Any) -> torch.Tensor:
        """Policy and CLIK for all worlds: writes the joint targets into ``control``; returns the
        actions (N, A)."""
        import warp as wp

        obs = self.observations(state)
        actions = self.policy.act(obs).clamp(-100.0, 100.0)
        self.actions.copy_(actions)
        targets = wp.to_torch(control.joint_target_q)
        root, q = self._host_state(state)
        la = self.cfg.clik_lookahead_s
        self._solve_arms(*(self._host_state(state, la) if la > 0.0 else (root, q)))
        arm_t = torch.as_tensor(self.arm_q[:, self._all_arm_cols], dtype=targets.dtype, device=self.device)
        targets[self.index.joint_q[:, self._all_arm_cols_t]] = arm_t
        legs = self.default_q[self.act_cols] + self.action_scale * actions
        targets[self.index.joint_q[:, self.act_cols]] = legs.to(targets.dtype)
        self.hands.write(targets)
        if self.cfg.arm_gravity_feedforward:
            forces = wp.to_torch(control.joint_f)
            tau = self.arm_gravity(root, q)
            forces[self.index.joint_qd[:, self._all_arm_cols_t]] = torch.as_tensor(tau, dtype=forces.dtype,
                                                                                   device=self.device)
        return actions

    def _solve_arms(self, root: np.ndarray, q: np.ndarray) -> None:
        """CLIK of every active (world, arm) from the measured configuration ``q`` (N, nq), goals
        moved into the measured base frames ``root`` (N, 4, 4); updates ``arm_q``."""
        active = [a for a in self.arm_names if self.ee_active[a].any()]
        if not active:
            return
        rows = np.flatnonzero(np.any([self.ee_active[a] for a in active], axis=0))
        q0 = q[rows]
        for a in self.arm_names:                         # warm start: the arms' last solution
            cols = self._arm_cols[a]
            q0[:, self._pin_cols[cols]] = self.arm_q[np.ix_(rows, cols)]
        inv_root = np.linalg.inv(root[rows])
        for a in active:
            sub = np.flatnonzero(self.ee_active[a][rows])
            in_base = self.ee_in_base[a][rows[sub]][:, None, None]
            self._advance_goals(a, rows[sub], root[rows[sub]], q[rows[sub]])
            goal_frame = self.ee_goals[a][rows[sub]]
            goal = np.where(in_base, goal_frame, inv_root[sub] @ goal_frame)
            res = self.clik.solve({a: goal}, q0[sub])
            self.last_clik[a] = res
            cols = self._arm_cols[a]
            self.arm_q[np.ix_(rows[sub], cols)] = res.q[:, self._pin_cols[cols]]

    def _advance_goals(self, arm: str, rows: np.ndarray, root: np.ndarray, q: np.ndarray) -> None:
        """Move the CLIK goals of ``arm`` in worlds ``rows`` one control step towards their targets
        (rate-limited: a target far from the hand does not make the arm jump and push the body)."""
        from scipy.spatial.transform import Rotation

        fresh = self._ee_fresh[arm][rows]
        if fresh.any():                                   # start from the hand's measured pose
            hand_b = self.clik.ee_pose(q[fresh], arm)
            in_base = self.ee_in_base[arm][rows[fresh]][:, None, None]
            self.ee_goals[arm][rows[fresh]] = np.where(in_base, hand_b, root[fresh] @ hand_b)
            self._ee_fresh[arm][rows[fresh]] = False
        goal, target = self.ee_goals[arm][rows], self.ee_targets[arm][rows]
        dp = target[:, :3, 3] - goal[:, :3, 3]
        dist = np.linalg.norm(dp, axis=1, keepdims=True)
        step = self.cfg.ee_speed * self.control_dt
        goal[:, :3, 3] += dp * np.minimum(1.0, step / np.maximum(dist, 1e-12))
        rel = Rotation.from_matrix(np.swapaxes(goal[:, :3, :3], 1, 2) @ target[:, :3, :3]).as_rotvec()
        angle = np.linalg.norm(rel, axis=1, keepdims=True)
        turn = self.cfg.ee_turn_rate * self.control_dt
        rel *= np.minimum(1.0, turn / np.maximum(angle, 1e-12))
        goal[:, :3, :3] = goal[:, :3, :3] @ Rotation.from_rotvec(rel).as_matrix()
        self.ee_goals[arm][rows] = goal

    def arm_gravity(self, root: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Gravity torques [N m] (N, 2 x 7) of the arm joints (all arms' joints in arm order) for
        base poses ``root`` (N, 4, 4) and configurations ``q`` (N, nq): Pinocchio's generalized
        gravity of the model fixed at the base, gravity expressed in the base frame."""
        import pinocchio as pin

        tau = np.zeros((len(q), len(self._all_arm_cols)))
        model, data = self.pin_model, self._pin_data
        for w in range(len(q)):
            model.gravity.linear = root[w, :3, :3].T @ GRAVITY
            tau[w] = pin.computeGeneralizedGravity(model, data, q[w])[self._arm_v]
        return tau


@dataclass(frozen=True, kw_only=True)
class HumanoidWorldsConfig:
    """N G1 worlds on a flat floor, simulated as in training (SolverMuJoCo, 200 Hz)."""

    num_worlds: int = 2
    device: str = "cpu"
    runtime: LeggedRuntimeConfig = field(default_factory=LeggedRuntimeConfig)
    solver_iterations: int = 10
    ls_iterations: int = 20
    foot_mu: float = 0.6
    """feet's friction coefficient (training randomizes 0.3-1.2)"""
    use_mujoco_cpu: bool | None = None
    """MuJoCo C instead of MuJoCo-Warp; None: on a CPU with one world (measured in a task kitchen:
    1.5 s per simulated second against 19 s for MuJoCo-Warp's CPU path, same trajectory to 1 mm)"""


class HumanoidWorlds:
    """N G1 worlds, their SolverMuJoCo, states and a :class:`LeggedPolicyRuntime`. By default the
    model is ``robot.build_g1_model`` (the training robot on a flat floor); ``model`` gives another
    one holding one G1 per world (e.g. ``scene.build_humanoid_scene``: a G1 in a task kitchen) and
    ``solver_options`` its SolverMuJoCo options (contact buffers). ``step()`` runs one control
    step: the runtime, then ``decimation`` physics steps. ``state`` is the current state."""

    def __init__(self, cfg: HumanoidWorldsConfig | None = None, *, model: Any = None,
                 solver_options: dict[str, Any] | None = None) -> None:
        import newton
        import warp as wp

        from stages.locomotion.humanoids import humanoid
        from stages.locomotion.policy import policy_humanoid
        from stages.locomotion.robot import build_humanoid_model

        self.cfg = cfg = cfg or HumanoidWorldsConfig()
        rt_cfg = cfg.runtime if cfg.runtime.device == cfg.device else _with_device(cfg.runtime, cfg.device)
        if model is None:  # the robot the policy was trained on (policy.json's humanoid), the spec's hands
            from stages.embodiment import load_spec
            from stages.locomotion.hands import humanoid_for_spec

            desc = humanoid_for_spec(load_spec(rt_cfg.spec), humanoid(policy_humanoid(rt_cfg.policy)))
            model, _ = build_humanoid_model(desc, cfg.num_worlds, wp.get_device(cfg.device), foot_mu=cfg.foot_mu)
        self.model = model
        self.runtime = LeggedPolicyRuntime(self.model, rt_cfg)
        meta = self.runtime.policy.meta
        self.sim_dt, self.decimation = float(meta["sim_dt"]), int(meta["decimation"])
        cpu = cfg.use_mujoco_cpu if cfg.use_mujoco_cpu is not None else (
            not model.device.is_cuda and model.world_count == 1)
        options = dict(iterations=cfg.solver_iterations, ls_iterations=cfg.ls_iterations, nconmax=24, njmax=160,
                       use_mujoco_cpu=cpu)
        options.update(solver_options or {})
        self.solver = newton.solvers.SolverMuJoCo(self.model, **options)
        self.state, self._next = self.model.state(), self.model.state()
        self.control = self.model.control()
        q = wp.to_torch(self.state.joint_q)
        self.home = q[self.runtime.index.root_q[:, None] + torch.arange(7, device=self.runtime.device)].clone()
        """each world's initial base pose (N, 7): position [m], quaternion xyzw"""
        self.time = 0.0
        """simulated time [s]"""

    def step(self) -> torch.Tensor:
        """One control step for all worlds; returns the actions (N, A)."""
        import warp as wp

        actions = self.runtime.control_step(self.state, self.control)
        if self.runtime.device.type == "cuda":
            torch.cuda.current_stream(self.runtime.device).synchronize()
        for _ in range(self.decimation):
            self.solver.step(self.state, self._next, self.control, None, self.sim_dt)
            self.state, self._next = self._next, self.state
        wp.synchronize_device(self.model.device)
        self.time += self.sim_dt * self.decimation
        return actions

    def reset(self, worlds: Any = None, *, xy: Any = None, yaw: Any = None) -> None:
        """Put worlds (K,) (default: all) back standing in the default pose, at rest, at their
        initial base pose (``home``) or at base position ``xy`` (K, 2) [m] with heading ``yaw`` (K,)
        [rad]; their commands, modes and arm targets are cleared."""
        import warp as wp

        rt = self.runtime
        ids = np.arange(rt.num_worlds) if worlds is None else np.asarray(worlds, int)
        k = len(ids)
        root = self.home[torch.as_tensor(ids, device=rt.device)].cpu().double().numpy()
        if xy is not None:
            root[:, :2] = np.broadcast_to(np.asarray(xy, float), (k, 2))
        if yaw is not None:
            yaw = np.broadcast_to(np.asarray(yaw, float), (k,))
            root[:, 3:7] = 0.0
            root[:, 5], root[:, 6] = np.sin(yaw / 2), np.cos(yaw / 2)
        dev = rt.device
        t_ids = torch.as_tensor(ids, device=dev)
        ix = rt.index
        for st in (self.state, self._next):
            q, qd = wp.to_torch(st.joint_q), wp.to_torch(st.joint_qd)
            q[ix.root_q[t_ids][:, None] + torch.arange(7, device=dev)] = torch.as_tensor(root, dtype=q.dtype,
                                                                                          device=dev)
            q[ix.joint_q[t_ids]] = rt.default_q.to(q.dtype)
            qd[ix.root_qd[t_ids][:, None] + torch.arange(6, device=dev)] = 0.0
            qd[ix.joint_qd[t_ids]] = 0.0
        wp.to_torch(self.control.joint_target_q)[ix.joint_q[t_ids]] = rt.default_q
        wp.to_torch(self.control.joint_f)[ix.joint_qd[t_ids]] = 0.0
        views = [(wp.to_torch(st.joint_q), wp.to_torch(st.joint_qd)) for st in (self.state, self._next)]
        rt.hands.reset(ids, views, wp.to_torch(self.control.joint_target_q))
        rt.reset(ids)
        rt.set_command(np.zeros((k, 3)), ids)
        rt.set_mode(np.full(k, int(Mode.LOCOMOTION)), ids)

    def run(self, seconds: float) -> None:
        """Control steps for ``seconds`` [s] of simulated time."""
        for _ in range(int(round(seconds / self.runtime.control_dt))):
            self.step()


def _with_device(cfg: LeggedRuntimeConfig, device: str) -> LeggedRuntimeConfig:
    from dataclasses import replace

    return replace(cfg, device=device)
