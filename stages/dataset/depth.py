"""Depth frames as stored in the datasets: 16-bit PNG (lossless, zlib level 1), base64 text.

A dataset's ``depth.<camera>`` feature (:mod:`stages.dataset.schema`) holds one such string per
frame; ``LeRobotDataset`` items and DataLoader batches carry it as ``str`` (a list of ``str`` per
batch). :func:`decode_depth` gives back the exact uint16 millimetres; :func:`depth_keys_of` finds the
depth features of a dataset's ``features`` (``meta/info.json``).
"""

from __future__ import annotations

import base64
from collections.abc import Mapping
from typing import Any

import numpy as np

from .schema import DEPTH_ENCODING

PNG_LEVEL = 1  # zlib level: fast, and most of the gain of higher levels


def encode_depth(depth_mm: np.ndarray) -> str:
    """uint16 (H, W) or (H, W, 1) depth [mm] -> base64 text of its 16-bit PNG."""
    import cv2

    d = np.ascontiguousarray(np.asarray(depth_mm).reshape(np.shape(depth_mm)[:2]))
    if d.dtype != np.uint16:
        raise ValueError(f"depth must be uint16 millimetres, got {d.dtype}")
    ok, buf = cv2.imencode(".png", d, [cv2.IMWRITE_PNG_COMPRESSION, PNG_LEVEL])
    if not ok:
        raise RuntimeError("cv2.imencode failed to write a 16-bit PNG")
    return base64.b64encode(buf.tobytes()).decode("ascii")


def decode_depth(value: str | bytes) -> np.ndarray:
    """base64 text (or raw bytes) of a 16-bit PNG -> uint16 (H, W) depth [mm], exact."""
    import cv2

    raw = base64.b64decode(value, validate=True) if isinstance(value, str) else bytes(value)
    img = cv2.imdecode(np.frombuffer(raw, np.uint8), cv2.IMREAD_UNCHANGED)
    if img is None or img.dtype != np.uint16 or img.ndim != 2:
        raise ValueError("not a one-channel 16-bit PNG depth frame")
    return img


def depth_keys_of(features: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """The depth feature keys of a lerobot ``features`` dict (``info.agentworld_depth`` set)."""
    return [k for k, ft in features.items() if (ft.get("info") or {}).get("agentworld_depth") == DEPTH_ENCODING]
