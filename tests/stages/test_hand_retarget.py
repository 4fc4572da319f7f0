"""Retargeting WebXR hand joints to the Allegro and Shadow hands with dex-retargeting (CPU, seconds):
synthetic XRHand joint sets (a parametric right hand whose fingers curl by a flexion angle) give
joint targets that flex when the hand closes, do not depend on where the wrist is, mirror a left
hand onto the right, stay within the joint limits; malformed joint sets are rejected with a reason."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("dex_retargeting", reason="dex-retargeting (pip) retargets the hands")

from stages.teleop.hand_retarget import HandPoseError, HandRetargeter, check_hand, keypoints  # noqa: E402
from teleop_testutil import synthetic_hand  # noqa: E402

def _random_pose(seed: int) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(seed)
    m = np.eye(4)
    m[:3, :3] = Rotation.random(random_state=seed).as_matrix()
    m[:3, 3] = rng.uniform(-1, 1, 3) + (0, 1.2, 0)
    return m


@pytest.fixture(scope="module", params=["vector", "dexpilot"])
def allegro(request, tmp_path_factory, shared_assets):
    return HandRetargeter("allegro", tmp_path_factory.mktemp("allegro"), optimizer=request.param,
                          low_pass_alpha=1.0, shared_assets=shared_assets)


def _solve(r: HandRetargeter, joints, side="right", n=4) -> np.ndarray:
    r.reset()
    for _ in range(n):  # warm-started: a few calls settle the optimum (as a live stream does)
        q = r.retarget(joints, side)
    return q


def test_allegro_fingers_flex_when_the_hand_closes(allegro):
    open_q, closed_q = _solve(allegro, synthetic_hand(0.0)), _solve(allegro, synthetic_hand(1.1))
    assert open_q.shape == closed_q.shape == (16,)
    for name, k in (("index", 0), ("middle", 4), ("ring", 8)):
        flex_open, flex_closed = open_q[k + 1:k + 4].sum(), closed_q[k + 1:k + 4].sum()
        print(f"{allegro.optimizer} {name}: flexion {flex_open:.2f} -> {flex_closed:.2f} rad")
        assert flex_closed > flex_open + 1.0, (name, open_q, closed_q)
    assert open_q[1:4].max() < 0.6  # an open hand keeps the Allegro's fingers nearly straight


def test_allegro_targets_do_not_depend_on_the_wrist_pose_and_mirror_a_left_hand(allegro):
    hand = synthetic_hand(0.7, thumb_flex=0.3)
    ref = _solve(allegro, hand)
    for seed in (1, 2):
        moved = _solve(allegro, synthetic_hand(0.7, thumb_flex=0.3, wrist=_random_pose(seed)))
        np.testing.assert_allclose(moved, ref, atol=2e-3)
    left = _solve(allegro, synthetic_hand(0.7, thumb_flex=0.3, wrist=_random_pose(3), side="left"), side="left")
    np.testing.assert_allclose(left, ref, atol=2e-3)


def test_targets_stay_within_the_hand_joint_limits(allegro):
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(allegro.urdf))
    lo = np.array([model.lowerPositionLimit[model.joints[model.getJointId(j)].idx_q] for j in allegro.joints])
    hi = np.array([model.upperPositionLimit[model.joints[model.getJointId(j)].idx_q] for j in allegro.joints])
    for flex in (-0.5, 0.0, 0.8, 1.6, 2.5):  # past what a hand can do, too
        q = _solve(allegro, synthetic_hand(flex), n=2)
        assert np.all(q >= lo - 2e-3) and np.all(q <= hi + 2e-3), (flex, q)


def test_building_a_retargeter_leaves_no_scratch_folder(tmp_path, shared_assets):
    import tempfile

    root = Path(tempfile.gettempdir())
    before = set(root.glob("dex_retargeting-*")) | set(root.glob("aw-retarget-*"))
    HandRetargeter("allegro", tmp_path, shared_assets=shared_assets)
    after = set(root.glob("dex_retargeting-*")) | set(root.glob("aw-retarget-*"))
    assert after <= before, sorted(after - before)


def test_shadow_fingers_flex_when_the_hand_closes(tmp_path, shared_assets):
    from stages.simulate.hands import SHADOW_JOINTS

    r = HandRetargeter("shadow", tmp_path, low_pass_alpha=1.0, shared_assets=shared_assets)
    open_q, closed_q = _solve(r, synthetic_hand(0.0)), _solve(r, synthetic_hand(1.1))
    assert open_q.shape == (22,)
    for f in ("FF", "MF", "RF", "LF"):
        idx = [SHADOW_JOINTS.index(f"shadow_{f}J{i}") for i in (2, 1)]
        assert closed_q[idx].sum() > open_q[idx].sum() + 0.8, (f, open_q[idx], closed_q[idx])


def _with(joint: int, fn):
    def change(h: np.ndarray) -> np.ndarray:
        h = h.copy()
        h[joint] = fn(h[joint])
        return h
    return change


@pytest.mark.parametrize("change, reason", [
    (lambda h: h[:24], r"shape \(25, 4, 4\)"),
    (_with(3, lambda m: m * np.nan), "not finite"),
    (_with(9, lambda m: m + np.pad([[0.5], [0.0], [0.0]], ((0, 1), (3, 0)))), r"joint 9 is 0\.\d+ m from the wrist"),
    (_with(0, lambda m: m @ np.diag([2.0, 1.0, 1.0, 1.0])), "orthonormal"),
])
def test_malformed_joint_sets_are_rejected_with_a_reason(change, reason):
    with pytest.raises(HandPoseError, match=reason):
        check_hand(change(synthetic_hand(0.3)))
    with pytest.raises(HandPoseError, match="left or right"):
        keypoints(synthetic_hand(0.3), "allegro", side="middle")
