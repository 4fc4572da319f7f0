"""The dual-arm platform's double-door task (issue 14: "open a double-door cabinet or fridge with
both arms"): the scene, the geometry of the doors' swing and the success predicate. The expert
(each arm takes one door's handle and swings its door open) is not built yet.

The catalog's two-door furniture (generators in :mod:`asset_catalog.generators`): ``wardrobe``
(always two doors, hinged on the outer sides, vertical bar handles 5 cm either side of the middle,
1.05 m high), ``closet`` (2-4 doors; two-door closets hinge like the wardrobe) and the
``side_by_side`` fridge. ``cabinet`` (0.72-0.9 m) has drawers only. The scene uses a wardrobe
(``wardrobe_01``: 0.92 m wide) standing on the floor, its front towards the robot.

- :func:`write_double_door_scene`: floor and the asset, turned to face the robot (its front towards
  -X), placed so that its handles' midpoint is at ``handles_xy``; the returned
  :class:`DoubleDoorScene` says which door each arm takes (the left arm, at +Y, the door whose
  handle is at +Y), each door's joint, hinge line and handle.
- :func:`handle_on_swing`: where a door's handle is when the door has turned by an angle (the
  expert's waypoints).
- :func:`judge_doors`: success from both joint angles: each door open at least ``DOOR_OPEN_DEG``.

Frames: world, Z up, metres; angles in degrees where named ``*_deg``, else radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

DOOR_OPEN_DEG = 70.0  # [deg] a door counts as open from this angle on
PACKAGE = "wardrobe_01"
ARMS = ("left", "right")


@dataclass(frozen=True, kw_only=True)
class Door:
    """One door as an arm sees it: joint (prim path of its revolute joint), body (the door link's
    prim path), handle (3,) [m] the bar handle's centre with the door shut, hinge (3,) [m] a point
    on the hinge line (vertical), opening: +1 / -1, the sense (about +Z) in which the door swings
    open."""

    joint: str
    body: str
    handle: np.ndarray
    hinge: np.ndarray
    opening: int


@dataclass(frozen=True, kw_only=True)
class DoubleDoorScene:
    """usd: the scene file; doors: arm name ("left", "right") -> :class:`Door`."""

    usd: Path
    doors: dict[str, Door]

    def angles(self, sim) -> dict[str, float]:
        """Each arm's door angle [rad] now (0 shut, positive open)."""
        q = sim.state_0.joint_q.numpy()
        out = {}
        for arm, d in self.doors.items():
            j = next(j for j, p in sim.scene.joint_path.items() if p == d.joint)
            out[arm] = float(q[int(sim.model.joint_q_start.numpy()[j])])
        return out


def handle_on_swing(door: Door, angle: float) -> np.ndarray:
    """The handle's centre (3,) [m] with ``door`` turned ``angle`` [rad] open about its hinge line."""
    a = door.opening * float(angle)
    r = np.asarray(door.handle, float) - np.asarray(door.hinge, float)
    c, s = math.cos(a), math.sin(a)
    return np.asarray(door.hinge, float) + np.array([c * r[0] - s * r[1], s * r[0] + c * r[1], r[2]])


def judge_doors(angles_rad: dict[str, float], *, min_deg: float = DOOR_OPEN_DEG) -> tuple[bool, str, dict]:
    """Success of a double-door episode from both door angles (arm -> rad): every door open at least
    ``min_deg``. Returns (success, reason, detail): reason "" or "<arm>_door_shut" for the first
    arm's door short of it ("doors_shut" when both are); detail: the angles in degrees."""
    deg = {a: round(math.degrees(v), 2) for a, v in angles_rad.items()}
    if set(deg) != set(ARMS):
        raise ValueError(f"judge_doors: angles of arms {sorted(deg)}, expected {list(ARMS)}")
    short = [a for a in ARMS if deg[a] < min_deg]
    reason = "" if not short else "doors_shut" if len(short) == 2 else f"{short[0]}_door_shut"
    return not short, reason, {"door_deg": deg}


def joint_frames(usd: Path) -> dict[str, tuple[np.ndarray, float]]:
    """Revolute joints of a package's USD ``usd``: joint name -> (a point on its axis (3,) [m] in
    the asset frame, the z component of its axis there). (The package's ``base`` link sits at the
    asset origin; the generators' door hinges are vertical.)"""
    from pxr import Gf, Usd, UsdPhysics

    out, stage = {}, Usd.Stage.Open(str(usd))
    for prim in stage.Traverse():
        if prim.IsA(UsdPhysics.RevoluteJoint):
            j = UsdPhysics.RevoluteJoint(prim)
            axis = Gf.Vec3d(*[float(k == j.GetAxisAttr().Get()) for k in "XYZ"])
            r = j.GetLocalRot0Attr().Get()
            az = Gf.Rotation(Gf.Quatd(r)).TransformDir(axis)[2] if r is not None else axis[2]
            out[prim.GetName()] = (np.asarray(j.GetLocalPos0Attr().Get(), float), float(az))
    return out


def doors_of(info: dict, joints: dict[str, tuple[np.ndarray, float]], pos, yaw: float) -> dict[str, Door]:
    """The two doors of a catalog record ``info`` (its ``handles``) with their ``joints``
    (:func:`joint_frames`; a door link ``L``'s joint is ``L_joint``) placed at ``pos`` (3,) [m]
    turned ``yaw`` [rad], assigned to the arms: the door whose handle is at the larger world Y to
    the left arm. Raises ValueError unless exactly two doors have vertical bar handles."""
    from stages.demos.hand_scene import OBJECT_PRIM

    handles = [h for h in info.get("handles", ()) if tuple(h.get("bar_axis", ())) == (0.0, 0.0, 1.0)]
    if len(handles) != 2 or any(f"{h['link']}_joint" not in joints for h in handles):
        raise ValueError(f"{info.get('asset_id', 'asset')}: expected two hinged doors with vertical bar "
                         f"handles, found handles on {[h['link'] for h in handles]}")
    c, s = math.cos(yaw), math.sin(yaw)

    def world(p) -> np.ndarray:
        p = np.asarray(p, float)
        return np.array([pos[0] + c * p[0] - s * p[1], pos[1] + s * p[0] + c * p[1], pos[2] + p[2]])

    doors = []
    for h in handles:
        origin, axis_z = joints[f"{h['link']}_joint"]
        doors.append(Door(joint=f"{OBJECT_PRIM}/joints/{h['link']}_joint", body=f"{OBJECT_PRIM}/{h['link']}",
                          handle=world(h["center"]), hinge=world(origin), opening=1 if axis_z > 0 else -1))
    doors.sort(key=lambda d: -d.handle[1])
    return dict(zip(ARMS, doors, strict=True))


def write_double_door_scene(path: Path, asset, *, handles_xy=(0.62, 0.0)) -> DoubleDoorScene:
    """Author the scene at ``path``: floor and ``asset`` (a two-door package, e.g. a wardrobe) on it,
    turned to face the robot (its front towards -X), placed so that the midpoint of its two door
    handles is at ``handles_xy`` [m]."""
    from stages.demos.hand_scene import table_world, write_object_world

    yaw = math.pi
    joints = joint_frames(asset.usd)
    probe = doors_of(asset.info, joints, (0.0, 0.0, 0.0), yaw)
    mid = (probe["left"].handle + probe["right"].handle) / 2
    pos = (handles_xy[0] - mid[0], handles_xy[1] - mid[1], 0.0)
    path = Path(path)
    w = table_world(table_xy=(-3.0, -3.0), table_size=(0.1, 0.1), table_height=0.05)   # no table in reach
    write_object_world(path, w, asset, pos, yaw)
    return DoubleDoorScene(usd=path, doors=doors_of(asset.info, joints, pos, yaw))
