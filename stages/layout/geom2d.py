"""Exact 2-D helpers on axis-aligned rectangles with integer centimeter coordinates.

Plans are built on integers (1 unit = 1 cm) so that shared walls, adjacency and overlaps are exact;
they are converted to meters only when written out.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

Point = tuple[int, int]


@dataclass(frozen=True, order=True)
class Rect:
    """Axis-aligned rectangle [x0, x1] x [y0, y1] in cm (x0 < x1, y0 < y1)."""

    x0: int
    y0: int
    x1: int
    y1: int

    @property
    def w(self) -> int:
        return self.x1 - self.x0

    @property
    def h(self) -> int:
        return self.y1 - self.y0

    @property
    def area(self) -> int:
        return self.w * self.h

    def overlap_area(self, o: "Rect") -> int:
        """Area of the intersection [cm^2] (0 when they only touch)."""
        dx = min(self.x1, o.x1) - max(self.x0, o.x0)
        dy = min(self.y1, o.y1) - max(self.y0, o.y0)
        return dx * dy if dx > 0 and dy > 0 else 0

    def intersects(self, o: "Rect") -> bool:
        """True when the interiors overlap."""
        return self.overlap_area(o) > 0

    def contains(self, x: float, y: float) -> bool:
        """Point strictly inside."""
        return self.x0 < x < self.x1 and self.y0 < y < self.y1

    def inside(self, o: "Rect") -> bool:
        """This rectangle lies within o (boundaries may touch)."""
        return o.x0 <= self.x0 and o.y0 <= self.y0 and self.x1 <= o.x1 and self.y1 <= o.y1

    def transposed(self) -> "Rect":
        return Rect(self.y0, self.x0, self.y1, self.x1)


def make_rect(xa: int, ya: int, xb: int, yb: int) -> Rect:
    """A Rect from two corners in any order."""
    return Rect(min(xa, xb), min(ya, yb), max(xa, xb), max(ya, yb))


def rects_minus(outer: Sequence[Rect], holes: Sequence[Rect]) -> list[Rect]:
    """Decompose (union of ``outer``) minus (union of ``holes``) into few disjoint rectangles.

    Coordinate compression, then row runs merged, then equal runs of consecutive rows merged.
    Deterministic order (by y, then x).
    """
    xs = sorted({v for r in (*outer, *holes) for v in (r.x0, r.x1)})
    ys = sorted({v for r in (*outer, *holes) for v in (r.y0, r.y1)})
    xi = {v: i for i, v in enumerate(xs)}
    yi = {v: i for i, v in enumerate(ys)}
    nx, ny = len(xs) - 1, len(ys) - 1
    filled = [[False] * nx for _ in range(ny)]
    for r in outer:
        for j in range(yi[r.y0], yi[r.y1]):
            for i in range(xi[r.x0], xi[r.x1]):
                filled[j][i] = True
    for r in holes:
        for j in range(yi[r.y0], yi[r.y1]):
            for i in range(xi[r.x0], xi[r.x1]):
                filled[j][i] = False
    open_runs: dict[tuple[int, int], int] = {}  # (i0, i1) -> start row
    out: list[Rect] = []
    for j in range(ny + 1):
        runs: list[tuple[int, int]] = []
        if j < ny:
            i = 0
            while i < nx:
                if filled[j][i]:
                    k = i
                    while k < nx and filled[j][k]:
                        k += 1
                    runs.append((i, k))
                    i = k
                else:
                    i += 1
        current = set(runs)
        for run in sorted(open_runs):
            if run not in current:
                j0 = open_runs.pop(run)
                out.append(Rect(xs[run[0]], ys[j0], xs[run[1]], ys[j]))
        for run in runs:
            open_runs.setdefault(run, j)
    return sorted(out, key=lambda r: (r.y0, r.x0))


def union_area(rects: Iterable[Rect]) -> int:
    """Area of the union [cm^2]."""
    rs = list(rects)
    return sum(r.area for r in rects_minus(rs, [])) if rs else 0


def snap(v: float, step: int = 5) -> int:
    """Round to the nearest multiple of ``step`` (cm)."""
    return int(round(v / step)) * step
