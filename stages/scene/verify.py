"""Final checks of a populated plan (exact collider penetrations, the robot path of every room) and
the settle repair (dropping instances with everything resting on them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stages.scene.collide import find_penetrations
from stages.scene.solver import Populator


@dataclass(frozen=True)
class CheckReport:
    """Result of the final checks of a populated plan: penetrations (owner pairs, depth [m]) and
    path problems (one line each)."""

    penetrations: tuple[tuple[str, str, float], ...]
    path: tuple[str, ...]

    @property
    def ok(self) -> bool:
        return not self.penetrations and not self.path


def verify(pop: Populator) -> CheckReport:
    """Exact collider check of every instance against the layout and each other, and the path check
    of every populated room (doors connected, every interactable reachable)."""
    from stages.scene.collide import find_penetrations as fp, piece_bounds

    pens: dict[tuple[str, str], float] = {}
    every = [p for o in pop.insts for p in o.pieces]
    (llo, lhi), (plo, phi) = piece_bounds(pop.layout), piece_bounds(every)
    start = 0
    for inst in pop.insts:
        start += len(inst.pieces)  # the pieces of the instances after this one: every[start:]
        bounds = np.concatenate([llo, plo[start:]]), np.concatenate([lhi, phi[start:]])
        for pen in fp(inst.pieces, pop.layout + every[start:], exact=True, bounds=bounds):
            key = (pen.owner_a, pen.owner_b)
            pens[key] = max(pens.get(key, 0.0), pen.depth)
    path: list[str] = []
    for rep in pop.reports:
        room = pop.plan.room(rep.room)
        ctx = pop.room_ctx[room.id]
        grid = pop.grids[room.floor]
        labels = grid.components()
        live = {grid.cell_label(labels, p) for p in ctx.door_points} - {0}
        if len(live) > 1:
            path.append(f"{room.id}: doors not connected by a {grid.radius * 2:.2f} m path")
            continue
        if not live:
            if ctx.door_points:
                path.append(f"{room.id}: no door reachable")
            continue
        lab = next(iter(live))
        reach = pop.rules.setting(room.type, "reach")
        for inst in pop.insts:
            if inst.p.room == room.id and inst.p.record.interactable:
                if not (grid.reach_mask(inst.footprint, reach) & (labels == lab)).any():
                    path.append(f"{room.id}: {inst.p.inst} out of reach")
    return CheckReport(tuple((a, b, d) for (a, b), d in sorted(pens.items())), tuple(path))


def remove_instances(pop: Populator, ids: set[str]) -> None:
    """Drop instances (and everything resting on them) from a populator (the settle repair)."""
    drop = set(ids)
    changed = True
    while changed:
        changed = False
        for i in pop.insts:
            if i.p.support in drop and i.p.inst not in drop:
                drop.add(i.p.inst)
                changed = True
    pop.insts = [i for i in pop.insts if i.p.inst not in drop]
    for g in pop.grids.values():
        for k in list(g.blocks):
            if k in drop:
                del g.blocks[k]
