"""Source files, as every loader sees them: the input limits they share (``LoadLimits``), the checks
on a source file before it is parsed, its content hash and one-line error text.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field

from pipeline.types import ItemError


class LoadLimits(BaseModel):
    """Limits on inputs; a source outside them fails alone with a one-line reason.

    max_file_mb: largest accepted source file [MiB];
    min_dimension_m / max_dimension_m: the asset's largest bounding-box dimension must lie in this
    range after unit conversion [m];
    unit_guess_dimension_m: a mesh without an annotated ``meters_per_unit`` whose largest dimension
    exceeds this many source units is rejected as "probably millimetres/centimetres" [m at 1 m/unit];
    min_hull_volume_m3: a rigid body whose convex hull encloses less than this is flat [m^3].
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    max_file_mb: float = Field(default=200.0, gt=0.0)
    min_dimension_m: float = Field(default=0.001, gt=0.0)
    max_dimension_m: float = Field(default=50.0, gt=0.0)
    unit_guess_dimension_m: float = Field(default=20.0, gt=0.0)
    min_hull_volume_m3: float = Field(default=1e-9, ge=0.0)


def check_source_file(path: Path, limits: LoadLimits) -> None:
    """Raise ItemError if ``path`` is missing, not a regular file, unreadable or larger than allowed."""
    try:
        st = path.stat()
    except FileNotFoundError:
        raise ItemError(f"{path}: source file not found") from None
    except OSError as e:
        raise ItemError(f"{path}: unreadable source file ({e.strerror})") from None
    if not path.is_file():
        raise ItemError(f"{path}: not a regular file")
    size_mb = st.st_size / (1024 * 1024)
    if size_mb > limits.max_file_mb:
        raise ItemError(f"{path}: file is {size_mb:.1f} MiB, over the {limits.max_file_mb:g} MiB limit "
                        f"(max_file_mb)")
    if st.st_size == 0:
        raise ItemError(f"{path}: empty file (0 bytes)")


def _sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _one_line(e: BaseException) -> str:
    msg = " ".join(str(e).split()) or type(e).__name__
    return msg[:300]
