"""A development and test world for the open/close experts: a walled room holding ONE referenced
default-catalog package, simulated with the mobile Panda.

::

    world = write_part_world(dir, package_usd=..., record=info[aid], asset_id=aid, rng=rng)
    sess = PartSession(world, panda_root=None, work_dir=dir)
    res = sess.run(part, "open", seed=3)          # PartEpisode: success, reason, seconds

Placement: a wall-standing asset (fridge, oven, cabinet, kitchen counter, dresser) stands with its
back 2 cm off one of the four walls (chosen by ``rng``), its front (+X) facing into the room; a
microwave stands on a box stand (counter height) the same way; a room door stands free in the
middle of the room (the robot can pass around it). Frame: world, Z up, metres, radians; the room
spans [0, size_x] x [0, size_y].
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.types import ItemError
from stages.demos.parts import ArticulatedPart, part_closed, part_opened, parts_of_package

log = logging.getLogger(__name__)

ASSET_PRIM = "/World/Asset"
WALL_T = 0.1
WALL_H = 2.5
WALL_GAP = 0.02   # asset back to wall [m]
ON_STAND = ("microwave",)
FREE_STANDING = ("door",)


@dataclass(frozen=True, kw_only=True)
class PartWorld:
    """usd: the scene file; size: room interior (x, y) [m]; asset_id; category; pose: the
    package's placement (x, y, z, yaw); parts: its doors and drawers; obstacles (K, 4): footprints
    [xmin, ymin, xmax, ymax] of walls, the asset (closed) and its stand, for base planning."""

    usd: Path
    size: tuple[float, float]
    asset_id: str
    category: str
    pose: tuple[float, float, float, float]
    parts: tuple[ArticulatedPart, ...]
    obstacles: np.ndarray

    def grid(self, extra: np.ndarray | None = None):
        """A :class:`~stages.demos.planner.NavGrid` (5 cm cells) of the obstacles (+ ``extra``)."""
        from stages.demos.planner import NavGrid

        boxes = self.obstacles if extra is None else np.vstack([self.obstacles, np.reshape(extra, (-1, 4))])
        sx, sy = self.size
        return NavGrid.from_boxes((-0.2, -0.2, sx + 0.2, sy + 0.2), boxes)


def package_bounds(package_usd: Path) -> np.ndarray:
    """(2, 3) axis-aligned bounds [min, max] of a package's geometry in its root frame [m]."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(package_usd))
    if stage is None or not stage.GetDefaultPrim():
        raise ItemError(f"{package_usd}: cannot open the package or it has no default prim")
    cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), [UsdGeom.Tokens.default_, UsdGeom.Tokens.render])
    r = cache.ComputeLocalBound(stage.GetDefaultPrim()).ComputeAlignedRange()
    return np.array([list(r.GetMin()), list(r.GetMax())], float)


def _footprint(bounds: np.ndarray, pose) -> tuple[float, float, float, float]:
    """World AABB (xmin, ymin, xmax, ymax) of root-frame bounds placed at pose (x, y, z, yaw)."""
    x, y, _, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    corners = np.array([[bx, by] for bx in bounds[:, 0] for by in bounds[:, 1]])
    w = corners @ np.array([[c, s], [-s, c]]) + [x, y]
    return (*w.min(0), *w.max(0))


def _wall_pose(bounds: np.ndarray, size, wall: int, along: float, z: float) -> tuple[float, ...]:
    """Placement with the asset's back (root min x) WALL_GAP off ``wall`` (0 south, 1 east,
    2 north, 3 west), front facing into the room; ``along`` in [0, 1] along the wall."""
    sx, sy = size
    back = -bounds[0, 0] + WALL_GAP
    half_w = max(-bounds[0, 1], bounds[1, 1]) + 0.1
    if wall == 0:
        return (half_w + along * (sx - 2 * half_w), back, z, math.pi / 2)
    if wall == 1:
        return (sx - back, half_w + along * (sy - 2 * half_w), z, math.pi)
    if wall == 2:
        return (half_w + along * (sx - 2 * half_w), sy - back, z, -math.pi / 2)
    return (back, half_w + along * (sy - 2 * half_w), z, 0.0)


def write_part_world(out_dir: Path, *, package_usd: Path, record: dict, asset_id: str,
                     rng: np.random.Generator, size: tuple[float, float] = (4.5, 4.0),
                     wall: int | None = None) -> PartWorld:
    """Author ``out_dir/scene.usda``: floor, walls, lights, the package referenced at
    :data:`ASSET_PRIM` (placed as the module docstring says; ``wall`` or one from ``rng``) and,
    for a microwave, its stand."""
    from pxr import Gf, Sdf

    from stages.simulate.demo_scene import _add_lights, _box, _walls, _Writer

    out_dir = Path(out_dir)
    package_usd = Path(package_usd).resolve()
    category = str(record.get("category", ""))
    bounds = package_bounds(package_usd)
    sx, sy = size
    stand = None
    if category in FREE_STANDING:
        yaw = float(rng.choice([0.0, math.pi / 2, math.pi, -math.pi / 2]))
        pose = (sx / 2 + float(rng.uniform(-0.2, 0.2)), sy / 2 + float(rng.uniform(-0.2, 0.2)), 0.0, yaw)
    else:
        wall = int(rng.integers(4)) if wall is None else wall
        z = 0.0
        if category in ON_STAND:
            z = float(rng.uniform(0.85, 0.92))
        pose = _wall_pose(bounds, size, wall, float(rng.uniform(0.2, 0.8)), z)
        if category in ON_STAND:
            # a counter-deep stand: its back at the wall, the asset's front 4 cm behind its front edge
            depth = float(bounds[1, 0] - bounds[0, 0]) + 0.04 + WALL_GAP
            width = float(bounds[1, 1] - bounds[0, 1]) + 0.2
            c, s = math.cos(pose[3]), math.sin(pose[3])
            back_x = bounds[0, 0] - WALL_GAP
            mid = back_x + depth / 2
            centre = (pose[0] + c * mid, pose[1] + s * mid, (z - 0.001) / 2)
            stand = (centre, (depth, width, z - 0.001), pose[3])
    w = _Writer()
    w.prim("/World", "Xform", meta={"kind": "assembly"})
    w.prim("/World/PhysicsScene", "PhysicsScene", attrs={
        "physics:gravityDirection": (Sdf.ValueTypeNames.Vector3f, Gf.Vec3f(0, 0, -1)),
        "physics:gravityMagnitude": (Sdf.ValueTypeNames.Float, 9.81)})
    _box(w, "/World/Floor", (sx / 2, sy / 2, -0.05), (sx + 2 * WALL_T, sy + 2 * WALL_T, 0.1),
         (0.6, 0.6, 0.58),
         label="floor")
    for b in _walls(size, WALL_T, WALL_H):
        _box(w, f"/World/{b.name}", b.center, b.size, b.rgb, label="wall")
    if stand is not None:
        _box(w, "/World/Stand", stand[0], stand[1], (0.5, 0.42, 0.35), label="table", yaw=stand[2])
    _add_lights(w, size)
    w.prim(ASSET_PRIM, "Xform")
    usd = out_dir / "scene.usda"
    w.write(usd, "World")
    layer = Sdf.Layer.FindOrOpen(str(usd))
    with Sdf.ChangeBlock():
        spec = layer.GetPrimAtPath(ASSET_PRIM)
        spec.referenceList.Prepend(Sdf.Reference(str(package_usd)))
        a = Sdf.AttributeSpec(spec, "xformOp:translate", Sdf.ValueTypeNames.Double3)
        a.default = Gf.Vec3d(*pose[:3])
        a = Sdf.AttributeSpec(spec, "xformOp:orient", Sdf.ValueTypeNames.Quatd)
        a.default = Gf.Quatd(math.cos(pose[3] / 2), 0.0, 0.0, math.sin(pose[3] / 2))
        a = Sdf.AttributeSpec(spec, "xformOpOrder", Sdf.ValueTypeNames.TokenArray, Sdf.VariabilityUniform)
        a.default = ["xformOp:translate", "xformOp:orient"]
    layer.Save()
    parts = parts_of_package(record, asset_id=asset_id, prim_root=ASSET_PRIM, pose=pose,
                             package_usd=package_usd)
    t = WALL_T
    obstacles = [(-t, -t, sx + t, 0.0), (-t, sy, sx + t, sy + t), (-t, -t, 0.0, sy + t),
                 (sx, -t, sx + t, sy + t),
                 _footprint(bounds, pose)]
    if stand is not None:
        (cx, cy, _), (d, wd, _), yaw = stand
        obstacles.append(_footprint(np.array([[-d / 2, -wd / 2, 0], [d / 2, wd / 2, 0]]), (cx, cy, 0, yaw)))
    log.info("part world %s: %s at %s", usd, asset_id, pose)
    return PartWorld(usd=usd, size=tuple(size), asset_id=asset_id, category=category, pose=tuple(pose),
                     parts=parts, obstacles=np.asarray(obstacles, float))


@dataclass
class PartEpisode:
    """success; reason ("" on success); detail; joint value at the end [rad or m]; sim_seconds;
    wall_seconds."""

    success: bool
    reason: str
    detail: str
    q_end: float
    sim_seconds: float
    wall_seconds: float


class PartSession:
    """The simulation of a :class:`PartWorld` with the mobile Panda (state/action recorder, no
    cameras), running open/close episodes."""

    def __init__(self, world: PartWorld, *, panda_root: Path | None, work_dir: Path, seed: int = 0,
                 device: str = "cpu") -> None:
        from stages.demos.experts import timed_clik
        from stages.demos.record import Commands, Recorder
        from stages.simulate.control import RobotControl
        from stages.simulate.robot import find_panda_description, write_robot_urdf
        from stages.simulate.world import SimConfig, build_sim

        self.world = world
        t0 = time.perf_counter()
        root = find_panda_description(panda_root)
        desc = write_robot_urdf(Path(work_dir) / "robot", panda_root=root)
        spawn = self._free_spot(np.random.default_rng(seed))
        self.sim = build_sim(SimConfig(scenes=(world.usd,), spawn=spawn, device=device), desc,
                             np.random.default_rng(seed))
        self.ctl = RobotControl(self.sim)
        self.ik = timed_clik(desc)
        self.cmd = Commands()
        self.recorder = Recorder(self.sim, self.ik, self.ctl, self.cmd, rig=None, fps=30)
        qs = self.sim.model.joint_q_start.numpy()
        self.coord = {p: int(qs[j]) for j, p in self.sim.scene.joint_path.items()}
        self.build_seconds = time.perf_counter() - t0

    def _free_spot(self, rng: np.random.Generator, part: ArticulatedPart | None = None,
                   q: float = 0.0) -> tuple[float, float, float]:
        """A base pose (x, y, yaw) whose footprint (0.5 m radius) is clear of every obstacle (and of
        ``part`` standing at joint value ``q``)."""
        from stages.demos.part_planning import swept_grid

        grid = self.world.grid()
        if part is not None:
            grid = swept_grid(grid, part, q, q)
        blocked = grid.inflate(0.5)
        for _ in range(500):
            x, y = rng.uniform(0.5, self.world.size[0] - 0.5), rng.uniform(0.5, self.world.size[1] - 0.5)
            iy, ix = grid.cell_of(x, y)
            if not blocked[iy, ix]:
                return (float(x), float(y), float(rng.uniform(-math.pi, math.pi)))
        raise ItemError(f"{self.world.usd}: no free spot for the robot")

    def reset(self, base: tuple[float, float, float], joints: dict[str, float]) -> None:
        """Robot base at ``base`` (x, y, yaw), scene joints (prim path -> value) set."""
        from stages.demos.session import set_coords

        self.sim.reset(base=base)
        self.ctl.reset()
        set_coords(self.sim, {self.coord[p]: v for p, v in joints.items()})
        self.cmd.base_velocity = np.zeros(3)
        self.cmd.gripper, self.cmd.mode = 0.0, 0

    def run(self, part: ArticulatedPart, action: str, *, seed: int, start_fraction: float = 0.9,
            max_seconds: float = 40.0) -> PartEpisode:
        """One episode: ``action`` "open" (from closed) or "close" (from ``start_fraction`` of the
        travel open); robot at a free random pose from ``seed``; expert then predicate."""
        from stages.demos.articulated import close_part, open_part
        from stages.demos.experts import Driver, ExpertFailure
        from stages.demos.record import EpisodeTimeout
        from stages.simulate.state import read_state

        rng = np.random.default_rng(seed)
        q0 = part.closed if action == "open" else part.closed + start_fraction * part.travel
        self.reset(self._free_spot(rng, part, q0), {part.joint_path: q0})
        drv = Driver(self.sim, self.ctl, self.ik, self.cmd, self.recorder, rng)
        t0 = time.perf_counter()
        self.recorder.start(max_seconds)
        reason = detail = ""
        try:
            if action == "open":
                open_part(part, drv, self.world.grid())
            else:
                close_part(part, drv, self.world.grid(), start=q0)
            drv.step(0.5)
        except ExpertFailure as e:
            reason, detail = e.reason, str(e)
        except EpisodeTimeout as e:
            reason, detail = "timeout", str(e)
        finally:
            self.recorder.stop()
            self.ctl.set_base_velocity(0.0, 0.0, 0.0)
        state = read_state(self.sim)
        q = float(state.scene_joints[part.joint_path])
        if not reason:
            ok, reason = part_opened(part, state) if action == "open" else part_closed(part, state)
            detail = reason
        return PartEpisode(success=not reason, reason=reason, detail=detail, q_end=q,
                           sim_seconds=self.sim.time,
                           wall_seconds=time.perf_counter() - t0)
