"""A checkpoint in parts small enough to move between machines (issue 17).

The device machine returns at most 8 files of 16 MiB per call (and takes 64 MiB per call), and an
ACT checkpoint is 206 MB: :func:`pack` writes a ``pretrained_model`` folder as ``manifest.json``,
``meta.tar`` (every file but the weights) and ``model.NNN`` parts of at most ``part_mib`` MiB of
``model.safetensors`` (floating tensors as float16 with ``half``: 103 MB for ACT); :func:`unpack`
checks every part against the manifest's SHA-256, joins them and writes the folder back (float16
tensors back to their recorded dtypes), ready for ``agentworld eval`` or ``train-policy --init``::

    python -m stages.policy.ckpt_parts pack RUN/lerobot/checkpoints/last/pretrained_model PARTS --half
    python -m stages.policy.ckpt_parts unpack PARTS CHECKPOINT
"""

from __future__ import annotations

import argparse
import hashlib
import io
import json
import shutil
import sys
import tarfile
from pathlib import Path

MODEL = "model.safetensors"


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def pack(ckpt: Path, out: Path, *, part_mib: float = 15.0, half: bool = True) -> list[Path]:
    """Write ``ckpt`` (a folder with ``model.safetensors``) as parts in ``out`` (see the module
    docstring); returns the files written, manifest first."""
    from safetensors.numpy import load_file, save

    ckpt, out = Path(ckpt), Path(out)
    if not (ckpt / MODEL).is_file():
        raise FileNotFoundError(f"{ckpt}: no {MODEL}")
    if part_mib <= 0:
        raise ValueError(f"pack: part_mib must be > 0, got {part_mib}")
    tensors = load_file(ckpt / MODEL)
    dtypes = {k: str(v.dtype) for k, v in tensors.items()}
    if half:
        tensors = {k: (v.astype("float16") if v.dtype.kind == "f" else v) for k, v in tensors.items()}
    blob = save(tensors)
    out.mkdir(parents=True, exist_ok=True)
    meta = io.BytesIO()
    with tarfile.open(fileobj=meta, mode="w") as tar:
        for p in sorted(ckpt.iterdir()):
            if p.is_file() and p.name != MODEL:
                tar.add(p, arcname=p.name)
    size = max(1, int(part_mib * 2**20))
    parts = [blob[i:i + size] for i in range(0, len(blob), size)] or [b""]
    files = [out / "meta.tar"]
    files[0].write_bytes(meta.getvalue())
    for k, part in enumerate(parts):
        files.append(out / f"model.{k:03d}")
        files[-1].write_bytes(part)
    manifest = {"model_sha256": _sha(blob), "half": half, "dtypes": dtypes, "meta_sha256": _sha(meta.getvalue()),
                "parts": [{"name": f.name, "bytes": len(p), "sha256": _sha(p)} for f, p in zip(files[1:], parts)]}
    (out / "manifest.json").write_text(json.dumps(manifest, indent=1) + "\n")
    return [out / "manifest.json", *files]


def unpack(parts: Path, out: Path) -> Path:
    """Check and join the parts in ``parts`` into the checkpoint folder ``out``; raises
    ``ValueError`` (one line, naming the file) on a missing or damaged part."""
    import numpy as np
    from safetensors.numpy import load, save_file

    parts, out = Path(parts), Path(out)
    try:
        manifest = json.loads((parts / "manifest.json").read_text())
        entries = manifest["parts"]
    except (OSError, ValueError, KeyError) as e:
        raise ValueError(f"{parts / 'manifest.json'}: unreadable manifest ({e})") from None
    chunks = []
    for e in entries:
        p = parts / Path(e["name"]).name  # names only: no path leaves the folder
        if not p.is_file():
            raise ValueError(f"{p}: part missing")
        data = p.read_bytes()
        if _sha(data) != e["sha256"]:
            raise ValueError(f"{p}: damaged part (SHA-256 differs from the manifest)")
        chunks.append(data)
    blob = b"".join(chunks)
    if _sha(blob) != manifest.get("model_sha256"):
        raise ValueError(f"{parts}: the joined parts differ from the packed model")
    meta = (parts / "meta.tar").read_bytes() if (parts / "meta.tar").is_file() else None
    if meta is None or _sha(meta) != manifest.get("meta_sha256"):
        raise ValueError(f"{parts / 'meta.tar'}: missing or damaged")
    tensors = load(blob)
    dtypes = manifest.get("dtypes", {})
    tensors = {k: (v.astype(np.dtype(dtypes[k])) if k in dtypes else v) for k, v in tensors.items()}
    if out.exists():
        raise FileExistsError(f"{out}: exists (unpack writes a new folder)")
    tmp = out.with_name(out.name + ".partial")
    shutil.rmtree(tmp, ignore_errors=True)  # a crashed earlier unpack's
    tmp.mkdir(parents=True)
    try:
        with tarfile.open(fileobj=io.BytesIO(meta)) as tar:
            tar.extractall(tmp, filter="data")
        save_file(tensors, str(tmp / MODEL))
        tmp.rename(out)  # nothing half-written at ``out``
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m stages.policy.ckpt_parts", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("pack")
    a.add_argument("checkpoint", type=Path)
    a.add_argument("out", type=Path)
    a.add_argument("--part-mib", type=float, default=15.0)
    a.add_argument("--half", action="store_true", help="floating tensors as float16 (half the bytes)")
    b = sub.add_parser("unpack")
    b.add_argument("parts", type=Path)
    b.add_argument("out", type=Path, help="the checkpoint folder to write (must not exist)")
    args = p.parse_args(argv)
    try:
        if args.cmd == "pack":
            files = pack(args.checkpoint, args.out, part_mib=args.part_mib, half=args.half)
            print(f"pack: {len(files)} files in {args.out}: " + ", ".join(f.name for f in files))
        else:
            print(f"unpack: {unpack(args.parts, args.out)}")
    except (ValueError, FileNotFoundError, FileExistsError) as e:
        print(f"ckpt_parts: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
