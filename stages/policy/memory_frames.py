"""lerobot's frame reads from columns held in memory (issue 17: training speed of state policies).

lerobot 0.6.1's ``DatasetReader.get_item`` reads a sample through the Hugging Face dataset: the frame
row, then one query per delta-timestamp key (ACT's 20 future actions, Diffusion Policy's 2 states and
16 actions), each formatted to torch row by row: ~3 ms a sample, so a data loader worker gives ~300
samples/s and a GPU training run of a small state policy waits on its loader (2-3 steps of 128 a second
with one worker). :func:`install` replaces ``get_item`` with the same computation on the dataset's
non-video columns held as tensors (built once per reader, ~5 s and ~40 bytes a frame entry for our
no-camera sets): the frame's values, the delta windows clamped to the episode and their ``*_is_pad``
masks, the task string. Video frames, image transforms and depth units go through lerobot's own code
unchanged (string columns, such as our ``depth.*``, pass through as lerobot passes them); a reader
with language columns or a column of another type keeps lerobot's path.
The tests compare the two item by item.
"""

from __future__ import annotations

import numpy as np

_MARK = "agentworld_memory_frames"


class MemoryColumns:
    """The non-video columns of a reader's Hugging Face dataset as tensors (row-aligned with it),
    each episode's absolute [from, to) index range, and the absolute -> row index map (an array)."""

    def __init__(self, reader) -> None:
        import pyarrow as pa
        import torch

        table = reader.hf_dataset.data.table if hasattr(reader.hf_dataset.data, "table") else reader.hf_dataset.data

        video = set(reader._meta.video_keys)
        self.columns: dict[str, object] = {}
        for name in table.column_names:
            if name in video:
                continue
            col = table.column(name).combine_chunks()
            kind = col.type.value_type if pa.types.is_list(col.type) or pa.types.is_fixed_size_list(col.type) else col.type
            if pa.types.is_string(col.type) or pa.types.is_large_string(col.type):
                self.columns[name] = col.to_pylist()  # lerobot passes strings through (depth.* here)
                continue
            if not (pa.types.is_integer(kind) or pa.types.is_floating(kind) or pa.types.is_boolean(kind)):
                raise TypeError(f"column {name!r} of type {col.type} is not held in memory")
            if kind is not col.type:  # a list column: (rows, n)
                values = col.flatten().to_numpy(zero_copy_only=False).reshape(len(col), -1)
            else:  # a scalar column: (rows,)
                values = col.to_numpy(zero_copy_only=False)
            self.columns[name] = torch.from_numpy(np.array(values, copy=True))
        index = self.columns["index"].numpy().astype(np.int64)
        self.row_of = None  # absolute index -> row (episode-filtered readers)
        if reader._absolute_to_relative_idx is not None:
            self.row_of = np.full(int(index.max()) + 1, -1, np.int64)
            self.row_of[index] = np.arange(len(index))
        eps = reader._meta.episodes
        self.ep_from = {int(e): int(f) for e, f in zip(eps["episode_index"], eps["dataset_from_index"], strict=True)}
        self.ep_to = {int(e): int(t) for e, t in zip(eps["episode_index"], eps["dataset_to_index"], strict=True)}

    def row(self, i: int) -> dict:
        """Row ``i``'s values (lerobot's formatting: a 0-d tensor per scalar, (n,) per list)."""
        return {k: v[i] for k, v in self.columns.items()}

    def rows(self, key: str, absolute: np.ndarray):
        """Column ``key`` at the absolute indices ``absolute`` (K,) -> (K, ...)."""
        return self.columns[key][absolute if self.row_of is None else self.row_of[absolute]]


def _get_item(self, idx) -> dict:
    """``DatasetReader.get_item`` on :class:`MemoryColumns` (see the module docstring)."""
    import torch

    mem = self._aw_memory
    item = mem.row(int(idx))
    ep_idx = int(item["episode_index"])
    abs_idx = int(item["index"])
    query_indices = None
    if self.delta_indices is not None:
        start, end = mem.ep_from[ep_idx], mem.ep_to[ep_idx]
        query_indices, padding = {}, {}
        for key, delta in self.delta_indices.items():
            want = abs_idx + np.asarray(delta, np.int64)
            query_indices[key] = np.clip(want, start, end - 1)
            padding[f"{key}_is_pad"] = torch.from_numpy((want < start) | (want >= end))
        for key, q in query_indices.items():
            if key not in self._meta.video_keys:
                item[key] = mem.rows(key, q)
        item = {**item, **padding}
        query_indices = {k: q.tolist() for k, q in query_indices.items()}
    if len(self._meta.video_keys) > 0:
        current_ts = item["timestamp"].item()
        query_timestamps = self._get_query_timestamps(current_ts, query_indices)
        video_frames = self._query_videos(query_timestamps, ep_idx)
        item = {**video_frames, **item}
    if self._image_transforms is not None:
        for cam in self._meta.camera_keys:
            if cam not in self._meta.depth_keys:
                item[cam] = self._image_transforms(item[cam])
    for key, stored_unit in self._image_depth_units.items():
        if key in item and stored_unit is not None and stored_unit != self._depth_output_unit:
            from lerobot.datasets import dataset_reader as dr

            item[key] = item[key] * dr.MM_PER_METRE if stored_unit == dr.DEPTH_METER_UNIT else item[key] / dr.MM_PER_METRE
    item["task"] = self._meta.tasks.iloc[int(item["task_index"])].name
    return item


def install() -> None:
    """Patch lerobot's ``DatasetReader.get_item`` (idempotent); readers whose dataset has language
    columns keep lerobot's own (:func:`usable`)."""
    from lerobot.datasets.dataset_reader import DatasetReader

    if getattr(DatasetReader.get_item, _MARK, False):
        return
    original = DatasetReader.get_item

    def get_item(self, idx) -> dict:
        return _get_item(self, idx) if usable(self) else original(self, idx)

    setattr(get_item, _MARK, True)
    get_item.lerobot_get_item = original
    DatasetReader.get_item = get_item


def usable(reader) -> bool:
    """Whether :func:`_get_item` serves ``reader``: a loaded dataset with no language columns whose
    other non-video columns are numbers or strings (its :class:`MemoryColumns` is built here, once)."""
    ok = getattr(reader, "_aw_memory_ok", None)
    if ok is None:
        from lerobot.datasets.io_utils import LANGUAGE_COLUMNS

        ok = reader.hf_dataset is not None and not (set(reader.hf_dataset.column_names) & set(LANGUAGE_COLUMNS))
        if ok:
            try:
                reader._aw_memory = MemoryColumns(reader)
            except TypeError:
                ok = False
        reader._aw_memory_ok = ok
    return ok
