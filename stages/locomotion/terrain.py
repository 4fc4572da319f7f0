"""Per-world terrain of the G1 training environment: flat floors, door thresholds and staircases,
as static boxes in each world of the batched Newton model, with a legged_gym/mjlab-style curriculum.

Every world holds the same ``B = TerrainConfig.num_boxes`` static boxes (Newton and MuJoCo-Warp
need one structure for all worlds); what differs per world is their placement. The kind of a
world is fixed when the model is built (the ``kinds`` shares, in world order); its difficulty
level moves during training: a level is only the boxes' heights, so a level change is a write to
``model.shape_transform`` and one ``SolverMuJoCo.notify_model_changed(SHAPE_PROPERTIES)``.

Geometry (world frame, the robot spawns at x = y = 0 facing +x, the lane is centred on y = 0):

* **flat**: the boxes are parked 1 m under the ground plane.
* **threshold**: ``B`` door thresholds (sills) of depth ``threshold_depth`` across the lane, the
  first at ``start_x``, one every ``threshold_spacing``; height from ``threshold_height`` by level.
* **stairs**: a flight of ``B`` risers up, a landing of ``landing`` and ``B`` risers down (box k
  spans ``[x0 + k run, x_end - k run]``, its top at ``(k + 1) rise``): the robot climbs and descends.
  The run per world is drawn from the layout stage's tread depths (``stages.layout.model.RUN``), the
  rise by level from ``stair_rise``, whose top is the layout stage's steepest riser
  (``stages.layout.model.RISE``).

Shapes: ``N`` worlds, ``B`` boxes per world. Heights [m], distances [m].
"""

from __future__ import annotations

import dataclasses
from typing import Any

import torch

from stages.locomotion.config import TerrainConfig

FLAT, THRESHOLD, STAIRS = 0, 1, 2
KIND_NAMES = ("flat", "threshold", "stairs")
PARKED_TOP = -1.0
"""top of a parked box [m] (under the ground plane, out of the feet's reach)"""


def world_kinds(cfg: TerrainConfig, num_worlds: int) -> torch.Tensor:
    """Kind of each world (N,) long: ``cfg.kinds`` shares of flat / threshold / stairs, interleaved
    so that any prefix of worlds has about the same mix (world i takes the kind whose quota is
    furthest behind)."""
    shares = torch.tensor(cfg.kinds, dtype=torch.float64)
    shares = shares / shares.sum()
    counts = torch.zeros(3, dtype=torch.float64)
    kinds = torch.empty(num_worlds, dtype=torch.long)
    for i in range(num_worlds):
        k = int(torch.argmax(shares * (i + 1) - counts))
        kinds[i] = k
        counts[k] += 1
    return kinds


class TerrainWorlds:
    """The terrain of N worlds: per-world kind, level, box placement, heights under points, and the
    curriculum. Built before the model is finalized (``add_boxes``), bound to it after (``bind``)."""

    def __init__(self, cfg: TerrainConfig, num_worlds: int, device: torch.device, gen: torch.Generator) -> None:
        self.cfg = cfg
        self.num_worlds = n = num_worlds
        self.device = device
        self.gen = gen
        self.kind = world_kinds(cfg, n).to(device)
        b = cfg.num_boxes
        u = torch.rand(n, generator=gen, device=device)
        self.run = cfg.stair_run[0] + (cfg.stair_run[1] - cfg.stair_run[0]) * u
        """tread depth of each world's stairs (N,) [m]"""
        top = cfg.init_max_level
        self.level = torch.randint(0, top + 1, (n,), generator=gen, device=device)
        self.level[self.kind == FLAT] = 0
        k = torch.arange(b, device=device, dtype=torch.float32)[None, :]
        x0 = cfg.start_x
        stairs_end = x0 + 2 * (b - 1) * self.run + cfg.landing                              # (N,)
        lo_s = x0 + k * self.run[:, None]
        hi_s = stairs_end[:, None] - k * self.run[:, None]
        lo_t = (x0 + k * cfg.threshold_spacing).expand(n, b)
        hi_t = lo_t + cfg.threshold_depth
        is_stairs = (self.kind == STAIRS)[:, None]
        self.x_lo = torch.where(is_stairs, lo_s, lo_t)
        """box footprint along x (N, B) [m]; across y the lane spans +-lane_width / 2"""
        self.x_hi = torch.where(is_stairs, hi_s, hi_t)
        self.end_x = torch.where(self.kind == STAIRS, stairs_end, x0 + (b - 1) * cfg.threshold_spacing
                                 + cfg.threshold_depth)
        """x past the last obstacle (N,) [m]; reaching it is success"""
        self.box_half_z = 0.5 * (b * max(cfg.stair_rise) + 0.2)
        self.box_shapes: torch.Tensor | None = None
        self.tops = self.box_tops(torch.arange(n, device=device))

    # ------------------------------------------------------------------ geometry
    def difficulty(self, ids: torch.Tensor) -> torch.Tensor:
        """level / (num_levels - 1) of worlds ``ids`` (K,), in [0, 1]"""
        return self.level[ids].float() / max(self.cfg.num_levels - 1, 1)

    def box_tops(self, ids: torch.Tensor) -> torch.Tensor:
        """Top height of each box (K, B) [m] of worlds ``ids`` at their current level."""
        cfg, b = self.cfg, self.cfg.num_boxes
        d = self.difficulty(ids)[:, None]
        rise = cfg.stair_rise[0] + (cfg.stair_rise[1] - cfg.stair_rise[0]) * d
        sill = cfg.threshold_height[0] + (cfg.threshold_height[1] - cfg.threshold_height[0]) * d
        k = torch.arange(1, b + 1, device=self.device, dtype=torch.float32)[None, :]
        kind = self.kind[ids][:, None]
        tops = torch.where(kind == STAIRS, rise * k, sill.expand(-1, b))
        return torch.where(kind == FLAT, torch.full_like(tops, PARKED_TOP), tops)

    def add_boxes(self, builder: Any, *, mu: float) -> int:
        """Add the ``B`` static boxes of one world to a Newton builder (placeholders: ``bind`` places
        them per world); returns the index of the first box among the builder's shapes."""
        import newton
        import warp as wp

        first = builder.shape_count
        cfg = newton.ModelBuilder.ShapeConfig(mu=mu)
        for _ in range(self.cfg.num_boxes):
            builder.add_shape_box(-1, xform=wp.transform((0.0, 0.0, PARKED_TOP - self.box_half_z),
                                                         wp.quat_identity()),
                                  hx=0.5, hy=0.5 * self.cfg.lane_width, hz=self.box_half_z, cfg=cfg)
        return first

    def bind(self, model: Any, first_box: int, shapes_per_world: int) -> None:
        """Place every world's boxes in ``model`` (before the solver is built or followed by
        ``notify``): x extents by kind, heights by level."""
        import warp as wp

        n, b = self.num_worlds, self.cfg.num_boxes
        self.box_shapes = (torch.arange(n, device=self.device)[:, None] * shapes_per_world + first_box
                           + torch.arange(b, device=self.device)[None, :])
        xf = wp.to_torch(model.shape_transform).view(-1, 7)
        scale = wp.to_torch(model.shape_scale).view(-1, 3)
        ids = self.box_shapes.reshape(-1)
        xf[ids, 0] = (0.5 * (self.x_lo + self.x_hi)).reshape(-1)
        scale[ids, 0] = (0.5 * (self.x_hi - self.x_lo)).reshape(-1)
        self._model = model
        self.apply(torch.arange(n, device=self.device))

    def apply(self, ids: torch.Tensor) -> None:
        """Write the box heights of worlds ``ids`` (K,) at their levels to the model's shape
        transforms (the solver needs ``notify`` afterwards); before ``bind``, only ``tops``."""
        import warp as wp

        self.tops[ids] = self.box_tops(ids)
        if self.box_shapes is None:  # not bound to a model (yet): heights only
            return
        xf = wp.to_torch(self._model.shape_transform).view(-1, 7)
        xf[self.box_shapes[ids].reshape(-1), 2] = (self.tops[ids] - self.box_half_z).reshape(-1)

    def notify(self, solver: Any) -> None:
        """Push the model's shape transforms to a SolverMuJoCo (after the torch writes land: Warp
        launches on its own stream)."""
        import newton

        if self.device.type == "cuda":
            torch.cuda.current_stream(self.device).synchronize()
        solver.notify_model_changed(newton.ModelFlags.SHAPE_PROPERTIES)

    def height_at(self, xy: torch.Tensor) -> torch.Tensor:
        """Terrain height (N,) [m] under one point per world, xy (N, 2) [m] in the world frame."""
        x, y = xy[:, 0:1], xy[:, 1:2]
        inside = (x >= self.x_lo) & (x <= self.x_hi) & (y.abs() <= 0.5 * self.cfg.lane_width)
        h = torch.where(inside, self.tops, torch.zeros_like(self.tops)).amax(dim=1)
        return h.clamp(min=0.0)

    # ------------------------------------------------------------------ curriculum
    def update_levels(self, ids: torch.Tensor, x_travelled: torch.Tensor, commanded: torch.Tensor) -> int:
        """Curriculum at the end of episodes of worlds ``ids`` (K,) (legged_gym's
        ``_update_terrain_curriculum``): up a level when the robot got past the terrain's end
        (``x_travelled`` (K,) [m] along the lane >= ``end_x``), down a level when it covered less than
        ``down_fraction`` of the distance its commands asked for (``commanded`` (K,) [m]); a world
        past the top level gets a random level. Flat worlds stay at level 0. Returns how many worlds
        changed level (their boxes are moved; the solver needs ``notify``)."""
        if len(ids) == 0:
            return 0
        cfg = self.cfg
        terr = self.kind[ids] != FLAT
        up = terr & (x_travelled >= self.end_x[ids])
        down = terr & ~up & (x_travelled < cfg.down_fraction * commanded)
        old = self.level[ids]
        new = old + up.long() - down.long()
        top = cfg.num_levels - 1
        beyond = new > top
        if beyond.any():
            new = torch.where(beyond, torch.randint(0, top + 1, new.shape, generator=self.gen, device=self.device), new)
        new = new.clamp(min=0)
        changed = ids[new != old]
        self.level[ids] = new
        if len(changed):
            self.apply(changed)
        return int(len(changed))

    def mean_level(self) -> float:
        """Mean level of the non-flat worlds (0 when all are flat)."""
        terr = self.kind != FLAT
        return float(self.level[terr].float().mean()) if bool(terr.any()) else 0.0

    def summary(self) -> dict[str, Any]:
        """Counts of worlds per kind and mean level per kind (a dict for logs and tests)."""
        out: dict[str, Any] = {}
        for k, name in enumerate(KIND_NAMES):
            sel = self.kind == k
            out[name] = {"worlds": int(sel.sum()),
                         "mean_level": float(self.level[sel].float().mean()) if bool(sel.any()) else 0.0}
        return out



def build_terrain_model(num_worlds: int, device: Any, terrain: TerrainWorlds, *, foot_mu: float = 0.6,
                        floor_mu: float = 0.3, robot: Any = None) -> tuple[Any, Any]:
    """``robot.build_humanoid_model`` of ``robot`` (a ``HumanoidDescription``, default the G1)
    with the terrain's ``B`` static boxes in every world, placed by
    ``terrain`` (its kinds and levels). Returns ``(model, layout)``; ``layout.shapes_per_world``
    counts the boxes (they follow the robot's shapes in each world)."""
    import newton

    from stages.locomotion.robot import G1, humanoid_builder

    robot, layout = humanoid_builder(robot or G1, foot_mu=foot_mu)
    first_box = terrain.add_boxes(robot, mu=floor_mu)
    layout = dataclasses.replace(layout, shapes_per_world=robot.shape_count)
    scene = newton.ModelBuilder()
    newton.solvers.SolverMuJoCo.register_custom_attributes(scene)
    scene.replicate(robot, num_worlds)
    scene.add_ground_plane(cfg=newton.ModelBuilder.ShapeConfig(mu=floor_mu))
    model = scene.finalize(device=device)
    terrain.bind(model, first_box, layout.shapes_per_world)
    return model, layout
