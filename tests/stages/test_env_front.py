"""The environment state's front entries (``environment_front``; stages/engine/env_state.py): the
articulated part front's planar direction in the robot's base frame, after the part's opening."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from test_env_state import scripted_env


def test_front_entries_are_the_drawer_axis_the_simulation_moves_the_handle_along(kitchen_catalog, tmp_path):
    """A whole scripted open_drawer episode (no cameras) with the front and gripper entries records
    7 numbers a frame: the handle and the opening as without them, then front_x, front_y (a unit
    vector), then the fingers' opening. Turned into the world by the simulated base yaw, the front
    is the direction the simulation moved the handle along while the drawer opened (the handle's
    recorded points turned back into the world by the simulated base pose), within 2 degrees, at
    every frame: it turns with the base as the base drives and stays fixed in the world."""
    pytest.importorskip("newton")
    from stages.engine.env_state import FRONT, GRIPPER, has_front, state_names

    names = state_names("open_drawer", gripper=True, front=True)
    assert names == (*state_names("open_drawer"), *FRONT, GRIPPER) and has_front(names)
    env, _, probes = scripted_env(kitchen_catalog, tmp_path, "open_drawer", names)
    np.testing.assert_allclose(np.hypot(env[:, 4], env[:, 5]), 1.0, atol=1e-5)
    base = np.array([(st.robot.base.x, st.robot.base.y, st.robot.base.theta) for st in probes], np.float64)
    c, s = np.cos(base[:, 2]), np.sin(base[:, 2])
    handle = np.stack([base[:, 0] + c * env[:, 0] - s * env[:, 1], base[:, 1] + s * env[:, 0] + c * env[:, 1]], 1)
    moved = handle[np.argmax(env[:, 3])] - handle[0]  # closed -> most open, in the world
    assert env[:, 3].max() > 0.15 and np.linalg.norm(moved) > 0.15, "the drawer opened"
    pull = math.atan2(moved[1], moved[0])
    world = np.arctan2(s * env[:, 4] + c * env[:, 5], c * env[:, 4] - s * env[:, 5])
    err = np.abs((world - pull + np.pi) % (2 * np.pi) - np.pi)
    assert err.max() < math.radians(2.0), math.degrees(err.max())
    assert np.ptp(np.arctan2(-env[:, 5], -env[:, 4])) > 0.3, "in the base frame it turns as the base drives"
    np.testing.assert_allclose(env[:, 6], [sum(st.robot.q[i] for i, n in enumerate(probes[0].robot.joint_names)
                                               if "finger" in n) for st in probes], atol=1e-5)


def test_front_options_are_checked_and_eval_finds_the_layout():
    """The recorder's option needs the environment state and a task with a part; eval picks the
    front's layout from the checkpoint's names, or from the policy's size when none are recorded,
    without changing the older layouts' sizes."""
    from pydantic import ValidationError

    from stages.demos.job import DemosConfig
    from stages.engine.env_state import BASE_VELOCITY, FRONT, GRIPPER, optional_layouts, state_names
    from stages.policy.evaluate import EvalConfig, env_layout

    assert DemosConfig(tasks=("open_drawer",), environment_state=True, environment_front=True).environment_front
    with pytest.raises(ValidationError, match="environment_front needs environment_state"):
        DemosConfig(tasks=("open_drawer",), environment_front=True)
    with pytest.raises(ValidationError, match="'pick_place_bowl' has no articulated part"):
        DemosConfig(tasks=("pick_place_bowl",), environment_state=True, environment_front=True)
    assert all(not set(FRONT) & set(n) for n in optional_layouts(("pick_place_bowl",)))
    assert len(optional_layouts(("open_drawer",))) == 8
    cfg = EvalConfig(checkpoint=Path("ck"), tasks=("open_drawer",), scenes=(101,), seeds=(1,))
    full = state_names("open_drawer", gripper=True, base_velocity=True, front=True)
    assert full[4:] == (*FRONT, *BASE_VELOCITY, GRIPPER)
    assert env_layout(cfg, SimpleNamespace(env_state_dim=10, env_state_names=full)) == full
    assert env_layout(cfg, SimpleNamespace(env_state_dim=10, env_state_names=None)) == full
    assert env_layout(cfg, SimpleNamespace(env_state_dim=6, env_state_names=None))[-2:] == FRONT
    # the older layouts keep their sizes: 7 is the base's velocity, not the front with the gripper
    assert env_layout(cfg, SimpleNamespace(env_state_dim=7, env_state_names=None))[-3:] == BASE_VELOCITY
    fg = state_names("open_drawer", gripper=True, front=True)
    assert env_layout(cfg, SimpleNamespace(env_state_dim=7, env_state_names=fg)) == fg
