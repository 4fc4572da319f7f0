"""Bimanual scripted experts for the dual-arm platform (:mod:`stages.simulate.dual_arm`) and the
table scene they work in.

- :func:`write_tray_scene`: floor, a table (static boxes) and a serving tray on it (a rigid body:
  a floor plate and four rims, :class:`TraySpec`), as a USD scene that
  :func:`stages.simulate.world.build_sim` loads like a composed scene.
- :func:`lift_tray`: both grippers come down top-down onto the middle of the tray's two side rims
  (the fingers straddling each rim, closing across it), close, lift the tray ``lift`` [m]
  straight up with both arms at once, and hold it ``hold`` [s]. The two grasps lie on one line
  above the tray's centre of mass, so the tray hangs level about that line; its roll about the
  other axis follows the two TCP heights. Returns the measured :class:`TrayLift`.

Frames: world, Z up, metres, radians; the robot's root at the spawn pose.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

TRAY_PRIM = "/World/Tray"


@dataclass(frozen=True, kw_only=True)
class TraySpec:
    """A serving tray: outer size (x, y) [m], height (floor bottom to rim top) [m], rim and floor
    thickness [m], mass [kg] (a 26 x 36 cm plastic tray: about 0.4 kg)."""

    size: tuple[float, float] = (0.26, 0.36)
    height: float = 0.05
    rim: float = 0.008
    floor: float = 0.006
    mass: float = 0.4

    def boxes(self) -> dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]]:
        """Part name -> (centre, size) [m] in the tray frame (origin: the floor's bottom centre)."""
        sx, sy = self.size
        h, t, f = self.height, self.rim, self.floor
        zr = f + (h - f) / 2
        return {"Floor": ((0.0, 0.0, f / 2), (sx, sy, f)),
                "RimFront": ((sx / 2 - t / 2, 0.0, zr), (t, sy, h - f)),
                "RimBack": ((-sx / 2 + t / 2, 0.0, zr), (t, sy, h - f)),
                "RimLeft": ((0.0, sy / 2 - t / 2, zr), (sx - 2 * t, t, h - f)),
                "RimRight": ((0.0, -sy / 2 + t / 2, zr), (sx - 2 * t, t, h - f))}


@dataclass(frozen=True, kw_only=True)
class TrayScene:
    """usd: the scene file; body: the tray's rigid-body prim path; tray; position: the tray
    origin's start position (3,) [m]; table_height [m]."""

    usd: Path
    body: str
    tray: TraySpec
    position: tuple[float, float, float]
    table_height: float


def write_tray_scene(path: Path, *, tray: TraySpec | None = None, table_xy=(0.62, 0.0), table_size=(0.6, 0.9),
                     table_height: float = 0.55, tray_xy=(0.46, 0.0)) -> TrayScene:
    """Author the scene at ``path`` (.usda): floor, a table whose top centre is at ``table_xy``
    [m] with its surface at ``table_height`` [m], and ``tray`` standing on it at ``tray_xy``."""
    from pxr import Gf, Sdf

    from stages.simulate.demo_scene import _box, _labels, _Writer, _xform_attrs

    tray = tray or TraySpec()
    path = Path(path)
    w = _Writer()
    w.prim("/World", "Xform", meta={"kind": "assembly"})
    w.prim("/World/PhysicsScene", "PhysicsScene", attrs={
        "physics:gravityDirection": (Sdf.ValueTypeNames.Vector3f, Gf.Vec3f(0, 0, -1)),
        "physics:gravityMagnitude": (Sdf.ValueTypeNames.Float, 9.81)})
    _box(w, "/World/Floor", (0.0, 0.0, -0.05), (6.0, 6.0, 0.1), (0.6, 0.6, 0.58), label="floor")
    la, lv = _labels("table")
    w.prim("/World/Table", "Xform", apis=la, attrs=lv)
    t = 0.04
    _box(w, "/World/Table/Top", (*table_xy, table_height - t / 2), (*table_size, t), (0.55, 0.4, 0.3))
    _box(w, "/World/Table/Base", (*table_xy, (table_height - t) / 2),
         (table_size[0] * 0.5, table_size[1] * 0.5, table_height - t), (0.4, 0.3, 0.25))
    pos = (float(tray_xy[0]), float(tray_xy[1]), float(table_height) + 0.0005)
    la, lv = _labels("tray")
    w.prim(TRAY_PRIM, "Xform", apis=["PhysicsRigidBodyAPI", "PhysicsMassAPI", *la],
           attrs={**_xform_attrs(pos), **lv, "physics:mass": (Sdf.ValueTypeNames.Float, tray.mass)})
    for name, (c, s) in tray.boxes().items():
        _box(w, f"{TRAY_PRIM}/{name}", c, s, (0.75, 0.72, 0.65))
    w.write(path, "World")
    return TrayScene(usd=path, body=TRAY_PRIM, tray=tray, position=pos, table_height=float(table_height))


# --------------------------------------------------------------------------------------------
# the tray lift
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class TrayLift:
    """What the tray lift measured. lift: rise of the tray [m] after the lift; lift_held: after
    the hold; tilt / tilt_max: angle [deg] of the tray's up axis from the vertical at the end of
    the hold / the largest during the hold; slip: largest change [m] of the tray's position
    relative to either TCP over the hold; gripped: per arm, the fingers touching the tray after
    the hold (0-2); height_error: difference of the two TCP heights [m] at the end."""

    lift: float
    lift_held: float
    tilt: float
    tilt_max: float
    slip: float
    gripped: dict[str, int]
    height_error: float


def tilt_deg(quat_xyzw) -> float:
    """Angle [deg] between a body's +Z (from its quaternion x, y, z, w) and the world's +Z."""
    from scipy.spatial.transform import Rotation

    z = Rotation.from_quat(np.asarray(quat_xyzw, float)).apply([0.0, 0.0, 1.0])
    return float(np.degrees(np.arccos(np.clip(z[2], -1.0, 1.0))))


def rim_grasps(scene: TrayScene, tray_q, *, depth: float = 0.015) -> dict[str, np.ndarray]:
    """TCP poses (4, 4), world, for the two side rims of the tray at pose ``tray_q`` (7,) (x, y,
    z, quaternion x, y, z, w): over the middle of each rim's centre line, ``depth`` [m] below its
    top, pointing down with the fingers closing across the rim; "left" takes the +Y rim."""
    from scipy.spatial.transform import Rotation

    from stages.simulate.control import pose, top_down

    r = Rotation.from_quat(tray_q[3:7])
    yaw = float(r.as_euler("xyz")[2])
    tr = scene.tray
    out = {}
    for arm, s in (("left", 1.0), ("right", -1.0)):
        local = np.array([0.0, s * (tr.size[1] / 2 - tr.rim / 2), tr.height - depth])
        # fingers close along the tray's Y (across the rim); the TCP's X points back at the robot
        out[arm] = pose(r.apply(local) + tray_q[:3], top_down(yaw + np.pi))
    return out


def gripper_contacts(sim, desc, body: int, world: int = 0) -> dict[str, int]:
    """Per arm, how many of its two fingers touch model body ``body`` now."""
    from stages.demos.hand_grasps import touching_pairs

    fingers = {sim.world_body(link, world): arm for arm, a in desc.arms.items() for link in a.finger_links}
    out = {arm: set() for arm in desc.arms}
    for a, b in touching_pairs(sim, world):
        for f, o in ((a, b), (b, a)):
            if o == body and f in fingers:
                out[fingers[f]].add(f)
    return {arm: len(v) for arm, v in out.items()}


def lift_tray(sim, ctl, ik, scene: TrayScene, *, lift: float = 0.10, hold: float = 2.0, above: float = 0.08,
              close_time: float = 0.6, world: int = 0) -> TrayLift:
    """The tray lift expert (see the module docstring) in ``sim`` with ``ctl`` (a
    :class:`stages.simulate.bimanual_control.BimanualControl`) and ``ik`` (``BimanualIk``):
    pre-grasp ``above`` [m] over both rims, down, close over ``close_time`` [s], lift, hold."""
    from stages.simulate.bimanual_control import move_arms

    body = sim.body_of_path(scene.body, world)
    bq = sim.state_0.body_q.numpy()[body]
    grasps = rim_grasps(scene, bq)
    pre = {a: _raised(p, above) for a, p in grasps.items()}
    ctl.set_gripper(0.0, world)
    move_arms(sim, ctl, ik, pre, 2.0, segments=8, settle=0.3, world=world)
    move_arms(sim, ctl, ik, grasps, 1.0, segments=4, settle=0.3, world=world)
    z0 = float(sim.state_0.body_q.numpy()[body][2])
    steps = max(1, int(round(close_time / sim.settings.dt)))
    for i in range(0, steps, 10):
        ctl.set_gripper(min(1.0, (i + 10) / steps), world)
        sim.step(10)
    sim.step(int(round(0.3 / sim.settings.dt)))
    move_arms(sim, ctl, ik, {a: _raised(p, lift) for a, p in grasps.items()}, 2.0, segments=8, settle=0.3,
              world=world)
    tcps = {a: sim.world_body(desc_arm.tcp, world) for a, desc_arm in ik.desc.arms.items()}

    def rel() -> np.ndarray:
        q = sim.state_0.body_q.numpy()
        return np.array([q[body][:3] - q[t][:3] for t in tcps.values()])

    q1 = sim.state_0.body_q.numpy()[body].copy()   # on the CPU, numpy() is a view of a swapped buffer
    r1, tilts = rel(), []
    for _ in range(int(round(hold / sim.settings.dt)) // 25):
        sim.step(25)
        tilts.append(tilt_deg(sim.state_0.body_q.numpy()[body][3:7]))
    q2 = sim.state_0.body_q.numpy()
    z_tcp = [float(q2[t][2]) for t in tcps.values()]
    return TrayLift(lift=float(q1[2]) - z0, lift_held=float(q2[body][2]) - z0, tilt=tilts[-1], tilt_max=max(tilts),
                    slip=float(np.linalg.norm(rel() - r1, axis=1).max()),
                    gripped=gripper_contacts(sim, ik.desc, body, world), height_error=abs(z_tcp[0] - z_tcp[1]))


def _raised(p: np.ndarray, dz: float) -> np.ndarray:
    out = np.array(p, float)
    out[2, 3] += dz
    return out
