"""Typed schema of AgentWorld's demonstration datasets (LeRobot v3.0 as written and read by lerobot 0.6).

Layout of one frame (``fps`` frames per second, 30 by default):

- ``observation.state`` float32 ``(arm_dof + 10,)`` = [arm joint positions (arm_dof) [rad],
  end-effector pose (7: x, y, z [m], quaternion w, x, y, z) in the robot base frame,
  base pose (3: x, y [m], theta [rad]) in the world frame];
- ``action`` float32 ``(arm_dof + 12,)`` = [arm joint targets (arm_dof) [rad], end-effector target
  (7: x, y, z [m], quaternion w, x, y, z), base velocity (3: vx, vy [m/s], vtheta [rad/s]) in the base
  frame, gripper command (1: 0 open .. 1 closed), mode (1: 0 locomotion / 1 manipulation)];
- with a dexterous hand (``DatasetSpec.hand_joints``: its n joints in control order), the state ends
  with the hand's joint positions (n) [rad] and the action's end-effector command is the hand's
  joint targets (n) [rad] in place of the gripper command: ``action`` = [arm targets, end-effector
  target, base velocity, hand joint targets (n), mode] (``arm_dof + 11 + n``), ``observation.state``
  = [arm joints, end-effector pose, base pose, hand joints (n)] (``arm_dof + 10 + n``);
- with several arms (``DatasetSpec.arms``: their names, e.g. ``("left", "right")`` of the dual-arm
  platform, each with a parallel gripper and ``arm_dof / len(arms)`` joints), the layout of
  :mod:`stages.embodiment.layout`: ``observation.state`` = [per arm its joints, per arm its
  end-effector pose (7), base pose (3)], ``action`` = [per arm its joint targets, per arm its
  end-effector target (7), base velocity (3), per arm its gripper command, mode]; the names carry
  the arm's prefix (``left_q0``, ``right_ee_x``, ``left_gripper``) and the frame's ``ee_pose`` /
  ``ee_target`` are (7 k,), its ``gripper`` (k,) for k arms;
- ``observation.images.<camera>`` RGB uint8 ``(H, W, 3)``, stored as mp4 video (lossy codec,
  :class:`VideoCodecSpec`; default x264 ultrafast, crf 23, GOP 30, chosen by measurement below);
- ``depth.<camera>`` depth uint16 ``(H, W)`` [mm], stored WITHOUT LOSS as a 16-bit PNG, base64 text
  (``dtype: string``, ``info.agentworld_depth: png16_base64``, ``info.height/width``,
  ``info.depth_unit: mm``) in the data parquet; :func:`stages.dataset.depth.decode_depth` gives the
  array back, exact for every uint16 value. Why this key and dtype: lerobot's policies take every
  ``image``/``video`` feature as a camera and every other ``observation.*`` feature as a state, so
  depth as ``observation.images.<camera>_depth`` (a 1-channel lerobot depth image) made
  ``lerobot-train --policy.type=act`` fail ("expected input ... to have 3 channels"); a key outside
  ``observation.`` that is not an image is passed through by ``LeRobotDataset`` (as a string per
  frame) and ignored by the policies, so datasets train as they are. (lerobot's depth *video* path
  quantizes to 12 bits, 4096 levels over 0.01-10 m, so it is not used.)
- optionally (``DatasetSpec.environment_state``: its names) ``observation.environment_state``
  float32 ``(D,)``: the task objects' key points in the robot base frame [m] (and an articulated
  part's opening), recorded at the instant of ``observation.state``
  (:mod:`stages.engine.env_state`); lerobot's ACT and Diffusion Policy take it as an ENV input;
- the task text (``task``) and, per episode, :class:`EpisodeInfo` as extra ``meta/episodes`` columns
  prefixed ``agentworld/`` (lerobot carries unknown columns through loading and aggregation).

RGB codec choice (``tests/benchmarks/bench_encode.py``, render-like moving textured content with
sensor noise, one encoder thread per process, 2 processes on this 2-core CI machine, frames/s of
both together; quality against the raw frames, decoded back):

    240x320            frames/s  KB/frame  PSNR [dB]  SSIM
    x264 ultrafast       967       4.3      29.13    0.915   <- default (CODEC_PRESETS["x264_ultrafast"])
    x264 veryfast        399       1.8      28.80    0.888
    AV1 p10, lerobot     139       9.0      29.58    0.933   (crf 30, GOP 2)
    AV1 p12, lerobot     130       9.0      29.58    0.933   (SVT-AV1 here maps preset 12 to 10)
    JPEG q90 (CPU)      1333      26.9      30.16    0.951   (image features, not video)
    480x640: x264 ultrafast 330, veryfast 144, AV1 p10 46, p12 39, JPEG 590 frames/s; quality
    within 0.4 dB of 240x320 (x264 ultrafast 29.40 dB, 0.914).

x264 ultrafast encodes 2.4x faster than veryfast at better PSNR/SSIM (at crf 23), and 7x faster than
lerobot's AV1 default for 0.45 dB less; most of every codec's loss is the sensor noise it does not
keep. On the 16-core GPU host issue 12 measured x264 ultrafast 10,778, veryfast 5,778, AV1 p10 5,026
and lerobot's default 751 frames/s at 320x240. JPEG is as fast on the CPU but 6x the bytes; nvJPEG
on CUDA tensors is measured by the benchmark with ``--device cuda``. Depth is not affected: it stays
lossless 16-bit PNG.

Nothing here imports torch or lerobot: the schema is plain data, usable by the recorder and tests.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

STATE_KEY = "observation.state"
ACTION_KEY = "action"
RGB_KEY = "observation.images.{camera}"
DEPTH_KEY = "depth.{camera}"
ENV_STATE_KEY = "observation.environment_state"  # optional (specs with environment_state names)
SUBTASK_KEY = "subtask_index"  # per-frame stage of a multistage task (0-based; specs with subtasks)
DEPTH_ENCODING = "png16_base64"  # info.agentworld_depth of the depth features
EPISODE_COLUMN_PREFIX = "agentworld/"
MODE_LOCOMOTION = 0
MODE_MANIPULATION = 1
DEPTH_MAX_MM = 65535

_NAME_RE = re.compile(r"^[a-z][a-z0-9_]*$")
_JOINT_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")  # joint names (the Shadow's: shadow_FFJ3)


class FrameError(ValueError):
    """A frame (or episode call) that does not match the dataset spec; the message lists every problem."""


@dataclass(frozen=True)
class CameraSpec:
    """One camera: name (``[a-z][a-z0-9_]*``), image size [px], and which streams are recorded."""

    name: str
    height: int = 240
    width: int = 320
    rgb: bool = True
    depth: bool = True

    def __post_init__(self) -> None:
        problems = []
        if not _NAME_RE.match(self.name):
            problems.append(f"camera name {self.name!r} must match [a-z][a-z0-9_]*")
        if self.height <= 0 or self.width <= 0:
            problems.append(f"camera {self.name!r}: size must be positive, got {self.height}x{self.width}")
        if not (self.rgb or self.depth):
            problems.append(f"camera {self.name!r} records neither rgb nor depth")
        if problems:
            raise ValueError("; ".join(problems))


@dataclass(frozen=True)
class VideoCodecSpec:
    """Encoder settings of the RGB videos (lerobot's ``RGBEncoderConfig``, encoded with PyAV).

    codec: ``h264`` (libx264), ``libsvtav1`` (lerobot's default) or ``hevc``;
    preset: codec preset (``"ultrafast"`` for h264, an int 0-13 for libsvtav1);
    crf: constant rate factor (lower is better quality, bigger files);
    gop: keyframe interval [frames] (``None``: the codec's default). Random access while training decodes
    from the previous keyframe, so a short GOP loads faster and encodes slower.
    """

    codec: str = "h264"
    preset: str | int | None = "ultrafast"
    crf: int = 23
    gop: int | None = 30
    pix_fmt: str = "yuv420p"

    def __post_init__(self) -> None:
        if self.codec not in ("h264", "libsvtav1", "hevc"):
            raise ValueError(f"video codec must be h264, libsvtav1 or hevc, got {self.codec!r}")


# Named encoder settings measured by tests/benchmarks/bench_encode.py (the av1 ones are lerobot 0.6's
# defaults, crf 30 and GOP 2, at two presets; preset 12 is lerobot's default).
CODEC_PRESETS: dict[str, VideoCodecSpec] = {
    "x264_ultrafast": VideoCodecSpec(codec="h264", preset="ultrafast", crf=23, gop=30),
    "x264_veryfast": VideoCodecSpec(codec="h264", preset="veryfast", crf=23, gop=30),
    "av1_p10_lerobot": VideoCodecSpec(codec="libsvtav1", preset=10, crf=30, gop=2),
    "av1_p12_lerobot": VideoCodecSpec(codec="libsvtav1", preset=12, crf=30, gop=2),
}


@dataclass(frozen=True)
class DatasetSpec:
    """Everything that fixes a dataset's schema and file layout. Shards merged together must share it.

    arm_dof: arm joints (7 for the default arm); fps: frames per second;
    data_files_size_mb / video_files_size_mb: size after which lerobot rolls over to the next
    ``chunk-XXX/file-YYY`` file; chunk_size: files per chunk folder; hand_joints: a dexterous
    hand's joint names (control order; empty for a parallel gripper): the state carries their
    positions and the action their targets in place of the gripper command (module docstring);
    subtasks: frames carry the stage of a multistage task (``subtask_index``, int64; the stages'
    language is the episode column ``agentworld/subtasks``, the stages its frames enter, in order,
    ``agentworld/subtasks_reached``); arms: the arm names of a multi-arm
    robot (empty: one arm; see the module docstring), each with ``arm_dof / len(arms)`` joints and a
    parallel gripper.
    """

    arm_dof: int = 7
    fps: int = 30
    robot_type: str = "agentworld_mobile_manipulator"
    cameras: tuple[CameraSpec, ...] = (
        CameraSpec("wrist"),
        CameraSpec("head"),
        CameraSpec("third_person"),
    )
    video: VideoCodecSpec = field(default_factory=VideoCodecSpec)
    data_files_size_mb: float = 100.0
    video_files_size_mb: float = 200.0
    chunk_size: int = 1000
    hand_joints: tuple[str, ...] = ()
    subtasks: bool = False
    arms: tuple[str, ...] = ()
    state_layout: tuple[str, ...] = ()
    """an embodiment's ``observation.state`` names (``stages.embodiment.layout.state_names``: two
    arms, no gripper ...); empty: the single-arm layout above. Frames then carry ``state_vector``."""
    action_layout: tuple[str, ...] = ()
    """an embodiment's ``action`` names (``stages.embodiment.layout.action_names``), with
    ``state_layout``; frames then carry ``action_vector``"""
    environment_state: tuple[str, ...] = ()
    """names of ``observation.environment_state`` (float32 (D,), :mod:`stages.engine.env_state`);
    empty: not recorded (the feature is absent). Frames then carry ``environment_state``"""

    def __post_init__(self) -> None:
        problems = []
        if self.arms and (len(set(self.arms)) != len(self.arms) or any(not _NAME_RE.match(a) for a in self.arms)
                          or self.arm_dof % len(self.arms) or self.hand_joints):
            problems.append(f"arms must be unique names matching [a-z][a-z0-9_]*, share arm_dof equally and "
                            f"have no hand_joints, got arms {list(self.arms)}, arm_dof {self.arm_dof}")
        if self.arms and self.state_layout:
            problems.append("arms (the arms' layout) and state_layout (an embodiment's own) exclude each other")
        if bool(self.state_layout) != bool(self.action_layout):
            problems.append("state_layout and action_layout must be given together")
        if self.state_layout and self.hand_joints:
            problems.append("hand_joints belong to the single-arm layout; an embodiment layout names its "
                            "joints")
        for what, names in (("state_layout", self.state_layout), ("action_layout", self.action_layout)):
            if any(not _JOINT_RE.match(n) for n in names) or len(set(names)) != len(names):
                problems.append(f"{what} must be unique names matching [A-Za-z][A-Za-z0-9_]*, "
                                f"got {list(names)}")
        if self.arm_dof <= 0:
            problems.append(f"arm_dof must be positive, got {self.arm_dof}")
        if self.fps <= 0:
            problems.append(f"fps must be positive, got {self.fps}")
        names = [c.name for c in self.cameras]
        if len(set(names)) != len(names):
            problems.append(f"camera names must be unique, got {names}")
        hj = self.hand_joints
        if any(not _JOINT_RE.match(j) for j in hj) or len(set(hj)) != len(hj):
            problems.append(f"hand_joints must be unique names matching [A-Za-z][A-Za-z0-9_]*, got {list(hj)}")
        es = self.environment_state
        if any(not _JOINT_RE.match(n) for n in es) or len(set(es)) != len(es):
            problems.append(f"environment_state must be unique names matching [A-Za-z][A-Za-z0-9_]*, got {list(es)}")
        if self.data_files_size_mb <= 0 or self.video_files_size_mb <= 0 or self.chunk_size <= 0:
            problems.append("file sizes and chunk_size must be positive")
        if problems:
            raise ValueError("; ".join(problems))

    @property
    def ee_count(self) -> int:
        """End effectors (one per arm; 1 for a one-arm spec)."""
        return len(self.arms) or 1

    @property
    def state_dim(self) -> int:
        if self.state_layout:
            return len(self.state_layout)
        return self.arm_dof + 7 * self.ee_count + 3 + len(self.hand_joints)

    @property
    def action_dim(self) -> int:
        if self.action_layout:
            return len(self.action_layout)
        return self.arm_dof + 7 * self.ee_count + 3 + (len(self.hand_joints) or self.ee_count) + 1

    def _arm_names(self, suffix: str) -> list[str]:
        k = self.arm_dof // len(self.arms)
        joints = [f"{a}_q{i}{suffix}" for a in self.arms for i in range(k)]
        return joints + [f"{a}_ee_{c}{suffix}" for a in self.arms for c in ("x", "y", "z", "qw", "qx", "qy", "qz")]

    def state_names(self) -> list[str]:
        if self.state_layout:
            return list(self.state_layout)
        if self.arms:
            return [*self._arm_names(""), "base_x", "base_y", "base_theta"]
        return [
            *(f"arm_q{i}" for i in range(self.arm_dof)),
            "ee_x", "ee_y", "ee_z", "ee_qw", "ee_qx", "ee_qy", "ee_qz",
            "base_x", "base_y", "base_theta", *self.hand_joints,
        ]  # fmt: skip

    def action_names(self) -> list[str]:
        if self.action_layout:
            return list(self.action_layout)
        if self.arms:
            return [*self._arm_names("_target"), "base_vx", "base_vy", "base_vtheta",
                    *(f"{a}_gripper" for a in self.arms), "mode"]
        return [
            *(f"arm_q{i}_target" for i in range(self.arm_dof)),
            "ee_x_target", "ee_y_target", "ee_z_target",
            "ee_qw_target", "ee_qx_target", "ee_qy_target", "ee_qz_target",
            "base_vx", "base_vy", "base_vtheta",
            *([f"{j}_target" for j in self.hand_joints] or ["gripper"]), "mode",
        ]  # fmt: skip

    def rgb_keys(self) -> dict[str, str]:
        """camera name -> feature key of its RGB video."""
        return {c.name: RGB_KEY.format(camera=c.name) for c in self.cameras if c.rgb}

    def depth_keys(self) -> dict[str, str]:
        """camera name -> feature key of its depth (16-bit PNG, base64; see the module docstring)."""
        return {c.name: DEPTH_KEY.format(camera=c.name) for c in self.cameras if c.depth}

    def features(self) -> dict[str, dict[str, Any]]:
        """The lerobot ``features`` dict (``meta/info.json``) of this spec."""
        feats: dict[str, dict[str, Any]] = {
            STATE_KEY: {"dtype": "float32", "shape": (self.state_dim,), "names": self.state_names()},
            ACTION_KEY: {"dtype": "float32", "shape": (self.action_dim,), "names": self.action_names()},
        }
        hwc = ["height", "width", "channels"]
        for cam in self.cameras:
            if cam.rgb:
                feats[RGB_KEY.format(camera=cam.name)] = {
                    "dtype": "video", "shape": (cam.height, cam.width, 3), "names": hwc,
                }  # fmt: skip
            if cam.depth:
                feats[DEPTH_KEY.format(camera=cam.name)] = {
                    "dtype": "string", "shape": (1,), "names": None,
                    "info": {"agentworld_depth": DEPTH_ENCODING, "height": cam.height, "width": cam.width,
                             "depth_unit": "mm"},
                }  # fmt: skip
        if self.environment_state:
            feats[ENV_STATE_KEY] = {"dtype": "float32", "shape": (len(self.environment_state),),
                                    "names": list(self.environment_state)}
        if self.subtasks:
            feats[SUBTASK_KEY] = {"dtype": "int64", "shape": (1,), "names": None}
        return feats

    def to_json(self) -> dict[str, Any]:
        """A JSON-able description (written to the shard's and the merged dataset's sidecar)."""
        return {
            "arm_dof": self.arm_dof, "fps": self.fps, "robot_type": self.robot_type,
            "cameras": [vars(c).copy() for c in self.cameras], "video": vars(self.video).copy(),
            "data_files_size_mb": self.data_files_size_mb, "video_files_size_mb": self.video_files_size_mb,
            "chunk_size": self.chunk_size,
            **({"hand_joints": list(self.hand_joints)} if self.hand_joints else {}),
            **({"subtasks": True} if self.subtasks else {}),
            **({"arms": list(self.arms)} if self.arms else {}),
            **({"state_layout": list(self.state_layout), "action_layout": list(self.action_layout)}
               if self.state_layout else {}),
            **({"environment_state": list(self.environment_state)} if self.environment_state else {}),
        }  # fmt: skip

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> DatasetSpec:
        d = dict(data)
        d["cameras"] = tuple(CameraSpec(**c) for c in d["cameras"])
        d["video"] = VideoCodecSpec(**d["video"])
        d["hand_joints"] = tuple(d.get("hand_joints", ()))
        d["arms"] = tuple(d.get("arms", ()))
        d["state_layout"] = tuple(d.get("state_layout", ()))
        d["action_layout"] = tuple(d.get("action_layout", ()))
        d["environment_state"] = tuple(d.get("environment_state", ()))
        return cls(**d)


@dataclass(frozen=True)
class EpisodeInfo:
    """What the recorder knows about an episode before it runs.

    task: the language instruction (lerobot's ``task``); task_kind: the task family
    (e.g. ``pick_place``); scene_id: the scene it ran in; seed: the episode's seed;
    asset_ids: ids of the assets involved (target object, container, ...); subtasks: the language
    instruction of each stage of a multistage task (the frames' ``subtask_index`` indexes it; empty
    for a one-stage task).
    """

    task: str
    task_kind: str
    scene_id: str
    seed: int
    asset_ids: tuple[str, ...] = ()
    subtasks: tuple[str, ...] = ()

    def problems(self) -> list[str]:
        out = []
        if not self.task.strip():
            out.append("task text is empty")
        if not self.task_kind or not self.scene_id:
            out.append("task_kind and scene_id must be non-empty")
        if not 0 <= int(self.seed) < 2**63:
            out.append(f"seed must be in [0, 2**63), got {self.seed}")
        if any(not t.strip() for t in self.subtasks):
            out.append("a subtask text is empty")
        return out


@dataclass(frozen=True)
class Frame:
    """One recorded time step (all arrays numpy; angles [rad], lengths [m], depth [mm]).

    arm_joint_pos (arm_dof,); ee_pose (7,) xyz + quat wxyz; base_pose (3,) x, y, theta;
    arm_joint_target (arm_dof,); ee_target (7,); base_velocity (3,) vx, vy [m/s], vtheta [rad/s];
    gripper in [0, 1] (several arms: ee_pose, ee_target (7 k,) and gripper (k,), arm after arm);
    mode 0 (locomotion) or 1 (manipulation); subtask_index: the stage of a
    multistage task (recorded where the spec has ``subtasks``);
    rgb: camera -> uint8 (H, W, 3); depth_mm: camera -> uint16 (H, W) or (H, W, 1)
    (use :func:`depth_m_to_mm` to convert a float depth map in metres);
    hand_joint_pos, hand_joint_target (n,) [rad]: a dexterous hand's joints (``DatasetSpec.hand_joints``;
    empty for a parallel gripper, whose command is ``gripper``).
    """

    arm_joint_pos: np.ndarray
    ee_pose: np.ndarray
    base_pose: np.ndarray
    arm_joint_target: np.ndarray
    ee_target: np.ndarray
    base_velocity: np.ndarray
    gripper: float | np.ndarray
    mode: int
    rgb: Mapping[str, np.ndarray]
    depth_mm: Mapping[str, np.ndarray]
    hand_joint_pos: np.ndarray = field(default_factory=lambda: np.zeros(0))
    hand_joint_target: np.ndarray = field(default_factory=lambda: np.zeros(0))
    subtask_index: int = 0
    state_vector: np.ndarray | None = None
    """the whole ``observation.state`` (S,) of a spec with an embodiment layout (``state_layout``)"""
    action_vector: np.ndarray | None = None
    """the whole ``action`` (A,) of a spec with an embodiment layout (``action_layout``)"""
    environment_state: np.ndarray | None = None
    """``observation.environment_state`` (D,) of a spec with ``environment_state`` names (None: none)"""

    @staticmethod
    def of_vectors(state: np.ndarray, action: np.ndarray, mode: int, rgb: Mapping[str, np.ndarray],
                   depth_mm: Mapping[str, np.ndarray], subtask_index: int = 0) -> Frame:
        """A frame of a spec with an embodiment layout: its state (S,) and action (A,) vectors."""
        empty = np.zeros(0)
        return Frame(arm_joint_pos=empty, ee_pose=empty, base_pose=empty, arm_joint_target=empty,
                     ee_target=empty, base_velocity=empty, gripper=0.0, mode=int(mode), rgb=rgb,
                     depth_mm=depth_mm, subtask_index=subtask_index, state_vector=np.asarray(state),
                     action_vector=np.asarray(action))

    def state(self) -> np.ndarray:
        """float32 (arm_dof + 10 + n,) (n: hand joints, 0 for a parallel gripper); or ``state_vector``."""
        if self.state_vector is not None:
            return np.asarray(self.state_vector, np.float32)
        return np.concatenate([self.arm_joint_pos, self.ee_pose, self.base_pose,
                               np.ravel(self.hand_joint_pos)]).astype(np.float32)

    def action(self) -> np.ndarray:
        """float32 (arm_dof + 12,), or (arm_dof + 11 + n,) with a hand's n joint targets; or
        ``action_vector``."""
        if self.action_vector is not None:
            return np.asarray(self.action_vector, np.float32)
        ee_cmd = np.ravel(self.hand_joint_target) if np.size(self.hand_joint_target) else np.ravel(self.gripper)
        return np.concatenate(
            [self.arm_joint_target, self.ee_target, self.base_velocity, ee_cmd, [self.mode]]
        ).astype(np.float32)


def depth_m_to_mm(depth_m: np.ndarray) -> np.ndarray:
    """float depth [m] (H, W) -> uint16 [mm], rounded; non-finite or <= 0 -> 0 (no return);
    clipped at 65.535 m."""
    d = np.asarray(depth_m, dtype=np.float64)
    mm = np.where(np.isfinite(d) & (d > 0), np.rint(d * 1000.0), 0.0)
    return np.clip(mm, 0, DEPTH_MAX_MM).astype(np.uint16)


def _vector_problems(name: str, value: Any, dim: int) -> list[str]:
    arr = np.asarray(value)
    if arr.shape != (dim,):
        return [f"{name}: shape {arr.shape}, expected ({dim},)"]
    if not np.issubdtype(arr.dtype, np.number):
        return [f"{name}: dtype {arr.dtype} is not numeric"]
    if not np.all(np.isfinite(arr)):
        return [f"{name}: contains NaN or inf"]
    return []


def _quat_problems(name: str, pose: Any) -> list[str]:
    arr = np.asarray(pose, dtype=np.float64)
    if arr.shape == (7,) and np.all(np.isfinite(arr)) and abs(float(np.linalg.norm(arr[3:])) - 1.0) > 1e-3:
        return [f"{name}: quaternion norm {np.linalg.norm(arr[3:]):.4f}, expected 1 (wxyz)"]
    return []


def _poses_quat_problems(name: str, poses: Any, k: int) -> list[str]:
    arr = np.asarray(poses, dtype=np.float64)
    if k == 1 or arr.shape != (7 * k,):
        return _quat_problems(name, poses)
    return [p for i in range(k) for p in _quat_problems(f"{name}[{i}]", arr[7 * i:7 * i + 7])]


def _image_problems(spec: DatasetSpec, frame: Frame) -> list[str]:
    out = []
    for cam in spec.cameras:
        if cam.rgb:
            img = frame.rgb.get(cam.name)
            if img is None:
                out.append(f"rgb[{cam.name!r}] missing")
            elif not (isinstance(img, np.ndarray) and img.dtype == np.uint8
                      and img.shape == (cam.height, cam.width, 3)):  # fmt: skip
                out.append(f"rgb[{cam.name!r}]: expected uint8 ({cam.height}, {cam.width}, 3), got "
                           f"{getattr(img, 'dtype', type(img))} {getattr(img, 'shape', '')}")  # fmt: skip
        if cam.depth:
            d = frame.depth_mm.get(cam.name)
            shapes = ((cam.height, cam.width), (cam.height, cam.width, 1))
            if d is None:
                out.append(f"depth_mm[{cam.name!r}] missing")
            elif not isinstance(d, np.ndarray) or d.dtype != np.uint16 or d.shape not in shapes:
                out.append(f"depth_mm[{cam.name!r}]: expected uint16 ({cam.height}, {cam.width}), got "
                           f"{getattr(d, 'dtype', type(d))} {getattr(d, 'shape', '')}")  # fmt: skip
    extra_rgb = set(frame.rgb) - set(spec.rgb_keys())
    extra_depth = set(frame.depth_mm) - set(spec.depth_keys())
    if extra_rgb:
        out.append(f"rgb has cameras not in the spec: {sorted(extra_rgb)}")
    if extra_depth:
        out.append(f"depth_mm has cameras not in the spec: {sorted(extra_depth)}")
    return out


def frame_problems(spec: DatasetSpec, frame: Frame) -> list[str]:
    """Every way ``frame`` does not match ``spec`` (empty list: valid)."""
    if spec.state_layout:
        return _layout_frame_problems(spec, frame)
    n, k = spec.arm_dof, spec.ee_count
    out = [
        *_vector_problems("arm_joint_pos", frame.arm_joint_pos, n),
        *_vector_problems("ee_pose", frame.ee_pose, 7 * k),
        *_poses_quat_problems("ee_pose", frame.ee_pose, k),
        *_vector_problems("base_pose", frame.base_pose, 3),
        *_vector_problems("arm_joint_target", frame.arm_joint_target, n),
        *_vector_problems("ee_target", frame.ee_target, 7 * k),
        *_poses_quat_problems("ee_target", frame.ee_target, k),
        *_vector_problems("base_velocity", frame.base_velocity, 3),
        *_vector_problems("hand_joint_pos", frame.hand_joint_pos, len(spec.hand_joints)),
        *_vector_problems("hand_joint_target", frame.hand_joint_target, len(spec.hand_joints)),
    ]
    if spec.arms:
        g = np.asarray(frame.gripper)
        if not (g.shape == (k,) and np.issubdtype(g.dtype, np.number) and np.all((g >= 0.0) & (g <= 1.0))):
            out.append(f"gripper must be {k} numbers in [0, 1] (one per arm), got {frame.gripper!r}")
    elif not (isinstance(frame.gripper, (int, float, np.floating, np.integer)) and math.isfinite(frame.gripper)
              and 0.0 <= float(frame.gripper) <= 1.0):  # fmt: skip
        out.append(f"gripper must be a number in [0, 1], got {frame.gripper!r}")
    if frame.mode not in (MODE_LOCOMOTION, MODE_MANIPULATION):
        out.append(f"mode must be 0 (locomotion) or 1 (manipulation), got {frame.mode!r}")
    if spec.subtasks and not (isinstance(frame.subtask_index, (int, np.integer)) and frame.subtask_index >= 0):
        out.append(f"subtask_index must be an integer >= 0, got {frame.subtask_index!r}")
    out.extend(_env_problems(spec, frame))
    out.extend(_image_problems(spec, frame))
    return out


def _env_problems(spec: DatasetSpec, frame: Frame) -> list[str]:
    """The frame's environment state against the spec's (present with its D entries, or absent)."""
    if not spec.environment_state:
        return [] if frame.environment_state is None else ["environment_state given, but the spec records none"]
    if frame.environment_state is None:
        return [f"environment_state missing (the spec records {len(spec.environment_state)} entries)"]
    return _vector_problems("environment_state", frame.environment_state, len(spec.environment_state))


def _layout_frame_problems(spec: DatasetSpec, frame: Frame) -> list[str]:
    """:func:`frame_problems` for a spec with an embodiment layout: the two vectors, mode, images."""
    out = [*_vector_problems("state_vector", frame.state_vector, spec.state_dim),
           *_vector_problems("action_vector", frame.action_vector, spec.action_dim)]
    if frame.mode not in (MODE_LOCOMOTION, MODE_MANIPULATION):
        out.append(f"mode must be 0 (locomotion) or 1 (manipulation), got {frame.mode!r}")
    elif not out and "mode" in spec.action_layout and (
            frame.action_vector[spec.action_layout.index("mode")] != frame.mode):
        out.append("action_vector's mode differs from the frame's mode")
    if spec.subtasks and not (isinstance(frame.subtask_index, (int, np.integer)) and frame.subtask_index >= 0):
        out.append(f"subtask_index must be an integer >= 0, got {frame.subtask_index!r}")
    out.extend(_env_problems(spec, frame))
    out.extend(_image_problems(spec, frame))
    return out


def validate_frame(spec: DatasetSpec, frame: Frame, where: str = "frame") -> None:
    """Raise one :class:`FrameError` listing every problem of ``frame`` (nothing if it is valid)."""
    problems = frame_problems(spec, frame)
    if problems:
        raise FrameError(f"{where}: {len(problems)} problem(s): " + "; ".join(problems))


def episode_columns(info: EpisodeInfo, success: bool, reached: tuple[int, ...] | None = None) -> dict[str, Any]:
    """The extra ``meta/episodes`` columns of one written episode; ``reached``: the stages
    (``subtask_index``) its frames enter, in order (a spec with subtasks: ``subtasks_reached``)."""
    p = EPISODE_COLUMN_PREFIX
    return {
        f"{p}task_kind": info.task_kind,
        f"{p}scene_id": info.scene_id,
        f"{p}seed": int(info.seed),
        f"{p}asset_ids": list(info.asset_ids),
        f"{p}success": bool(success),
        **({f"{p}subtasks": list(info.subtasks)} if info.subtasks else {}),
        **({f"{p}subtasks_reached": [int(k) for k in reached]} if reached is not None else {}),
    }
