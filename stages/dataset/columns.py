"""The frames of one frame step as columns (issue 12): a batched engine hands a writer pool all its
worlds' frames of a step at once (:meth:`stages.dataset.pool.ShardPool.add_frames`).

A :class:`FrameColumns` holds K frames' non-image fields, each a (K, ...) array (a scalar field a
(K,) array); images stay in the render's stacked buffers (camera -> RGB (B, H, W, 3) uint8, depth
(B, H, W) uint16 [mm]) and a frame names its row in them. :func:`suspect_rows` screens all K frames
with a few array operations: it passes only frames that :func:`~stages.dataset.schema.frame_problems`
passes, and marks the rest for that per-frame check (the authority: a bad frame is still rejected
with its own message). :func:`pack_columns` packs the numeric fields of the frames in the layout of
the pool's per-frame message, so the writer process rebuilds the same :class:`Frame` values.
"""

from __future__ import annotations

import dataclasses
import struct
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .schema import MODE_LOCOMOTION, MODE_MANIPULATION, DatasetSpec, Frame

IMAGE_FIELDS = ("rgb", "depth_mm")
NUMERIC = tuple(f.name for f in dataclasses.fields(Frame) if f.name not in IMAGE_FIELDS)
"""Frame's non-image fields, in the order of the pool's messages."""
SCALAR_FLOAT, SCALAR_INT, VECTOR, NONE = 0, 1, 2, 3  # NONE: an optional field left None
_SCALARS = ("gripper", "mode", "subtask_index")
_NUMBER = (np.integer, np.floating)

Images = Mapping[str, tuple[np.ndarray, np.ndarray]]
"""camera -> (RGB (B, H, W, 3) uint8, depth (B, H, W) uint16 [mm]): a render's stacked buffers."""


@dataclass
class FrameColumns:
    """K frames' non-image fields: name (a :class:`Frame` field) -> (K, ...) array; scalar fields
    (gripper of a one-arm spec, mode, subtask_index) (K,). hand_joint_pos/target default to (K, 0),
    subtask_index to zeros; state_vector, action_vector and environment_state may be left out (None
    in every frame)."""

    fields: dict[str, np.ndarray]

    def __post_init__(self) -> None:
        unknown = set(self.fields) - set(NUMERIC)
        if unknown:
            raise ValueError(f"FrameColumns: unknown fields {sorted(unknown)}")
        k = len(self)
        self.fields.setdefault("hand_joint_pos", np.zeros((k, 0)))
        self.fields.setdefault("hand_joint_target", np.zeros((k, 0)))
        self.fields.setdefault("subtask_index", np.zeros(k, np.int64))
        bad = [n for n, c in self.fields.items() if len(c) != k]
        if bad:
            raise ValueError(f"FrameColumns: fields {bad} do not have {k} rows")

    def __len__(self) -> int:
        return len(next(iter(self.fields.values()))) if self.fields else 0

    def take(self, rows: list[int]) -> FrameColumns:
        """The frames ``rows`` (this object itself when that is all of them, in order)."""
        if len(rows) == len(self) and all(r == j for j, r in enumerate(rows)):
            return self
        idx = np.asarray(rows, np.intp)
        return FrameColumns({n: c[idx] for n, c in self.fields.items()})

    def frame(self, j: int, rgb: Mapping[str, np.ndarray] | None = None,
              depth_mm: Mapping[str, np.ndarray] | None = None) -> Frame:
        """Frame ``j`` (vectors: views of row j; scalar fields: Python numbers)."""
        values = {n: (c[j].item() if c.ndim == 1 else c[j]) for n, c in self.fields.items()}
        return Frame(**values, rgb={} if rgb is None else rgb, depth_mm={} if depth_mm is None else depth_mm)


def frame_images(images: Images, row: int, copy: bool = False) -> tuple[dict, dict]:
    """The RGB and depth images (by camera) of row ``row`` of stacked buffers (either may be None:
    that camera records no such image): views, or copies."""
    def pick(k: int) -> dict:
        return {c: (im[k][row].copy() if copy else im[k][row]) for c, im in images.items() if im[k] is not None}

    return pick(0), pick(1)


def _images_ok(spec: DatasetSpec, images: Images) -> bool:
    """Every spec camera's RGB (and depth where the camera records it; None where it does not),
    and nothing else, in the shapes and dtypes a frame needs."""
    if set(images) != {c.name for c in spec.cameras} or not all(c.rgb for c in spec.cameras):
        return False
    for c in spec.cameras:
        rgb, depth = images[c.name]
        if not (isinstance(rgb, np.ndarray) and rgb.dtype == np.uint8 and rgb.shape[1:] == (c.height, c.width, 3)):
            return False
        if not c.depth:
            if depth is not None:
                return False
        elif not (isinstance(depth, np.ndarray) and depth.dtype == np.uint16
                  and depth.shape[1:] == (c.height, c.width)):
            return False
    return True


def _numeric(c: np.ndarray) -> bool:
    return isinstance(c, np.ndarray) and np.issubdtype(c.dtype, np.number) and c.dtype != np.bool_


def suspect_rows(spec: DatasetSpec, cols: FrameColumns, images: Images) -> np.ndarray:
    """bool (K,): the frames that need the per-frame check (:func:`frame_problems`); every other
    frame is valid. All K are suspect where the screen does not apply (a spec with an embodiment
    layout, images or fields of another shape or type)."""
    k = len(cols)
    every = np.ones(k, bool)
    f = cols.fields
    if spec.state_layout or not _images_ok(spec, images):
        return every
    n, e, h = spec.arm_dof, spec.ee_count, len(spec.hand_joints)
    dims = {"arm_joint_pos": n, "ee_pose": 7 * e, "base_pose": 3, "arm_joint_target": n, "ee_target": 7 * e,
            "base_velocity": 3, "hand_joint_pos": h, "hand_joint_target": h}
    bad = np.zeros(k, bool)
    for name, d in dims.items():
        c = f.get(name)
        if c is None or not _numeric(c) or c.shape != (k, d):
            return every
        bad |= ~np.isfinite(c).all(axis=1)
    for name in ("ee_pose", "ee_target"):
        q = f[name].reshape(k, e, 7)[..., 3:].astype(np.float64)
        with np.errstate(invalid="ignore"):  # NaN rows are bad already
            bad |= (np.abs(np.linalg.norm(q, axis=-1) - 1.0) > 1e-3 - 1e-9).any(axis=1)  # margin: stricter
    g = f.get("gripper")
    if g is None or not _numeric(g) or g.shape != ((k, e) if spec.arms else (k,)):
        return every
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(g) & (g >= 0.0) & (g <= 1.0)
    bad |= ~(ok.all(axis=1) if spec.arms else ok)
    m = f.get("mode")
    if m is None or not _numeric(m) or m.shape != (k,):
        return every
    bad |= ~((m == MODE_LOCOMOTION) | (m == MODE_MANIPULATION))
    s = f["subtask_index"]
    if spec.subtasks:
        if not (isinstance(s, np.ndarray) and np.issubdtype(s.dtype, np.integer) and s.shape == (k,)):
            return every
        bad |= s < 0
    env = f.get("environment_state")
    if spec.environment_state:
        if env is None or not _numeric(env) or env.shape != (k, len(spec.environment_state)):
            return every
        bad |= ~np.isfinite(env).all(axis=1)
    elif env is not None:
        return every
    if any(f.get(v) is not None for v in ("state_vector", "action_vector")):
        return every
    return bad


def _kind(name: str, c: np.ndarray | None) -> tuple[int, int]:
    """(kind, length) of a column as the per-frame packing (``pool._pack_numeric``) gives it."""
    if c is None:
        return NONE, 0
    if c.ndim == 1 and name in _SCALARS:
        return (SCALAR_INT, 1) if np.issubdtype(c.dtype, np.integer) else (SCALAR_FLOAT, 1)
    return VECTOR, int(np.prod(c.shape[1:]))


def pack_columns(cols: FrameColumns) -> tuple[bytes, np.ndarray]:
    """(header, values): the per-field (kind, length) header of every frame (uint16 pairs in
    :data:`NUMERIC` order, as the per-frame message) and a (K, L) float64 array, row j the values
    of frame j (its bytes follow the header in frame j's message)."""
    k = len(cols)
    kinds, values = [], []
    for name in NUMERIC:
        c = cols.fields.get(name)
        kind = _kind(name, c)
        kinds.append(kind)
        if kind[0] != NONE and kind[1]:
            values.append(np.asarray(c, np.float64).reshape(k, -1))
    head = struct.pack(f"<{2 * len(kinds)}H", *[x for kd in kinds for x in kd])
    return head, (np.concatenate(values, axis=1) if values else np.zeros((k, 0)))
