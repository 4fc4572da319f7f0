"""What the scene stage needs to know of an asset package, read from its USD (the colliders the
simulator uses, not the visuals): convex collider pieces in the asset's root frame, which of them
move with a joint, the swept 2-D regions of its doors and drawers, and its support surfaces.

All lengths are meters; the asset frame is Z-up with +X its front (asset_catalog conventions).
"""

from __future__ import annotations

import functools
import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from stages.scene.collide import ConvexPiece, convex_piece
from stages.scene.geom import convex_hull_2d, points_in_convex, polygon_area

log = logging.getLogger(__name__)

MIN_SURFACE_AREA = 0.02   # [m^2] smallest support surface
ROBOT_BLOCK_HEIGHT = 0.03  # [m] pieces lower than this (rugs) do not block the robot
SWEEP_SAMPLES = 7         # joint positions sampled over [lower, upper] for the swept region


@dataclass(frozen=True, eq=False)
class Surface:
    """A horizontal support surface: height z [m] above the asset origin; polygon (K, 2) convex
    CCW outline in the asset frame [m]."""

    z: float
    polygon: np.ndarray


@dataclass(frozen=True, eq=False)
class AssetGeometry:
    """Collision-level description of one asset package.

    pieces: convex collider pieces (asset frame, zero joint configuration); moving: per piece, True
    if it belongs to a link moved by a joint; lo, hi (3,): bounds of all pieces [m];
    swings: 2-D convex regions (K, 2) swept by moving links over their joint ranges;
    surfaces: support surfaces of the fixed part; dynamic: has rigid bodies not fixed to the world;
    n_bodies: rigid bodies in the package; mass: total mass of its bodies [kg]; com (3,): their
    center of mass, asset frame [m] (authored MassAPI values; pieces' centroid when none);
    neutral_joints: gravity does no work on any joint (revolute axes vertical, prismatic axes
    horizontal), so joints cannot start moving on their own.
    """

    usd_path: Path
    pieces: tuple[ConvexPiece, ...]
    moving: tuple[bool, ...]
    lo: np.ndarray
    hi: np.ndarray
    swings: tuple[np.ndarray, ...]
    surfaces: tuple[Surface, ...]
    dynamic: bool
    n_bodies: int
    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    neutral_joints: bool = True

    @functools.cached_property
    def footprint(self) -> np.ndarray:
        """(K, 2) convex outline of every piece projected on the floor, asset frame [m]."""
        return convex_hull_2d(np.vstack([p.vertices[:, :2] for p in self.pieces]))

    @functools.cached_property
    def rests_flat(self) -> bool:
        """Whether the asset stands on a flat base: the outline of its collider points within 2 mm of
        its bottom covers >= 30 % of its footprint and holds the center of its colliders (xy) well
        inside. Round things (fruit, balls) fail: their hulls roll when dropped onto a support."""
        pts = np.vstack([p.vertices for p in self.pieces])
        base = pts[pts[:, 2] < self.lo[2] + 0.002][:, :2]
        if len(base) < 3:
            return False
        poly = convex_hull_2d(base)
        if len(poly) < 3:
            return False
        area = polygon_area(poly)
        if area < 0.3 * polygon_area(self.footprint):
            return False
        c = np.mean([p.vertices.mean(axis=0) for p in self.pieces], axis=0)[:2]
        return bool(points_in_convex(c[None], poly, margin=0.1 * np.sqrt(area))[0])

    @functools.cached_property
    def ground_footprint(self) -> np.ndarray | None:
        """Outline of the pieces whose top is above ROBOT_BLOCK_HEIGHT (what blocks a robot; a rug
        does not), or None."""
        pts = [p.vertices[:, :2] for p in self.pieces if p.hi[2] > self.lo[2] + ROBOT_BLOCK_HEIGHT]
        return convex_hull_2d(np.vstack(pts)) if pts else None


@functools.lru_cache(maxsize=512)
def load_asset_geometry(usd_path: Path) -> AssetGeometry:
    """Read an asset package's colliders, joints and surfaces (cached per process)."""
    from pxr import Usd, UsdGeom, UsdPhysics

    import usd_schemas  # noqa: F401  (schema plugin registered before the stage is opened)

    stage = Usd.Stage.Open(str(usd_path))
    if stage is None:
        raise ValueError(f"{usd_path}: cannot open the asset package")
    root = stage.GetDefaultPrim()
    cache = UsdGeom.XformCache()
    root_inv = np.linalg.inv(np.asarray(cache.GetLocalToWorldTransform(root), dtype=np.float64))
    bodies, joints, colliders = [], [], []
    for prim in Usd.PrimRange(root):
        if prim.HasAPI(UsdPhysics.RigidBodyAPI):
            bodies.append(prim.GetPath())
        if prim.IsA(UsdPhysics.Joint):
            joints.append(prim)
        if prim.HasAPI(UsdPhysics.CollisionAPI) and prim.IsA(UsdGeom.Mesh):
            pts = np.asarray(UsdGeom.Mesh(prim).GetPointsAttr().Get(), dtype=np.float64)
            m = np.asarray(cache.GetLocalToWorldTransform(prim), dtype=np.float64) @ root_inv
            colliders.append((prim.GetPath(), pts @ m[:3, :3] + m[3, :3]))
    if not colliders:
        raise ValueError(f"{usd_path}: asset has no collider meshes")
    masses = []
    for b in bodies:
        prim = stage.GetPrimAtPath(b)
        mass_api = UsdPhysics.MassAPI(prim)
        m_attr, c_attr = mass_api.GetMassAttr(), mass_api.GetCenterOfMassAttr()
        if m_attr.HasAuthoredValue() and c_attr.HasAuthoredValue() and float(m_attr.Get()) > 0:
            mb = np.asarray(cache.GetLocalToWorldTransform(prim), dtype=np.float64) @ root_inv
            masses.append((float(m_attr.Get()), np.asarray(c_attr.Get(), dtype=np.float64) @ mb[:3, :3] + mb[3, :3]))
    fixed_to_world, moving_bodies, sweeps, neutral = False, {}, [], True
    for j in joints:
        b0 = j.GetRelationship("physics:body0").GetTargets()
        b1 = j.GetRelationship("physics:body1").GetTargets()
        if j.IsA(UsdPhysics.FixedJoint) and (not b0 or b0[0] not in bodies):
            fixed_to_world = True
        elif j.IsA(UsdPhysics.RevoluteJoint) or j.IsA(UsdPhysics.PrismaticJoint):
            if b1:
                motion, axis = _joint_motion(j, b0[0] if b0 else None, cache, root_inv)
                moving_bodies[b1[0]] = motion
                vertical = abs(float(axis[2])) / max(float(np.linalg.norm(axis)), 1e-12)
                neutral &= vertical > 0.999 if j.IsA(UsdPhysics.RevoluteJoint) else vertical < 1e-3
    pieces, moving = [], []
    for path, pts in colliders:
        body = next((b for b in bodies if path.HasPrefix(b)), None)
        pieces.append(convex_piece(pts))
        moving.append(body in moving_bodies)
        if body in moving_bodies:
            sweeps.append((body, pts))
    swings = []
    for body, motion in moving_bodies.items():
        pts = [pts for b, pts in sweeps if b == body]
        if pts:
            allp = np.vstack(pts)
            swept = np.vstack([motion(allp, s) for s in np.linspace(0.0, 1.0, SWEEP_SAMPLES)])
            swings.append(convex_hull_2d(swept[:, :2]))
    lo = np.min([p.lo for p in pieces], axis=0)
    hi = np.max([p.hi for p in pieces], axis=0)
    fixed_pieces = [p for p, mv in zip(pieces, moving) if not mv]
    if masses and len(masses) == len(bodies):
        mass = sum(m for m, _ in masses)
        com = sum(m * c for m, c in masses) / mass
    else:
        mass, com = 0.0, np.mean([p.vertices.mean(axis=0) for p in pieces], axis=0)
    return AssetGeometry(usd_path=Path(usd_path), pieces=tuple(pieces), moving=tuple(moving), lo=lo, hi=hi,
                         swings=tuple(swings), surfaces=tuple(_surfaces(fixed_pieces, pieces, hi[0])),
                         dynamic=bool(bodies) and not fixed_to_world, n_bodies=len(bodies), mass=mass, com=com,
                         neutral_joints=neutral)


def _joint_motion(joint, body0, cache, root_inv):
    """(a function (points (K, 3) in the asset frame, s in [0, 1]) -> points moved to the joint
    position lower + s (upper - lower), the joint axis (3,) in the asset frame)."""
    from pxr import Gf, UsdPhysics
    from scipy.spatial.transform import Rotation

    prim = joint
    pos0 = np.asarray(prim.GetAttribute("physics:localPos0").Get() or Gf.Vec3f(0, 0, 0), dtype=np.float64)
    rot0 = prim.GetAttribute("physics:localRot0").Get() or Gf.Quatf(1, 0, 0, 0)
    q = np.array([*rot0.GetImaginary(), rot0.GetReal()], dtype=np.float64)
    r0 = Rotation.from_quat(q).as_matrix()
    if body0 is not None:
        m = np.asarray(cache.GetLocalToWorldTransform(prim.GetStage().GetPrimAtPath(body0)), dtype=np.float64) @ root_inv
        b_rot, b_t = m[:3, :3].T, m[3, :3]
    else:
        b_rot, b_t = np.eye(3), np.zeros(3)
    origin = b_rot @ pos0 + b_t
    axis_local = {"X": (1, 0, 0), "Y": (0, 1, 0), "Z": (0, 0, 1)}[str(prim.GetAttribute("physics:axis").Get() or "X")]
    axis = b_rot @ r0 @ np.asarray(axis_local, dtype=np.float64)
    lower = float(prim.GetAttribute("physics:lowerLimit").Get() or 0.0)
    upper = float(prim.GetAttribute("physics:upperLimit").Get() or 0.0)
    revolute = prim.IsA(UsdPhysics.RevoluteJoint)

    def move(pts: np.ndarray, s: float) -> np.ndarray:
        v = lower + s * (upper - lower)
        if revolute:
            rot = Rotation.from_rotvec(axis * np.radians(v)).as_matrix()
            return (pts - origin) @ rot.T + origin
        return pts + axis * v

    return move, axis


def _surfaces(fixed: list[ConvexPiece], every: list[ConvexPiece], front_x: float) -> list[Surface]:
    """Open horizontal tops of fixed pieces (area >= MIN_SURFACE_AREA): nothing right above the
    center, and nothing (a shelf, a door) between the center and the asset's front (+X)."""
    out = []
    for p in fixed:
        top = p.hi[2]
        ring = p.vertices[p.vertices[:, 2] > top - 1e-4][:, :2]
        if len(ring) < 3:
            continue
        poly = convex_hull_2d(ring)
        if len(poly) < 3 or polygon_area(poly) < MIN_SURFACE_AREA:
            continue
        c = poly.mean(axis=0)
        probes = [np.array([c[0], c[1], top + 0.02])]
        probes += [np.array([x, c[1], top + 0.03]) for x in np.arange(c[0], front_x + 0.01, 0.004)]
        if any(_inside(q, x) for q in every if q is not p for x in probes):
            continue
        out.append(Surface(z=float(top), polygon=poly))
    return out


def _inside(p: ConvexPiece, x: np.ndarray) -> bool:
    """Whether point x (3,) lies inside the convex piece (half-space test on its face normals)."""
    if np.any(x < p.lo) or np.any(x > p.hi):
        return False
    return bool(np.all(p.normals @ x < (p.vertices @ p.normals.T).max(axis=0)))


def _hinged(geo: AssetGeometry) -> list[tuple[int, float, float, float, bool]]:
    """The vertically hinged doors' swings of ``geo``: (index in ``geo.swings``, the swing's far x, its
    y_lo, y_hi, hinge at +Y) [m], asset frame. A swing whose far end spans its width (a drawer, a
    bottom-hinged oven door) or reaching under 0.2 m out is none; a door's hinge side is where its
    swing reaches furthest out (the leaf opened to its stop lies along the hinge's line)."""
    out = []
    for k, s in enumerate(geo.swings):
        x_far = float(s[:, 0].max())
        if x_far - geo.hi[0] < 0.2:
            continue
        far = s[s[:, 0] > x_far - 0.02]
        if float(np.ptp(far[:, 1])) > 0.5 * float(np.ptp(s[:, 1])):
            continue
        y_lo, y_hi = float(s[:, 1].min()), float(s[:, 1].max())
        out.append((k, x_far, y_lo, y_hi, float(far[:, 1].mean()) >= 0.5 * (y_lo + y_hi)))
    return out


def stand_zones(geo: AssetGeometry, width: float, depth: float, hinge_width: float = 0.0) -> list[np.ndarray]:
    """Asset-frame rectangles (4, 2) [m] of floor a robot stands on to open and close a vertically
    hinged door: ``width`` out beside each such door's free edge (where the base takes the handle)
    and ``hinge_width`` out beyond its hinge (where the base pushes the open leaf shut), from the
    asset's front face (asset +X) out by ``depth`` or the swing's depth, whichever is larger (see
    :func:`_hinged` for which swings are doors)."""
    out: list[np.ndarray] = []
    for _, x_far, y_lo, y_hi, hinge_up in _hinged(geo):
        x0, x1 = float(geo.hi[0]), float(geo.hi[0] + max(depth, x_far - geo.hi[0]))
        lo_w, hi_w = (width, hinge_width) if hinge_up else (hinge_width, width)
        for y0, y1 in ((y_lo - lo_w, y_lo), (y_hi, y_hi + hi_w)):
            z = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])
            if y1 - y0 > 0 and not any(np.allclose(z, o) for o in out):
                out.append(z)
    return out


def leaf_doors(geo: AssetGeometry) -> int:
    """How many vertically hinged doors ``geo`` has (the doors :func:`leaf_zones` numbers, in order)."""
    return len(_hinged(geo))


def leaf_zones(geo: AssetGeometry, radius: float, door: int | None = None) -> list[np.ndarray]:
    """Asset-frame rectangles (4, 2) [m] of floor a robot's base goes round an open door's leaf on:
    for each vertically hinged door (:func:`_hinged`; ``door``: only the door-th of them), the square
    ``2 radius`` wide centred on the free edge of its leaf opened to its stop (on the hinge's line, the
    swing's far x), less what lies behind the asset's front face. The base's disc (0.4 m radius) passes
    round that edge, and stands beyond it to push the leaf shut, within ~0.8 m of it (organize the
    wardrobe: a leaf ending 0.39 m from a wall left no base to push it shut). None for radius 0."""
    if radius <= 0:
        return []
    doors = _hinged(geo)
    if door is not None:
        doors = [doors[door % len(doors)]] if doors else []
    out = []
    for _, x_far, y_lo, y_hi, hinge_up in doors:
        y = y_hi if hinge_up else y_lo
        x0, x1, y0, y1 = float(geo.hi[0]), x_far + radius, y - radius, y + radius
        out.append(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]))
    return out


def side_zones(geo: AssetGeometry, depth: float, beyond: float) -> list[np.ndarray]:
    """Asset-frame rectangles (4, 2) [m] of floor a robot works from along one of the asset's long
    sides (a bed's): ``depth`` out from its right side (-Y, looking out along +X; a negative
    ``depth``: its left side, +Y), from the asset's back to ``beyond`` past its front, and a
    ``beyond`` square before its front, inward of that side's corner (a bin set down off a bed's foot). None when
    ``depth`` is 0. (The placement solver tries a rule's ``side`` on the right and the left in turn, for the first
    half of its candidate poses.)"""
    if depth == 0:
        return []
    x0, x1 = float(geo.lo[0]), float(geo.hi[0])
    y = float(geo.lo[1]) if depth > 0 else float(geo.hi[1])   # the side's face; the strip reaches y - depth
    lo, hi = sorted((y, y - depth))
    out = [np.array([[x0, lo], [x1 + beyond, lo], [x1 + beyond, hi], [x0, hi]])]
    if beyond > 0:
        lo, hi = sorted((y, y + np.sign(depth) * beyond))  # inward: before the front
        out.append(np.array([[x1, lo], [x1 + beyond, lo], [x1 + beyond, hi], [x1, hi]]))
    return out
