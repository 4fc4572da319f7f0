"""The G1 with Dex3 hands (spec ``g1_29dof_dex3``) in the humanoid runtime and engine: 43 joints,
the policy's observations from the 29 body joints as in training, the 14 hand joints by PD targets
from the spec's open/closed poses; it stands and walks with the hands' mass; frames carry the
hand commands; the hands' collision boxes come from the URDF; the pick_place_bowl expert end to end
with cameras (slow). Real policy, MuJoCo C on the CPU, no mocks."""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("newton")
pytest.importorskip("pinocchio")
pytest.importorskip("torch")


def test_the_spec_gives_the_g1_with_hand_joints_and_the_rubber_hand_spec_the_g1_as_trained():
    """``humanoid_for_spec``: the rubber-hand spec's humanoid is the trained G1 itself; the Dex3
    spec's has its URDF, 43 joints and the hand drives of the spec (kp 3, kd 0.1, armature
    HAND_ARMATURE, effort the hands' max_force 1.4 N m), the body's drives unchanged; the newton
    MJCF variant is refused in one line naming it."""
    from stages.embodiment import EmbodimentError, load_spec
    from stages.locomotion.hands import HAND_ARMATURE, hand_arms, humanoid_for_spec
    from stages.locomotion.robot import G1

    assert humanoid_for_spec(load_spec("g1_29dof")) is G1 and hand_arms(load_spec("g1_29dof")) == ()
    spec = load_spec("g1_29dof_dex3")
    d = humanoid_for_spec(spec)
    assert d.num_joints == 43 and d.source_file.endswith("g1_29dof_with_hand_rev_1_0.urdf")
    assert hand_arms(spec) == ("left", "right")
    g = d.gains("right_hand_index_1_joint")
    assert (g.stiffness, g.damping, g.armature, g.effort_limit) == (3.0, 0.1, HAND_ARMATURE, 1.4)
    assert d.gains("left_knee_joint") == G1.gains("left_knee_joint")
    with pytest.raises(EmbodimentError, match="g1_29dof_dex3_newton.*example-robot-data URDFs only"):
        humanoid_for_spec(load_spec("g1_29dof_dex3_newton"))


def test_hand_link_boxes_come_from_the_urdf():
    """The palm's box is its collision mesh's bounds (0.087 x 0.042 x 0.088 m); thumb_1's is the
    URDF's own box (0.02 x 0.03 x 0.02 m at (-0.001, -0.032, 0)); a link without collision
    geometry is refused naming the file."""
    from stages.embodiment import load_spec
    from stages.embodiment.sources import resolve_description
    from stages.engine.humanoid_hands import hand_link_boxes

    desc = resolve_description(load_spec("g1_29dof_dex3").description)
    boxes = hand_link_boxes(desc.path, desc.root, ["left_hand_palm_link", "left_hand_thumb_1_link"])
    (c, h), = boxes["left_hand_palm_link"]
    np.testing.assert_allclose(2 * h, [0.087, 0.0418, 0.0878], atol=1e-3)
    np.testing.assert_allclose(c, [0.0435, 0.0005, 0.0], atol=1e-3)
    (c, h), = boxes["left_hand_thumb_1_link"]
    np.testing.assert_allclose(2 * h, [0.02, 0.03, 0.02], atol=1e-9)
    np.testing.assert_allclose(c, [-0.001, -0.032, 0.0], atol=1e-9)
    with pytest.raises(ValueError, match=f"{desc.path.name}.*'no_such_link' has no collision geometry"):
        hand_link_boxes(desc.path, desc.root, ["no_such_link"])


def test_g1_with_dex3_hands_stands_walks_and_closes_a_hand():
    """One world on a flat floor: the runtime finds the policy's 29 joints and the 14 hand joints,
    its observations are the training layout (85: 12 + 2 x 29 + 15); standing 1 s, then vx 0.5 m/s
    for 4 s with the right hand closing: it walks (measured 1.86 m, 0.486 m/s over the last 2 s;
    the rubber-hand G1: 1.83 m, 0.483 m/s), the right hand's joints reach the spec's closed pose,
    the left stays open; the frame's action ends with the hand commands (left 0, right 1) and the
    mode. About 10 s on 2 cores."""
    import warp as wp

    from stages.embodiment import load_spec
    from stages.embodiment.layout import action_names, state_names
    from stages.locomotion.embodiment import frame_vectors
    from stages.locomotion.runtime import HumanoidWorlds, HumanoidWorldsConfig, LeggedRuntimeConfig

    sim = HumanoidWorlds(HumanoidWorldsConfig(num_worlds=1, device="cpu",
                                              runtime=LeggedRuntimeConfig(spec="g1_29dof_dex3")))
    rt = sim.runtime
    assert sim.model.joint_coord_count == 7 + 43 and len(rt.joint_names) == 29 and len(rt.hands.names) == 14
    assert rt.observations(sim.state).shape == (1, 85)
    sim.run(1.0)
    p0 = rt.base_state(sim.state)[0][0].numpy().copy()
    assert p0[2] > 0.72
    rt.set_command(np.array([[0.5, 0.0, 0.0]]))
    rt.hands.set("right", 1.0)
    sim.run(2.0)
    p1 = rt.base_state(sim.state)[0][0].numpy().copy()
    sim.run(2.0)
    p2 = rt.base_state(sim.state)[0][0].numpy()
    assert math.dist(p0[:2], p2[:2]) > 1.6 and abs(math.dist(p1[:2], p2[:2]) / 2.0 - 0.5) < 0.06
    assert p2[2] > 0.72
    q = rt.hands.positions(wp.to_torch(sim.state.joint_q))[0]
    spec = load_spec("g1_29dof_dex3")
    np.testing.assert_allclose(q[7:], spec.end_effectors["right_hand"].closed, atol=0.05)
    np.testing.assert_allclose(q[:7], spec.end_effectors["left_hand"].open, atol=0.05)
    state, action = frame_vectors(rt, sim.state)
    assert state.shape == (1, len(state_names(spec))) == (1, 31)
    names = action_names(spec)
    assert action.shape == (1, len(names)) == (1, 34)
    assert names[-3:] == ["left_gripper", "right_gripper", "mode"]
    np.testing.assert_array_equal(action[0, -3:], [0.0, 1.0, 0.0])


@pytest.mark.slow
def test_pick_place_bowl_with_a_dex3_hand_is_recorded_and_loads(kitchen_catalog, tmp_path):
    """One pick_place_bowl episode (kitchen world seed 5, episode seed 1) by the humanoid recorder
    with the Dex3 G1 and head and wrist cameras: the mug ends in the bowl, released, upright; the
    merged dataset loads with LeRobotDataset (robot type unitree_g1, action 34 with the hand
    commands, which close and open during the episode). Measured: 21.4 s simulated; 3.5 min
    on 2 shared cores (load average 10), 28 s of it the kitchen."""
    from stages.dataset import load_dataset
    from stages.demos.humanoid_run import HumanoidRunConfig, record

    from kitchen_testutil import link_kitchen_catalog

    work = tmp_path / "w"
    link_kitchen_catalog(kitchen_catalog, work / "kitchens")
    cams = ("head", "left_wrist", "right_wrist")
    rep = record(work, HumanoidRunConfig(tasks=("pick_place_bowl",), episodes=1, spec="g1_29dof_dex3",
                                         cameras=cams, width=32, height=24))
    assert rep["tasks"]["pick_place_bowl"]["successes"] == 1, rep["episodes"]
    ds = load_dataset(rep["dataset"])
    assert ds.meta.robot_type == "unitree_g1" and ds.meta.total_episodes == 1
    assert set(ds.meta.camera_keys) == {f"observation.images.{c}" for c in cams}
    names = ds.meta.features["action"]["names"]
    names = names if isinstance(names, list) else next(iter(names.values()))
    col = names.index("right_gripper")
    grip = np.array([float(ds[i]["action"][col]) for i in range(0, ds.meta.total_frames, 5)])
    assert grip.max() == 1.0 and grip[0] == 0.0 and grip[-1] == 0.0
