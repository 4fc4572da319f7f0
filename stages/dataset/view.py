"""A state view of a dataset: the same episodes with some ``observation.state`` entries left out.

Our recorder's ``observation.state`` ends with the base pose in the world (``base_x``, ``base_y``
[m], ``base_theta`` [rad]): right for a dataset, where a consumer may want the whole robot state,
but a poor policy input: every other entry (arm joints, end-effector pose in the base frame, the
task objects' state in the base frame) is robot-relative, while the world pose changes with the
kitchen (a held-out kitchen puts it where training never did) and ``base_theta`` wraps at +-pi.
:func:`write_state_view` writes a LeRobot dataset that lerobot loads and trains as it is: the same
frames, actions, tasks, episodes and videos, with ``observation.state`` holding only the kept
entries (in the source order) and its feature names, ``meta/stats.json`` and per-episode stats cut
to them. ``meta/agentworld.json`` gains ``state_view`` (the source and its state names), so a
policy trained on the view can be fed the same entries in closed loop (:func:`state_columns`).

Videos are linked (hard link where the file system allows, else copied), never rewritten.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Sequence
from pathlib import Path

STATE = "observation.state"


def feature_names(dataset: Path, key: str = STATE) -> list[str] | None:
    """The entry names of ``dataset``'s feature ``key`` (``meta/info.json``; lerobot's
    ``{"motors": [...]}`` form too); None when the feature has none. ValueError naming the file when
    it cannot be read."""
    info = Path(dataset) / "meta" / "info.json"
    try:
        feats = json.loads(info.read_text())["features"]
    except (OSError, KeyError, json.JSONDecodeError) as e:
        raise ValueError(f"{info}: no readable features ({e})") from None
    names = feats.get(key, {}).get("names")
    if isinstance(names, dict):
        names = next(iter(names.values()), None)
    return [str(n) for n in names] if isinstance(names, list) else None


def state_names(dataset: Path) -> list[str]:
    """The names of ``dataset``'s ``observation.state`` entries (``meta/info.json``)."""
    names = feature_names(dataset, STATE)
    shape = json.loads((Path(dataset) / "meta" / "info.json").read_text())["features"].get(STATE, {}).get("shape")
    if names is None or [len(names)] != list(shape or []):
        raise ValueError(f"{Path(dataset) / 'meta' / 'info.json'}: {STATE} has no names list of its shape {shape}")
    return names


def kept_names(dataset: Path, drop: Sequence[str]) -> tuple[list[str], list[str]]:
    """(the state names of ``dataset``, those left after dropping ``drop``); ValueError naming the
    dataset for an unknown name or when nothing would be left."""
    names = state_names(dataset)
    unknown = [n for n in drop if n not in names]
    if unknown:
        raise ValueError(f"state view: {dataset}: no state entries {unknown} (it has {names})")
    keep = [n for n in names if n not in set(drop)]
    if not keep:
        raise ValueError(f"state view: {dataset}: dropping {list(drop)} leaves no state entry")
    return names, keep


def state_columns(source: Sequence[str], wanted: Sequence[str], what: str = "state view") -> list[int]:
    """Indices into ``source`` names of the ``wanted`` names, in ``wanted``'s order; ValueError
    naming the missing ones."""
    index = {n: i for i, n in enumerate(source)}
    missing = [n for n in wanted if n not in index]
    if missing:
        raise ValueError(f"{what}: state entries {missing} are not in the state ({list(source)})")
    return [index[n] for n in wanted]


def _link(src: Path, dst: Path) -> None:
    dst.parent.mkdir(parents=True, exist_ok=True)
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)


def write_state_view(src: Path, dst: Path, drop: Sequence[str]) -> list[str]:
    """Write the view of dataset ``src`` without the state entries ``drop`` to the new folder
    ``dst`` (written beside it, then renamed: nothing half-written stays); returns the kept
    names. ValueError naming ``src`` for an unknown name or when nothing would be kept;
    FileExistsError when ``dst`` exists."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    src, dst = Path(src), Path(dst)
    names, keep_names = kept_names(src, drop)
    keep = state_columns(names, keep_names)
    if dst.exists():
        raise FileExistsError(f"state view: {dst} exists")
    tmp = dst.with_name(f".{dst.name}.partial")
    if tmp.exists():
        shutil.rmtree(tmp)
    try:
        for path in sorted(src.rglob("*")):
            rel = path.relative_to(src)
            if path.is_dir():
                continue
            out = tmp / rel
            out.parent.mkdir(parents=True, exist_ok=True)
            if rel.parts[0] == "data" and path.suffix == ".parquet":
                table = pq.read_table(path)
                col = table.column(STATE).combine_chunks()
                values = np.asarray(col.flatten().to_numpy(zero_copy_only=False)).reshape(len(col), len(names))
                cut = pa.array(list(values[:, keep]), type=col.type)
                table = table.set_column(table.schema.get_field_index(STATE), STATE, cut)
                pq.write_table(table, out)
            elif rel.parts[:2] == ("meta", "episodes") and path.suffix == ".parquet":
                table = pq.read_table(path)
                for i, field in enumerate(table.schema):
                    if field.name.startswith(f"stats/{STATE}/"):
                        rows = table.column(i).to_pylist()
                        cut = [r if r is None or len(r) != len(names) else [r[k] for k in keep] for r in rows]
                        table = table.set_column(i, field, pa.array(cut, type=field.type))
                pq.write_table(table, out)
            elif rel == Path("meta/info.json"):
                info = json.loads(path.read_text())
                feat = info["features"][STATE]
                feat["shape"] = [len(keep_names)]
                feat["names"] = keep_names
                out.write_text(json.dumps(info, indent=4) + "\n")
            elif rel == Path("meta/stats.json"):
                stats = json.loads(path.read_text())
                for k, v in stats.get(STATE, {}).items():
                    if isinstance(v, list) and len(v) == len(names):
                        stats[STATE][k] = [v[j] for j in keep]
                out.write_text(json.dumps(stats, indent=4) + "\n")
            elif rel == Path("meta/agentworld.json"):
                meta = json.loads(path.read_text())
                meta["state_view"] = {"source": str(src.resolve()), "source_state": names, "state": keep_names}
                out.write_text(json.dumps(meta, indent=2) + "\n")
            else:
                _link(path, out)
        tmp.rename(dst)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return keep_names
