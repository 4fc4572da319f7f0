"""Terrain of the G1 training env: kinds, box heights by level, heights under points, the level
curriculum (pure torch, fast); the batched Newton model with the boxes (a G1 stands on a landing);
a few PPO iterations on terrain resumed from the committed flat-floor checkpoint (slow, 20 s); the
house evaluation end to end (1 s trials, MuJoCo C)."""

from __future__ import annotations

import csv
import importlib.util
import json
import math
import sys
from pathlib import Path

import pytest

torch = pytest.importorskip("torch")

from stages.locomotion.config import (EnvConfig, PPOConfig, Randomization, RewardWeights,  # noqa: E402
                                      TerrainConfig, TrainConfig)
from stages.locomotion.terrain import FLAT, STAIRS, THRESHOLD, TerrainWorlds, world_kinds  # noqa: E402

POLICY = Path(__file__).resolve().parents[2] / "stages/locomotion/policies/g1_velocity"


def _terrain(n=6, **kw):
    gen = torch.Generator().manual_seed(0)
    return TerrainWorlds(TerrainConfig(enabled=True, **kw), n, torch.device("cpu"), gen)


def test_defaults_follow_the_layout_stage_stairs():
    from stages.layout.model import RISE, RUN

    cfg = TerrainConfig()
    assert not cfg.enabled and not EnvConfig().terrain.enabled     # flat training unchanged by default
    assert cfg.stair_rise[1] == RISE[1]
    assert cfg.stair_run == (RUN[0] / 100, RUN[1] / 100)
    assert cfg.threshold_height == (0.01, 0.04)
    with pytest.raises(ValueError, match="stair_rise"):
        EnvConfig(terrain=TerrainConfig(enabled=True, stair_rise=(0.2, 0.1)))


def test_kinds_are_interleaved_by_share():
    kinds = world_kinds(TerrainConfig(kinds=(0.2, 0.3, 0.5)), 10)
    assert torch.bincount(kinds, minlength=3).tolist() == [2, 3, 5]
    assert set(world_kinds(TerrainConfig(kinds=(1, 1, 1)), 3).tolist()) == {FLAT, THRESHOLD, STAIRS}


def test_box_heights_and_height_under_points_by_level():
    t = _terrain(3, kinds=(1, 1, 1), num_boxes=4)
    t.level[:] = torch.tensor([0, 9, 9])
    t.apply(torch.arange(3))
    flat, sill, stairs = (int(torch.nonzero(t.kind == k)) for k in (FLAT, THRESHOLD, STAIRS))
    assert (t.tops[flat] < 0).all()                                       # parked under the ground
    assert torch.allclose(t.tops[sill], torch.full((4,), 0.04))
    assert torch.allclose(t.tops[stairs], 0.19 * torch.arange(1, 5).float())
    run = float(t.run[stairs])
    assert 0.26 <= run <= 0.30
    x0 = t.cfg.start_x
    xs = torch.tensor([x0 - 0.1, x0 + 0.5 * run, x0 + 3.5 * run, float(t.end_x[stairs]) - 0.5 * run,
                       float(t.end_x[stairs]) + 0.1])
    h = torch.stack([t.height_at(torch.tensor([[x, 0.0]] * 3))[stairs] for x in xs])
    assert torch.allclose(h, torch.tensor([0.0, 0.19, 0.76, 0.19, 0.0]), atol=1e-5)
    assert float(t.height_at(torch.tensor([[x0 + 3.5 * run, 1.0]] * 3))[stairs]) == 0.0  # off the lane


def test_curriculum_moves_levels_up_on_success_and_down_on_failure():
    t = _terrain(30, init_max_level=2)
    terr = torch.nonzero(t.kind != FLAT).flatten()
    flat = torch.nonzero(t.kind == FLAT).flatten()
    t.level[terr] = 3
    before = t.tops.clone()
    far = t.end_x + 0.5
    changed = t.update_levels(terr, far[terr], torch.full((len(terr),), 10.0))
    assert changed == len(terr) and (t.level[terr] == 4).all()
    assert (t.tops[terr] > before[terr]).all()                             # higher boxes
    changed = t.update_levels(terr, torch.full((len(terr),), 0.5), torch.full((len(terr),), 10.0))
    assert changed == len(terr) and (t.level[terr] == 3).all()
    # covered most of what was commanded but not the whole lane: stays
    assert t.update_levels(terr, torch.full((len(terr),), 0.9), torch.full((len(terr),), 1.0)) == 0
    # flat worlds never move; past the top level a world gets a random level
    t.update_levels(flat, torch.full((len(flat),), 100.0), torch.ones(len(flat)))
    assert (t.level[flat] == 0).all()
    t.level[terr] = t.cfg.num_levels - 1
    t.update_levels(terr, far[terr], torch.full((len(terr),), 10.0))
    assert (t.level[terr] <= t.cfg.num_levels - 1).all() and (t.level[terr] < t.cfg.num_levels - 1).any()


def test_wide_arm_ranges_reach_counter_height():
    pin = pytest.importorskip("pinocchio")
    import numpy as np

    from stages.locomotion.robot import ARM_JOINTS, DEFAULT_BASE_HEIGHT, DEFAULT_POSE, g1_urdf_path, reach_arm_range

    model = pin.buildModelFromUrdf(str(g1_urdf_path()))
    data = model.createData()
    hand = model.getFrameId("right_wrist_yaw_link")
    rng = np.random.default_rng(0)

    def heights(draw):
        out = []
        for _ in range(300):
            q = pin.neutral(model)
            for name, v in DEFAULT_POSE.items():
                q[model.joints[model.getJointId(name)].idx_q] = v
            for name in ARM_JOINTS:
                j = model.joints[model.getJointId(name)].idx_q
                q[j] = np.clip(draw(name, DEFAULT_POSE.get(name, 0.0)), model.lowerPositionLimit[j],
                               model.upperPositionLimit[j])
            pin.framesForwardKinematics(model, data, q)
            out.append(data.oMf[hand].translation[2] + DEFAULT_BASE_HEIGHT)
        return np.array(out)

    narrow = heights(lambda n, d: d + rng.uniform(-0.6, 0.6))
    wide = heights(lambda n, d: rng.uniform(*reach_arm_range(n)))
    # a hand 10-20 cm above a 0.9 m counter: outside the default draw, well inside the wide one
    assert (narrow > 1.05).mean() < 0.02
    assert (wide > 1.05).mean() > 0.2 and wide.max() > 1.3


@pytest.fixture(scope="module")
def terrain_env():
    pytest.importorskip("newton")
    from stages.locomotion.env import G1VelocityEnv

    return G1VelocityEnv(EnvConfig(num_worlds=3, device="cpu", seed=4,
                                   terrain=TerrainConfig(enabled=True, kinds=(1, 1, 1)),
                                   rewards=RewardWeights(foot_clearance=-1.0),
                                   randomization=Randomization(arm_reach=True, push_velocity=0.0)))


def test_g1_stands_on_the_stairs_landing_of_its_world(terrain_env):
    env = terrain_env
    t = env.terrain
    t.level[t.kind != FLAT] = t.cfg.num_levels - 1
    t.apply(torch.arange(3))
    t.notify(env.solver)
    env.reset_worlds(torch.arange(3))
    s = int(torch.nonzero(t.kind == STAIRS))
    landing = 0.5 * float(t.x_lo[s, -1] + t.x_hi[s, -1])
    env.q[:, 0] = landing
    env.q[:, 2] += t.tops[:, -1].clamp(min=0.0)
    for _ in range(20):
        obs, critic, reward, fell, _ = env.step(torch.zeros(3, env.num_actions))
        assert not fell.any() and torch.isfinite(reward).all()
    top = 0.19 * t.cfg.num_boxes
    assert abs(float(env.q[s, 2]) - (top + 0.74)) < 0.08                  # pelvis over the 1.14 m landing
    for w in range(3):
        if w != s:
            assert float(env.q[w, 2]) < 0.85                               # the other worlds' floors are low
    assert obs.shape == (3, env.num_obs) == (3, 85)                        # the flat policy's observations
    # the stairs world holds a heading (or stands); arm targets come from the wide draw
    assert bool(env.heading_hold[s]) or (env.commands[s] == 0).all()
    assert (env.arm_targets >= env.reach_lo - 1e-6).all() and (env.arm_targets <= env.reach_hi + 1e-6).all()


def test_terrain_commands_keep_yaw_rates_across_the_range(terrain_env):
    env = terrain_env
    t, cfg = env.terrain, env.cfg.terrain
    flat, sill, stairs = (int(torch.nonzero(t.kind == k)) for k in (FLAT, THRESHOLD, STAIRS))
    ids = torch.arange(3)
    yaw = {w: [] for w in range(3)}
    hold = {w: [] for w in range(3)}
    for _ in range(300):
        env._resample_commands(ids)
        for w in range(3):
            hold[w].append(bool(env.heading_hold[w]))
            if not hold[w][-1] and (env.commands[w] != 0).any():
                yaw[w].append(float(env.commands[w, 2]))
        target = env.heading_target[env.heading_hold]
        assert (target.abs() <= cfg.heading_range + 1e-6).all()
        err = torch.atan2(torch.sin(env.heading_target - env.base_yaw()), torch.cos(env.heading_target - env.base_yaw()))
        want = (cfg.heading_gain * err).clamp(-1.0, 1.0)
        assert torch.allclose(env.commands[env.heading_hold, 2], want[env.heading_hold], atol=1e-5)
    assert not any(hold[flat]) and all(hold[stairs][i] or not yaw[stairs] for i in range(300))
    assert not yaw[stairs]                                   # stairs: always a heading (or standing)
    share = sum(hold[sill]) / 300                            # thresholds: turn_fraction of draws turn
    assert abs((1 - share) - (cfg.turn_fraction + (1 - cfg.turn_fraction) * 0.1)) < 0.1
    for w in (flat, sill):                                   # free yaw rates span the whole range
        y = torch.tensor(yaw[w])
        assert y.min() < -0.8 and y.max() > 0.8 and (y.abs() <= 1.0).all()
    assert TerrainConfig().kinds[0] >= 0.4                   # a flat share like mjlab's rough mix


def test_terrain_yaw_kernel_leaves_out_roll_and_pitch_rates():
    from stages.locomotion.rewards import reward_terms

    n, a = 2, 3
    kw = dict(joint_pos=torch.zeros(n, a), default_pos=torch.zeros(a), posture_std=torch.ones(a),
              soft_lo=-torch.ones(a), soft_hi=torch.ones(a), actions=torch.zeros(n, a),
              prev_actions=torch.zeros(n, a), fell=torch.zeros(n, dtype=torch.bool))
    commands = torch.tensor([[0.5, 0.0, 0.8], [0.5, 0.0, 0.8]])
    lin_b = torch.tensor([[0.5, 0.0, 0.3], [0.5, 0.0, 0.3]])
    ang_b = torch.tensor([[1.2, 0.8, 0.8], [1.2, 0.8, 0.0]])             # climbing: pitching and rolling
    flat = reward_terms(RewardWeights(), lin_b=lin_b, ang_b=ang_b, commands=commands, **kw)
    terr = reward_terms(RewardWeights(), lin_b=lin_b, ang_b=ang_b, commands=commands, planar_tracking=True, **kw)
    assert flat["track_ang_vel"][0] < 0.01                                # saturated: turning no longer pays
    assert terr["track_ang_vel"][0] == pytest.approx(1.0)
    assert terr["track_ang_vel"][1] == pytest.approx(math.exp(-0.64 / 0.25))
    assert terr["track_lin_vel"][0] == pytest.approx(1.0) and flat["track_lin_vel"][0] < 1.0
    assert terr["ang_vel_xy"][0] == pytest.approx(1.2 ** 2 + 0.8 ** 2)   # penalized by its own weight


def test_commanded_distance_counts_the_commands_along_the_lane(terrain_env):
    env = terrain_env
    ids = torch.arange(3)
    env.reset_worlds(ids)
    yaw = torch.tensor([0.0, math.pi / 2, math.pi])
    env.q[:, 3:7] = torch.stack([torch.zeros(3), torch.zeros(3), torch.sin(yaw / 2), torch.cos(yaw / 2)], dim=1)
    env.heading_hold[:] = False
    env.commands[:] = torch.tensor([0.8, 0.0, 0.0])
    env.commanded_x[:] = 0.0
    env.step(torch.zeros(3, env.num_actions))
    dt = env.cfg.control_dt
    assert float(env.commanded_x[0]) == pytest.approx(0.8 * dt, rel=0.05)   # facing the lane
    assert float(env.commanded_x[1]) < 0.1 * 0.8 * dt                     # facing across it
    assert float(env.commanded_x[2]) == 0.0                               # facing back


@pytest.mark.slow
def test_ppo_on_terrain_resumes_from_the_flat_checkpoint(tmp_path):
    pytest.importorskip("rsl_rl")
    from stages.locomotion.train import train

    cfg = TrainConfig(env=EnvConfig(num_worlds=3, device="cpu", seed=1, terrain=TerrainConfig(enabled=True),
                                    rewards=RewardWeights(foot_clearance=-1.0)),
                      ppo=PPOConfig(num_steps_per_env=3, num_mini_batches=1, num_learning_epochs=1),
                      iterations=2, save_every=1, checkpoint_dir=str(tmp_path),
                      init_from=str(POLICY / "checkpoint.pt"))
    start = int(json.loads((POLICY / "policy.json").read_text())["iteration"])
    out = train(cfg)
    assert out["iteration"] == start + 2 and (tmp_path / f"model_{start + 2}.pt").is_file()
    rows = list(csv.DictReader((tmp_path / "curve.csv").open()))
    assert int(rows[-1]["iteration"]) == start + 2 and len(rows) == start + 2
    assert rows[-1]["terrain_level"] != "" and float(rows[-1]["terrain_level"]) >= 0.0
    assert float(rows[-1]["term_foot_clearance"]) >= 0.0


def test_house_evaluation_runs_end_to_end(tmp_path):
    pytest.importorskip("newton")
    pytest.importorskip("pinocchio")
    from stages.locomotion.cli import house_main

    out = tmp_path / "house.json"
    assert house_main(["--timeout-s", "1.0", "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    assert [t["trial"] for t in result["trials"]] == ["door", "stairs"]
    assert result["stairs"]["risers"] * result["stairs"]["rise_m"] == pytest.approx(2.82, abs=0.1)
    assert 0.15 <= result["stairs"]["rise_m"] <= 0.19 and result["door"]["threshold_m"] == 0.03
    for t in result["trials"]:
        assert t["success"] + t["fell"] <= 1 and t["time_s"] <= 1.0 + 0.02
    assert house_main(["--policy", str(tmp_path / "missing")]) == 2


def test_house_colliders_need_no_manifold3d(monkeypatch):
    from stages.layout.geometry import build_geometry
    from stages.locomotion.house_eval import house_plan

    plan, _ = house_plan(0)
    full = build_geometry(plan) if importlib.util.find_spec("manifold3d") else None
    monkeypatch.setitem(sys.modules, "manifold3d", None)                  # as on the GPU machines
    with pytest.raises(ImportError):
        build_geometry(plan)
    boxes = build_geometry(plan, meshes=False)
    assert boxes and all(len(e.vertices) == 0 and len(e.faces) == 0 for e in boxes)
    assert any(e.label == "stairs" and e.colliders for e in boxes)
    if full is not None:
        assert [(e.name, e.colliders) for e in boxes] == [(e.name, e.colliders) for e in full]
