"""The environment state's base-velocity entries (``environment_base_velocity``; stages/engine/env_state.py):
the base's measured velocity in its own frame, beside the task's entries, before the gripper's."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from test_env_state import scripted_env


def test_base_velocity_entries_are_the_simulated_base_velocity_in_the_base_frame(kitchen_catalog, tmp_path):
    """A whole scripted open_drawer episode (no cameras) with the base-velocity and gripper entries
    records 8 numbers a frame: the handle and the opening as without them, then base_vx, base_vy
    [m/s], base_vtheta [rad/s] (the planar joints' velocities turned into the base frame: the
    simulation's own reading at the same frame), then the fingers' opening. They show the drive
    (speeds up to the expert's) and the stop (zero while the hand works at the drawer)."""
    pytest.importorskip("newton")
    from stages.engine import EngineConfig
    from stages.engine.env_state import BASE_VELOCITY, GRIPPER, has_base_velocity, state_names

    names = state_names("open_drawer", gripper=True, base_velocity=True)
    assert names == (*state_names("open_drawer"), *BASE_VELOCITY, GRIPPER) and has_base_velocity(names)
    env, frames, probes = scripted_env(kitchen_catalog, tmp_path, "open_drawer", names)
    assert env.shape[1] == 8
    jn = list(probes[0].robot.joint_names)
    ix, iy, iyaw = jn.index("base_x"), jn.index("base_y"), jn.index("base_yaw")
    q = np.array([st.robot.q for st in probes])
    qd = np.array([st.robot.qd for st in probes])
    c, s = np.cos(q[:, iyaw]), np.sin(q[:, iyaw])
    want = np.stack([c * qd[:, ix] + s * qd[:, iy], -s * qd[:, ix] + c * qd[:, iy], qd[:, iyaw]], axis=1)
    np.testing.assert_allclose(env[:, 4:7], want, atol=1e-4)
    assert np.abs(env[:, 4]).max() > 0.3, "the drive shows"
    manip = np.array([f.mode for f in frames]).reshape(-1) == 1
    assert manip.sum() > 30 and np.abs(env[manip][:, 4:7]).max(axis=1).min() < 1e-3, "the stop shows"
    # the base frame's speeds agree with the world pose's motion between frames
    base = np.array([(st.robot.base.x, st.robot.base.y, st.robot.base.theta) for st in probes], np.float64)
    dt = 1.0 / EngineConfig(worlds=1).fps
    vw = np.diff(base[:, :2], axis=0) / dt
    th = base[:-1, 2]
    vb = np.stack([np.cos(th) * vw[:, 0] + np.sin(th) * vw[:, 1], -np.sin(th) * vw[:, 0] + np.cos(th) * vw[:, 1]], 1)
    mid = 0.5 * (env[:-1, 4:6] + env[1:, 4:6])
    assert np.median(np.abs(vb - mid)) < 0.02
    np.testing.assert_allclose(env[:, 7], [sum(st.robot.q[i] for i, n in enumerate(jn) if "finger" in n)
                                           for st in probes], atol=1e-5)


def test_base_velocity_options_are_checked_and_eval_finds_the_layout():
    from types import SimpleNamespace

    from pydantic import ValidationError

    from stages.demos.job import DemosConfig
    from stages.engine.env_state import BASE_VELOCITY, GRIPPER, check_names, state_names
    from stages.policy.evaluate import EvalConfig, env_layout

    assert DemosConfig(tasks=("open_drawer",), environment_state=True,
                       environment_base_velocity=True).environment_base_velocity
    with pytest.raises(ValidationError, match="environment_base_velocity needs environment_state"):
        DemosConfig(tasks=("open_drawer",), environment_base_velocity=True)
    with pytest.raises(ValueError, match="has environment state"):
        check_names(state_names("open_drawer", base_velocity=True)[:-1], "open_drawer", "test")
    cfg = EvalConfig(checkpoint=Path("ck"), tasks=("open_drawer",), scenes=(101,), seeds=(1,))
    assert env_layout(cfg, SimpleNamespace(env_state_dim=7, env_state_names=None))[-3:] == BASE_VELOCITY
    got = env_layout(cfg, SimpleNamespace(env_state_dim=8, env_state_names=None))
    assert got[-1] == GRIPPER and got[-4:-1] == BASE_VELOCITY
    assert env_layout(cfg, SimpleNamespace(env_state_dim=5, env_state_names=None))[-1] == GRIPPER


def test_eval_takes_the_environment_layout_the_checkpoint_names(tmp_path):
    """agentworld_policy.json's environment-state names choose the layout (not the size alone);
    names of another size or of no task layout fail in one line naming the file or checkpoint."""
    from types import SimpleNamespace

    from stages.engine.env_state import state_names
    from stages.policy.evaluate import EvalConfig, env_layout
    from stages.policy.runner import POLICY_INFO, read_policy_info

    cfg = EvalConfig(checkpoint=Path("ck"), tasks=("open_drawer",), scenes=(101,), seeds=(1,))
    both = state_names("open_drawer", gripper=True, base_velocity=True)
    assert env_layout(cfg, SimpleNamespace(env_state_dim=8, env_state_names=both)) == both
    swapped = both[:4] + both[5:7] + both[4:5] + both[7:]  # a layout of the right size in no task's order
    with pytest.raises(ValueError, match="ck: the policy's environment state .* is none of the tasks' layouts"):
        env_layout(cfg, SimpleNamespace(env_state_dim=8, env_state_names=swapped))
    info = {"state": [f"s{i}" for i in range(3)], "environment_state": list(both)}
    (tmp_path / POLICY_INFO).write_text(json.dumps(info))
    assert read_policy_info(tmp_path, 3, 8) == (tuple(info["state"]), both)
    with pytest.raises(ValueError, match=f"{POLICY_INFO}: 8 environment-state names for a policy environment state"):
        read_policy_info(tmp_path, 3, 5)
    (tmp_path / POLICY_INFO).write_text(json.dumps({"state": [], "environment_state": []}))
    assert read_policy_info(tmp_path, 3, 8) == (None, None)
    (tmp_path / POLICY_INFO).write_text("[1, 2]")
    with pytest.raises(ValueError, match="unreadable"):
        read_policy_info(tmp_path, 3, 8)
    assert read_policy_info(tmp_path / "none", 3, 8) == (None, None)
