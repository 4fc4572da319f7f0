"""WebXR hand joints -> a dexterous hand's joint targets, with dex-retargeting (package index).

Input: one hand's 25 XRHand joint poses (25, 4, 4) [m] in the XR reference space, WebXR joint
order (0 wrist; 1-4 thumb metacarpal, proximal, distal, tip; 5-9 index metacarpal, proximal,
intermediate, distal, tip; 10-14 middle; 15-19 ring; 20-24 little). Output: the hand's joint
targets (n,) [rad] in :class:`~stages.simulate.hands.HandInfo` ``joints`` order (Allegro 16,
Shadow 22), within the joint limits.

Steps (:meth:`HandRetargeter.retarget`):

1. :func:`keypoints`: the 21 keypoints of the MANO / MediaPipe convention dex-retargeting's
   configurations index (wrist, then 4 per finger from its base knuckle to its tip; the WebXR
   metacarpals of the four fingers are dropped: :data:`XR_TO_MANO`), expressed in the wrist
   joint's frame and turned into the robot palm's frame (:data:`PALM_FROM_XR_WRIST`: WebXR's
   wrist has -z along the fingers, +y out of the back of the hand and, for a right hand, the
   thumb on -x). A left hand is mirrored (x -> -x) onto our right robot hand.
2. The reference vectors: keypoint[task] - keypoint[origin] per configured pair (wrist -> each
   fingertip for the vector optimizer; DexPilot's finger-to-finger and wrist-to-finger vectors).
3. dex-retargeting's :class:`SeqRetargeting` (nlopt SLSQP on the Pinocchio model of a hand-only
   URDF, warm-started from the previous solution, low-pass filtered) gives the joint positions,
   reordered into the hand's control order.

The hand-only URDF (:func:`write_retarget_urdf`) is the hand that
:func:`stages.simulate.hands.add_hand` mounts on the Panda, without the mount, meshes and
collision shapes, rooted at its palm link, plus the frames dex-retargeting needs: the Allegro's
wrist (``allegro_wrist``, 95 mm behind the finger bases along the palm) and the Shadow's
fingertips (``shadow_<f>tip``, the MJCF's tip sites). Configurations (:data:`CONFIGS`) follow
dex-retargeting's teleop configurations for these hands (links renamed, the same human keypoints
and scaling factors: the Allegro is about 1.6 times a human hand, the Shadow 1.2 times).

Untrusted input: :func:`check_hand` rejects a joint set that is not (25, 4, 4), not finite, or
has a joint farther than :data:`~stages.teleop.protocol.MAX_HAND_SPAN` from the wrist
(:class:`HandPoseError`, naming the joint); the session logs it and keeps the last targets.
"""

from __future__ import annotations

import logging
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stages.teleop.protocol import MAX_HAND_SPAN, XR_JOINTS

log = logging.getLogger(__name__)

XR_TO_MANO = (0, 1, 2, 3, 4, 6, 7, 8, 9, 11, 12, 13, 14, 16, 17, 18, 19, 21, 22, 23, 24)
"""WebXR joint index of each of the 21 MANO keypoints (wrist; thumb CMC, MCP, IP, tip; per finger
MCP, PIP, DIP, tip: the WebXR proximal phalanx starts at the MCP)."""


class HandPoseError(ValueError):
    """A hand joint set that cannot be retargeted; the text names the problem."""


@dataclass(frozen=True, kw_only=True)
class RetargetConfig:
    """A hand's retargeting set-up. palm_from_wrist: rotation (3, 3) from the XR wrist joint's
    frame of a right hand to the robot palm link's frame; origin / task: link names of the
    vector optimizer's vectors, with their human keypoints (MANO indices) human_origin /
    human_task; wrist_link and tip_links (thumb first): DexPilot's; scaling: robot / human hand size;
    extra_frames: {name: (parent link, xyz [m])} added to the hand-only URDF."""

    palm_from_wrist: tuple
    origin: tuple[str, ...]
    task: tuple[str, ...]
    human_origin: tuple[int, ...]
    human_task: tuple[int, ...]
    wrist_link: str
    tip_links: tuple[str, ...]
    scaling: float
    extra_frames: dict


# Allegro palm_link: +x out of the palm, +y toward the thumb and index, +z along the fingers.
# Shadow palm: +x toward the thumb and index, -y out of the palm, +z along the fingers.
_ALLEGRO_TIPS = ("allegro_link_15_tip", "allegro_link_3_tip", "allegro_link_7_tip", "allegro_link_11_tip")
_SHADOW_TIPS = ("shadow_thtip", "shadow_fftip", "shadow_mftip", "shadow_rftip", "shadow_lftip")
CONFIGS = {
    "allegro": RetargetConfig(
        palm_from_wrist=((0, -1, 0), (-1, 0, 0), (0, 0, -1)),
        origin=("allegro_wrist",) * 4, task=_ALLEGRO_TIPS, human_origin=(0,) * 4, human_task=(4, 8, 12, 16),
        wrist_link="allegro_wrist", tip_links=_ALLEGRO_TIPS, scaling=1.6,
        extra_frames={"allegro_wrist": ("allegro_palm_link", (0.0, 0.0, -0.095))}),
    "shadow": RetargetConfig(
        palm_from_wrist=((-1, 0, 0), (0, 1, 0), (0, 0, -1)),
        origin=("shadow_palm",) * 10,
        task=_SHADOW_TIPS + tuple(f"shadow_{f}middle" for f in ("th", "ff", "mf", "rf", "lf")),
        human_origin=(0,) * 10, human_task=(4, 8, 12, 16, 20, 2, 6, 10, 14, 18),
        wrist_link="shadow_palm", tip_links=_SHADOW_TIPS, scaling=1.2,
        extra_frames={"shadow_thtip": ("shadow_thdistal", (0.0, 0.0, 0.0275)),
                      **{f"shadow_{f}tip": (f"shadow_{f}distal", (0.0, 0.0, 0.026))
                         for f in ("ff", "mf", "rf", "lf")}}),
}
PALM_FROM_XR_WRIST = {k: np.asarray(c.palm_from_wrist, float) for k, c in CONFIGS.items()}
"""Rotation (3, 3) from a right hand's XR wrist frame to the robot palm's, per hand kind."""


def check_hand(joints) -> np.ndarray:
    """The joint set as a float array (25, 4, 4), or :class:`HandPoseError` with the reason."""
    a = np.asarray(joints, dtype=float) if not isinstance(joints, np.ndarray) else joints.astype(float)
    if a.shape != (XR_JOINTS, 4, 4):
        raise HandPoseError(f"hand joints: expected shape ({XR_JOINTS}, 4, 4), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise HandPoseError("hand joints: not finite (NaN or infinity)")
    d = np.linalg.norm(a[:, :3, 3] - a[0, :3, 3], axis=1)
    far = int(np.argmax(d))
    if d[far] > MAX_HAND_SPAN:
        raise HandPoseError(f"hand joints: joint {far} is {d[far]:.2f} m from the wrist "
                            f"(at most {MAX_HAND_SPAN} m)")
    r = a[0, :3, :3]
    if np.abs(r.T @ r - np.eye(3)).max() > 1e-3:
        raise HandPoseError("hand joints: the wrist pose has no orthonormal rotation")
    return a


def keypoints(joints, kind: str, side: str = "right") -> np.ndarray:
    """The 21 MANO keypoints (21, 3) [m] of an XR joint set (25, 4, 4), relative to the wrist, in
    the robot palm's frame of hand ``kind``; ``side`` "left" is mirrored onto the right hand."""
    a = check_hand(joints)
    w = a[0]
    local = (a[list(XR_TO_MANO), :3, 3] - w[:3, 3]) @ w[:3, :3]  # rows: R_w^T (p - p_w)
    if side == "left":
        local[:, 0] *= -1.0
    elif side != "right":
        raise HandPoseError(f"hand side must be left or right, got {side!r}")
    return local @ PALM_FROM_XR_WRIST[kind].T


def write_retarget_urdf(kind: str, out_dir: Path, shared_assets: Path | None = None) -> Path:
    """Write ``out_dir/<kind>_retarget.urdf``: hand ``kind`` alone (see the module docstring)."""
    from stages.embodiment.sources import default_shared_assets
    from stages.simulate.hands import add_hand

    if kind not in CONFIGS:
        raise ValueError(f"hand retargeting: unknown hand {kind!r}; known {sorted(CONFIGS)}")
    robot = ET.Element("robot", name=f"{kind}_retarget")
    info = add_hand(robot, kind, Path(shared_assets) if shared_assets else default_shared_assets())
    drop = {f"{info.palm_link}_mount", info.tcp, f"{info.tcp}_joint"}
    for el in list(robot):
        if el.get("name") in drop:
            robot.remove(el)
        for geo in el.findall("visual") + el.findall("collision"):
            el.remove(geo)
    for name, (parent, xyz) in CONFIGS[kind].extra_frames.items():
        link = ET.SubElement(robot, "link", name=name)
        ine = ET.SubElement(link, "inertial")
        ET.SubElement(ine, "mass", value="0.001")
        ET.SubElement(ine, "inertia", ixx="1e-8", ixy="0", ixz="0", iyy="1e-8", iyz="0", izz="1e-8")
        j = ET.SubElement(robot, "joint", name=f"{name}_joint", type="fixed")
        ET.SubElement(j, "parent", link=parent)
        ET.SubElement(j, "child", link=name)
        ET.SubElement(j, "origin", xyz=" ".join(f"{v:.9g}" for v in xyz), rpy="0 0 0")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{kind}_retarget.urdf"
    ET.ElementTree(robot).write(path, xml_declaration=True, encoding="utf-8")
    return path


class HandRetargeter:
    """XR hand joints -> hand ``kind``'s joint targets (see the module docstring).

    work_dir: where the hand-only URDF is written; optimizer: "vector" or "dexpilot";
    low_pass_alpha: the output filter's weight of a new solution (1: no filtering)."""

    def __init__(self, kind: str, work_dir: Path, *, optimizer: str = "vector", low_pass_alpha: float = 0.5,
                 shared_assets: Path | None = None) -> None:
        from dex_retargeting.retargeting_config import RetargetingConfig

        from stages.simulate.hands import allegro_info, shadow_info

        if optimizer not in ("vector", "dexpilot"):
            raise ValueError(f"hand retargeting: optimizer must be vector or dexpilot, got {optimizer!r}")
        self.kind, self.optimizer = kind, optimizer
        self.urdf = write_retarget_urdf(kind, work_dir, shared_assets)
        c = CONFIGS[kind]
        self.joints = (allegro_info() if kind == "allegro" else shadow_info()).joints
        cfg = {"type": optimizer, "urdf_path": str(self.urdf), "scaling_factor": c.scaling,
               "low_pass_alpha": float(low_pass_alpha), "target_joint_names": list(self.joints)}
        if optimizer == "vector":
            cfg |= {"target_origin_link_names": list(c.origin), "target_task_link_names": list(c.task),
                    "target_link_human_indices": [list(c.human_origin), list(c.human_task)]}
        else:
            cfg |= {"wrist_link_name": c.wrist_link, "finger_tip_link_names": list(c.tip_links)}
        self.seq = _build_in_scratch(RetargetingConfig.from_dict(cfg))
        idx = np.asarray(self.seq.optimizer.target_link_human_indices)
        self._origin, self._task = idx[0], idx[1]
        self._pin_idx = np.asarray(self.seq.optimizer.idx_pin2target)
        self.calls = 0

    def reset(self) -> None:
        """Forget the previous solution and the filter's state (a new episode)."""
        self.seq.reset()
        if self.seq.filter is not None:
            self.seq.filter.reset()

    def reference(self, joints, side: str = "right") -> np.ndarray:
        """The optimizer's reference vectors (k, 3) [m, human scale] of an XR joint set."""
        kp = keypoints(joints, self.kind, side)
        return kp[self._task] - kp[self._origin]

    def retarget(self, joints, side: str = "right") -> np.ndarray:
        """Joint targets (n,) [rad] in ``self.joints`` order for an XR joint set (25, 4, 4) [m]."""
        ref = self.reference(joints, side)
        q = self.seq.retarget(ref)  # (robot dof,) in Pinocchio's order
        self.calls += 1
        return np.asarray(q, float)[self._pin_idx]


def _build_in_scratch(config):
    """``config.build()`` with dex-retargeting's scratch copy of the URDF (a ``mkdtemp`` it never
    removes) made in a temporary folder of ours, removed once the model is loaded."""
    import tempfile

    with tempfile.TemporaryDirectory(prefix="aw-retarget-") as scratch:
        before, tempfile.tempdir = tempfile.tempdir, scratch
        try:
            return config.build()
        finally:
            tempfile.tempdir = before
