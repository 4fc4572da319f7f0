"""Dataset schema: dimensions, lerobot features, frame validation (no lerobot needed)."""

from __future__ import annotations

import numpy as np
import pytest

from stages.dataset.schema import (
    CameraSpec,
    DatasetSpec,
    EpisodeInfo,
    FrameError,
    depth_m_to_mm,
    frame_problems,
    validate_frame,
)
from stages.dataset.synthetic import synthetic_frame


def test_default_spec_dimensions_and_features():
    spec = DatasetSpec()
    assert spec.state_dim == 7 + 7 + 3 and spec.action_dim == 7 + 7 + 3 + 1 + 1
    feats = spec.features()
    assert feats["observation.state"]["shape"] == (17,) and len(feats["observation.state"]["names"]) == 17
    assert feats["action"]["shape"] == (19,) and feats["action"]["names"][-2:] == ["gripper", "mode"]
    for cam in ("wrist", "head", "third_person"):
        assert feats[f"observation.images.{cam}"] == {
            "dtype": "video", "shape": (240, 320, 3), "names": ["height", "width", "channels"]}  # fmt: skip
        depth = feats[f"depth.{cam}"]  # not an image and not observation.*: no policy takes it as input
        assert depth["dtype"] == "string" and depth["shape"] == (1,)
        assert depth["info"] == {"agentworld_depth": "png16_base64", "height": 240, "width": 320, "depth_unit": "mm"}


def test_spec_is_configurable_and_round_trips_json():
    spec = DatasetSpec(arm_dof=6, cameras=(CameraSpec("head", 64, 80, depth=False),), data_files_size_mb=0.5)
    assert spec.state_dim == 16 and spec.action_dim == 18
    assert set(spec.features()) == {"observation.state", "action", "observation.images.head"}
    assert DatasetSpec.from_json(spec.to_json()) == spec


def test_hand_joints_replace_the_gripper_command_and_extend_the_state():
    """A dexterous hand (teleoperation's retargeted fingers): n joint targets in the action where
    the gripper command was, n joint positions at the end of the state; frames are checked."""
    import dataclasses

    hand = ("allegro_joint_0", "allegro_joint_1", "allegro_joint_2")
    spec = DatasetSpec(cameras=(), hand_joints=hand)
    assert spec.state_dim == 17 + 3 and spec.action_dim == 7 + 7 + 3 + 3 + 1
    assert spec.action_names()[-4:] == ["allegro_joint_0_target", "allegro_joint_1_target",
                                        "allegro_joint_2_target", "mode"]
    assert spec.state_names()[-3:] == list(hand) and "gripper" not in spec.action_names()
    assert DatasetSpec.from_json(spec.to_json()) == spec
    assert "hand_joints" not in DatasetSpec().to_json()  # parallel-gripper sidecars are unchanged
    assert frame_problems(spec, synthetic_frame(spec, 0, 0, 5)) == []
    frame = dataclasses.replace(synthetic_frame(spec, 0, 0, 5), hand_joint_pos=np.array([0.1, 0.2, 0.3]),
                                hand_joint_target=np.array([0.4, 0.5, 0.6]))
    assert frame_problems(spec, frame) == []
    np.testing.assert_allclose(frame.state()[-3:], [0.1, 0.2, 0.3])
    np.testing.assert_allclose(frame.action()[-4:], [0.4, 0.5, 0.6, 1.0])
    bad = dataclasses.replace(frame, hand_joint_target=np.array([0.4, np.nan, 0.6]), hand_joint_pos=np.zeros(2))
    assert frame_problems(spec, bad) == ["hand_joint_pos: shape (2,), expected (3,)",
                                         "hand_joint_target: contains NaN or inf"]
    assert frame_problems(DatasetSpec(cameras=()), frame)[0] == "hand_joint_pos: shape (3,), expected (0,)"
    with pytest.raises(ValueError, match="hand_joints"):
        DatasetSpec(hand_joints=("a", "a"))
    with pytest.raises(ValueError, match="hand_joints"):
        DatasetSpec(hand_joints=("joint 1",))


def test_two_arms_give_the_embodiment_layout_of_the_dual_arm_platform():
    """DatasetSpec.arms (the dual-arm platform): per arm its joints and end-effector pose, one gripper
    command per arm, named as stages.embodiment.layout names the spec mobile_aloha_viperx; frames carry
    (14,) poses and (2,) grippers, each quaternion checked."""
    import dataclasses

    from stages.embodiment.layout import action_names, state_names
    from stages.embodiment.spec import load_spec

    spec = DatasetSpec(arm_dof=12, cameras=(), arms=("left", "right"))
    viperx = load_spec("mobile_aloha_viperx")
    assert spec.state_names() == state_names(viperx) and spec.action_names() == action_names(viperx)
    assert spec.state_dim == 12 + 14 + 3 and spec.action_dim == 12 + 14 + 3 + 2 + 1
    assert DatasetSpec.from_json(spec.to_json()) == spec and "arms" not in DatasetSpec().to_json()
    one = synthetic_frame(DatasetSpec(arm_dof=12, cameras=()), 0, 0, 5)
    frame = dataclasses.replace(one, ee_pose=np.tile(one.ee_pose, 2), ee_target=np.tile(one.ee_target, 2),
                                gripper=np.array([0.0, 1.0]))
    assert frame_problems(spec, frame) == []
    assert frame.state().shape == (29,) and frame.action().shape == (32,)
    np.testing.assert_allclose(frame.action()[-3:], [0.0, 1.0, 1.0])
    bad = dataclasses.replace(frame, ee_pose=np.concatenate([one.ee_pose, [0, 0, 0, 2, 0, 0, 0]]), gripper=0.5)
    assert frame_problems(spec, bad) == ["ee_pose[1]: quaternion norm 2.0000, expected 1 (wxyz)",
                                         "gripper must be 2 numbers in [0, 1] (one per arm), got 0.5"]
    with pytest.raises(ValueError, match="arms"):
        DatasetSpec(arm_dof=13, arms=("left", "right"))


def test_spec_rejects_bad_values_in_one_message():
    with pytest.raises(ValueError, match="arm_dof.*fps"):
        DatasetSpec(arm_dof=0, fps=0)
    with pytest.raises(ValueError, match="unique"):
        DatasetSpec(cameras=(CameraSpec("a"), CameraSpec("a")))
    with pytest.raises(ValueError, match="name"):
        CameraSpec("Wrist Cam")


def test_valid_synthetic_frame_has_no_problems():
    spec = DatasetSpec(cameras=(CameraSpec("wrist", 24, 32), CameraSpec("head", 24, 32, rgb=False)))
    frame = synthetic_frame(spec, 0, 0, 5)
    assert frame_problems(spec, frame) == []
    assert frame.state().shape == (spec.state_dim,) and frame.state().dtype == np.float32
    assert frame.action()[-1] == 1.0  # mode: manipulation from frame 3 on


def test_validate_frame_collects_every_problem():
    spec = DatasetSpec(cameras=(CameraSpec("wrist", 24, 32),))
    good = synthetic_frame(spec, 0, 0, 0)
    bad = type(good)(
        arm_joint_pos=np.zeros(6),  # wrong dof
        ee_pose=np.array([0, 0, 0, 2.0, 0, 0, 0]),  # not a unit quaternion
        base_pose=np.array([0.0, np.nan, 0.0]),  # NaN
        arm_joint_target=good.arm_joint_target,
        ee_target=good.ee_target,
        base_velocity=good.base_velocity,
        gripper=1.5,
        mode=2,
        rgb={"wrist": good.rgb["wrist"].astype(np.float32), "extra": good.rgb["wrist"]},
        depth_mm={},
    )
    with pytest.raises(FrameError) as err:
        validate_frame(spec, bad, where="ep 3 frame 7")
    msg = str(err.value)
    assert msg.startswith("ep 3 frame 7: 8 problem(s)")
    for part in ("arm_joint_pos: shape (6,)", "quaternion norm 2.0000", "base_pose: contains NaN",
                 "gripper", "mode must be 0", "rgb['wrist']: expected uint8", "depth_mm['wrist'] missing",
                 "not in the spec: ['extra']"):  # fmt: skip
        assert part in msg


def test_depth_m_to_mm_rounds_and_marks_invalid_as_zero():
    d = np.array([[0.0004, 0.0006, 1.2346], [np.nan, np.inf, 70.0], [-1.0, 65.535, 2.0]], np.float32)
    mm = depth_m_to_mm(d)
    assert mm.dtype == np.uint16
    assert mm.tolist() == [[0, 1, 1235], [0, 0, 65535], [0, 65535, 2000]]


def test_episode_info_problems():
    assert EpisodeInfo("open the fridge", "open_close", "scene-1", 3).problems() == []
    probs = EpisodeInfo(" ", "", "scene-1", -1).problems()
    assert len(probs) == 3


def test_importing_the_package_loads_no_heavy_module():
    import subprocess
    import sys
    from pathlib import Path

    heavy = "('torch', 'lerobot', 'av', 'pyarrow', 'datasets', 'cv2')"
    code = f"import sys, stages.dataset; print(sorted(m for m in {heavy} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], cwd=Path(__file__).resolve().parents[2],
                         capture_output=True, text=True, check=True)  # fmt: skip
    assert out.stdout.strip() == "[]"


def test_measured_codec_presets_round_trip_and_the_default_is_x264_ultrafast():
    """The RGB default is the preset bench_encode.py measured fastest per quality; depth stays PNG text."""
    from stages.dataset.schema import CODEC_PRESETS, CameraSpec, DatasetSpec, VideoCodecSpec

    assert VideoCodecSpec() == CODEC_PRESETS["x264_ultrafast"]
    assert CODEC_PRESETS["av1_p12_lerobot"] == VideoCodecSpec(codec="libsvtav1", preset=12, crf=30, gop=2)
    for name, codec in CODEC_PRESETS.items():
        spec = DatasetSpec(cameras=(CameraSpec("head", 240, 320),), video=codec)
        assert DatasetSpec.from_json(spec.to_json()).video == codec, name
        feats = spec.features()
        assert feats["observation.images.head"]["dtype"] == "video"
        assert feats["depth.head"]["dtype"] == "string"


def test_depth_png_is_a_standard_16_bit_png_that_decoders_read_back_exactly():
    """encode_depth writes its own PNG (Up filter, zlib level 1): PIL and OpenCV read every value back."""
    import base64
    import io

    from PIL import Image

    from stages.dataset.depth import decode_depth, encode_depth, encode_depth_png

    rng = np.random.default_rng(3)
    frames = [rng.integers(0, 65536, (37, 53), dtype=np.uint16),  # odd sizes, every byte pattern
              np.full((1, 1), 65535, np.uint16), np.zeros((4, 300), np.uint16),
              rng.integers(0, 65536, (24, 32, 1), dtype=np.uint16),  # (H, W, 1) as cameras give it
              rng.integers(0, 65536, (40, 60), dtype=np.uint16)[::2, 1::2]]  # a strided view
    for d in frames:
        want = d.reshape(d.shape[:2])
        raw = encode_depth_png(d)
        assert raw[:8] == b"\x89PNG\r\n\x1a\n" and raw[-12:] == b"\x00\x00\x00\x00IEND\xaeB`\x82"
        np.testing.assert_array_equal(decode_depth(raw), want)
        np.testing.assert_array_equal(decode_depth(encode_depth(d)), want)
        assert base64.b64decode(encode_depth(d)) == raw
        with Image.open(io.BytesIO(raw)) as im:
            im.load()  # PIL checks the chunks' CRCs and the zlib stream
            assert im.size == (want.shape[1], want.shape[0]) and im.mode.startswith("I;16")
            np.testing.assert_array_equal(np.asarray(im).astype(np.uint16), want)
    with pytest.raises(ValueError, match="uint16"):
        encode_depth(np.zeros((4, 4), np.float32))
    with pytest.raises(ValueError, match="shape"):
        encode_depth(np.zeros((4, 4, 2), np.uint16))


def test_image_stats_quantiles_equal_numpys_bit_for_bit():
    """Image stats read the quantiles of uint8/uint16 frames from histograms: np.quantile's values exactly."""
    from stages.dataset.stats import QUANTILES, image_stats

    rng = np.random.default_rng(5)
    cases = ((1, 1, np.uint8, 1, 255.0), (7, 3, np.uint8, 256, 255.0), (3, 3, np.uint8, 40, 255.0),
             (5, 1, np.uint16, 65536, 1.0), (2, 1, np.uint16, 300, 1.0))
    for n, c, dtype, top, scale in cases:
        sampled = rng.integers(0, top, (n, c, 13, 17)).astype(dtype)
        x = sampled.transpose(1, 0, 2, 3).reshape(c, -1).astype(np.float64) / scale
        want = np.quantile(x, QUANTILES, axis=1)
        stats = image_stats(sampled, scale)
        for i, q in enumerate(QUANTILES):
            np.testing.assert_array_equal(stats[f"q{round(q * 100):02d}"].ravel(), want[i])
        np.testing.assert_array_equal(stats["min"].ravel(), x.min(1))
        np.testing.assert_array_equal(stats["max"].ravel(), x.max(1))
        assert stats["count"].tolist() == [n]


@pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="needs fork")
def test_a_forked_child_encodes_depth_with_threads_of_its_own():
    """The process-wide depth PNG threads: a forked child (the parent's threads are not there) gets
    its own pool instead of waiting forever on the parent's."""
    import os
    import warnings

    from stages.dataset.depth import encode_depth
    from stages.dataset.direct import _depth_executor

    d = np.arange(12, dtype=np.uint16).reshape(3, 4)
    assert _depth_executor().submit(encode_depth, d).result(timeout=10) == encode_depth(d)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # fork of a multi-threaded process
        pid = os.fork()
    if pid == 0:  # the child reports by its exit code
        code = 1
        try:
            code = 0 if _depth_executor().submit(encode_depth, d).result(timeout=10) == encode_depth(d) else 2
        finally:
            os._exit(code)
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0
