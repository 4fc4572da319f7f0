"""Bimanual scripted experts for the dual-arm platform (:mod:`stages.simulate.dual_arm`) and the
table scene they work in.

- :func:`write_table_scene`: floor, a table (static boxes) and an object on it: a serving tray
  (a rigid body of a floor plate and four rims, :class:`TraySpec`) or a block
  (:class:`BlockSpec`), as a USD scene that :func:`stages.simulate.world.build_sim` loads like a
  composed scene.
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

OBJECT_PRIM = "/World/Object"


@dataclass(frozen=True, kw_only=True)
class TraySpec:
    """A serving tray: outer size (x, y) [m], height (floor bottom to rim top) [m], rim and floor
    thickness [m], mass [kg] (a 26 x 36 cm plastic tray: about 0.4 kg)."""

    size: tuple[float, float] = (0.26, 0.36)
    height: float = 0.05
    rim: float = 0.008
    floor: float = 0.006
    mass: float = 0.4
    label: str = "tray"

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
class BlockSpec:
    """A block lying along Y: size (x, y, z) [m], mass [kg] (20 cm of 35 x 40 mm wood: 0.15 kg)."""

    size: tuple[float, float, float] = (0.035, 0.20, 0.04)
    mass: float = 0.15
    label: str = "block"

    @property
    def height(self) -> float:
        return self.size[2]

    def boxes(self) -> dict[str, tuple[tuple[float, float, float], tuple[float, float, float]]]:
        """Part name -> (centre, size) [m] in the block frame (origin: its bottom centre)."""
        return {"Body": ((0.0, 0.0, self.size[2] / 2), self.size)}


@dataclass(frozen=True, kw_only=True)
class TableScene:
    """usd: the scene file; body: the object's rigid-body prim path; obj: its spec
    (:class:`TraySpec` or :class:`BlockSpec`); position: the object origin's start position (3,)
    [m]; table_height [m]."""

    usd: Path
    body: str
    obj: TraySpec | BlockSpec
    position: tuple[float, float, float]
    table_height: float


def write_table_scene(path: Path, obj: TraySpec | BlockSpec, *, obj_xy=(0.46, 0.0), obj_yaw: float = 0.0,
                      table_xy=(0.62, 0.0), table_size=(0.6, 0.9), table_height: float = 0.55) -> TableScene:
    """Author the scene at ``path`` (.usda): floor, a table whose top centre is at ``table_xy``
    [m] with its surface at ``table_height`` [m], and ``obj`` (a rigid body of boxes) standing on
    it at ``obj_xy`` [m], turned ``obj_yaw`` [rad] about +Z."""
    from pxr import Sdf

    from stages.demos.hand_scene import table_world
    from stages.simulate.demo_scene import _box, _labels, _xform_attrs

    path = Path(path)
    w = table_world(table_xy, table_size, table_height)
    pos = (float(obj_xy[0]), float(obj_xy[1]), float(table_height) + 0.0005)
    la, lv = _labels(obj.label)
    w.prim(OBJECT_PRIM, "Xform", apis=["PhysicsRigidBodyAPI", "PhysicsMassAPI", *la],
           attrs={**_xform_attrs(pos, obj_yaw), **lv, "physics:mass": (Sdf.ValueTypeNames.Float, obj.mass)})
    for name, (c, s) in obj.boxes().items():
        _box(w, f"{OBJECT_PRIM}/{name}", c, s, (0.75, 0.72, 0.65))
    w.write(path, "World")
    return TableScene(usd=path, body=OBJECT_PRIM, obj=obj, position=pos, table_height=float(table_height))


# --------------------------------------------------------------------------------------------
# the tray lift
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class TrayLift:
    """What the tray lift measured. lift: rise of the tray [m] after the lift; lift_held: after
    the hold; tilt / tilt_max: angle [deg] of the tray's up axis from the vertical at the end of
    the hold / the largest from the grasp through the lift and the hold; slip: largest change
    [m] of the tray's position relative to either TCP over the hold; gripped: per arm, the
    fingers touching the tray after the hold (0-2); height_error: difference of the two TCP
    heights [m] at the end."""

    lift: float
    lift_held: float
    tilt: float
    tilt_max: float
    slip: float
    gripped: dict[str, int]
    height_error: float

    def success(self, lift: float = 0.10, *, max_tilt: float = 5.0, max_slip: float = 0.005) -> bool:
        """Lifted at least 95% of ``lift`` [m] and still there after the hold, within ``max_tilt``
        [deg] of level throughout, slipped less than ``max_slip`` [m], in all four fingers."""
        return (min(self.lift, self.lift_held) >= 0.95 * lift and self.tilt_max < max_tilt
                and self.slip < max_slip and all(n == 2 for n in self.gripped.values()))


def reset_episode(sim, ctl, scene: TableScene, xy, yaw: float = 0.0) -> None:
    """Start an episode (every world): the robot back at its default posture with the grippers
    open, base commands zero, and the object at ``xy`` [m] on the table, turned ``yaw`` [rad]."""
    from stages.demos.session import set_coords

    sim.reset()
    ctl.reset()
    body = sim.body_of_path(scene.body)
    j = int(np.flatnonzero(sim.model.joint_child.numpy() == body)[0])
    c = int(sim.model.joint_q_start.numpy()[j])
    pose7 = (float(xy[0]), float(xy[1]), scene.position[2], 0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2))
    for w in range(sim.world_count):
        set_coords(sim, {c + w * sim.coords_per_world + i: v for i, v in enumerate(pose7)})


def tilt_deg(quat_xyzw) -> float:
    """Angle [deg] between a body's +Z (from its quaternion x, y, z, w) and the world's +Z."""
    from scipy.spatial.transform import Rotation

    z = Rotation.from_quat(np.asarray(quat_xyzw, float)).apply([0.0, 0.0, 1.0])
    return float(np.degrees(np.arccos(np.clip(z[2], -1.0, 1.0))))


def rim_grasps(scene: TableScene, tray_q, *, depth: float = 0.015) -> dict[str, np.ndarray]:
    """TCP poses (4, 4), world, for the two side rims of the tray at pose ``tray_q`` (7,) (x, y,
    z, quaternion x, y, z, w): over the middle of each rim's centre line, ``depth`` [m] below its
    top, pointing down with the fingers closing across the rim; "left" takes the +Y rim."""
    from scipy.spatial.transform import Rotation

    from stages.simulate.control import pose, top_down

    r = Rotation.from_quat(tray_q[3:7])
    yaw = float(r.as_euler("xyz")[2])
    tr = scene.obj
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


def close_gripper(sim, ctl, arm: str | None, duration: float, *, settle: float = 0.3, world: int = 0,
                  opening: bool = False) -> None:
    """Ramp the gripper command of ``arm`` (None: both) from 0 to 1 (``opening``: 1 to 0) over
    ``duration`` [s], then wait ``settle`` [s] for the grip force to build."""
    steps = max(1, int(round(duration / sim.settings.dt)))
    for i in range(0, steps, 10):
        c = min(1.0, (i + 10) / steps)
        ctl.set_gripper(1.0 - c if opening else c, world, arm)
        sim.step(10)
    sim.step(int(round(settle / sim.settings.dt)))


def lift_tray(sim, ctl, ik, scene: TableScene, *, lift: float = 0.10, hold: float = 2.0, above: float = 0.08,
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
    close_gripper(sim, ctl, None, close_time, world=world)
    tilts: list[float] = []

    def watch(s) -> None:      # the tray's tilt every 25 steps, from the grasp to the end of the hold
        if s.steps % 25 == 0:
            tilts.append(tilt_deg(s.state_0.body_q.numpy()[body][3:7]))

    sim.post_step.append(watch)
    try:
        move_arms(sim, ctl, ik, {a: _raised(p, lift) for a, p in grasps.items()}, 2.0, segments=8, settle=0.3,
                  world=world)
        tcps = {a: sim.world_body(desc_arm.tcp, world) for a, desc_arm in ik.desc.arms.items()}

        def rel() -> np.ndarray:
            q = sim.state_0.body_q.numpy()
            return np.array([q[body][:3] - q[t][:3] for t in tcps.values()])

        q1 = sim.state_0.body_q.numpy()[body].copy()   # on the CPU, numpy() is a view of a swapped buffer
        r1 = rel()
        sim.step(int(round(hold / sim.settings.dt)))
    finally:
        sim.post_step.remove(watch)
    q2 = sim.state_0.body_q.numpy()
    z_tcp = [float(q2[t][2]) for t in tcps.values()]
    tilt = tilt_deg(q2[body][3:7])
    return TrayLift(lift=float(q1[2]) - z0, lift_held=float(q2[body][2]) - z0, tilt=tilt,
                    tilt_max=max([*tilts, tilt]), slip=float(np.linalg.norm(rel() - r1, axis=1).max()),
                    gripped=gripper_contacts(sim, ik.desc, body, world),
                    height_error=abs(z_tcp[0] - z_tcp[1]))


def _raised(p: np.ndarray, dz: float) -> np.ndarray:
    out = np.array(p, float)
    out[2, 3] += dz
    return out


# --------------------------------------------------------------------------------------------
# the hand-over
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class Handover:
    """What the hand-over measured. picked: the block's rise [m] in the giving gripper before the
    hand-over; gripped_after: per arm, the fingers touching the block at the end (the receiver 2,
    the giver 0); height: the block's bottom above the table [m] at the end; slip: change [m] of the
    block's position relative to the receiving TCP over the final hold; tilt: angle [deg] of the
    block's up axis from the vertical at the end."""

    picked: float
    gripped_after: dict[str, int]
    height: float
    slip: float
    tilt: float

    def success(self, receiver: str = "left", *, min_height: float = 0.10, max_tilt: float = 5.0,
                max_slip: float = 0.005) -> bool:
        """The block ends in ``receiver``'s two fingers only, at least ``min_height`` [m] above the
        table, within ``max_tilt`` [deg] of level, having slipped less than ``max_slip`` [m]."""
        return (self.gripped_after.get(receiver) == 2 and sum(self.gripped_after.values()) == 2
                and self.height >= min_height and self.tilt < max_tilt and self.slip < max_slip)


def block_grasp(block_q, along: float, height: float, *, depth: float = 0.012) -> np.ndarray:
    """TCP pose (4, 4), world, over a block of ``height`` [m] at pose ``block_q`` (7,) (x, y, z,
    quaternion x, y, z, w), ``along`` [m] from its centre along its length (its Y), ``depth`` [m]
    below its top, pointing down with the fingers closing across the block (along its X)."""
    from scipy.spatial.transform import Rotation

    from stages.simulate.control import pose, top_down

    r = Rotation.from_quat(block_q[3:7])
    yaw = float(r.as_euler("xyz")[2])
    return pose(r.apply([0.0, along, height - depth]) + block_q[:3], top_down(yaw + np.pi / 2))


def hand_over(sim, ctl, ik, scene: TableScene, *, giver: str = "right", receiver: str = "left",
              rise: float = 0.15, offset: float = 0.06, above: float = 0.08, hold: float = 1.0,
              world: int = 0) -> Handover:
    """The hand-over expert: ``giver`` picks the block (lying along Y) by its own end (``offset``
    [m] from the centre, top-down), lifts it ``rise`` [m]; ``receiver`` comes down on the block's
    other end where the block now is and closes; ``giver`` opens and withdraws ``above`` [m] up
    and away; ``receiver`` carries the block ``offset`` [m] towards its own side and holds it
    ``hold`` [s]."""
    from stages.simulate.bimanual_control import move_arms

    body = sim.body_of_path(scene.body, world)
    table_z = scene.table_height
    side = {"left": 1.0, "right": -1.0}
    q = sim.state_0.body_q.numpy()[body].copy()
    z0 = float(q[2])
    ctl.set_gripper(0.0, world)
    grasp = block_grasp(q, side[giver] * offset, scene.obj.height)
    move_arms(sim, ctl, ik, {giver: _raised(grasp, above)}, 1.5, segments=6, settle=0.2, world=world)
    move_arms(sim, ctl, ik, {giver: grasp}, 1.0, segments=4, settle=0.2, world=world)
    close_gripper(sim, ctl, giver, 0.5, world=world)
    move_arms(sim, ctl, ik, {giver: _raised(grasp, rise)}, 1.5, segments=6, settle=0.3, world=world)
    q = sim.state_0.body_q.numpy()[body].copy()
    picked = float(q[2]) - z0
    take = block_grasp(q, side[receiver] * offset, scene.obj.height)
    move_arms(sim, ctl, ik, {receiver: _raised(take, above)}, 1.5, segments=6, settle=0.2, world=world)
    move_arms(sim, ctl, ik, {receiver: take}, 1.0, segments=4, settle=0.2, world=world)
    close_gripper(sim, ctl, receiver, 0.5, world=world)
    close_gripper(sim, ctl, giver, 0.3, world=world, opening=True)
    back = _raised(grasp, rise + above)
    back[1, 3] += side[giver] * 0.10
    move_arms(sim, ctl, ik, {giver: back}, 1.0, segments=4, world=world)
    away = _raised(take, 0.0)
    away[1, 3] += side[receiver] * offset
    move_arms(sim, ctl, ik, {receiver: away}, 1.0, segments=4, settle=0.2, world=world)
    tcp = sim.world_body(ik.desc.arms[receiver].tcp, world)

    def rel() -> np.ndarray:
        bq = sim.state_0.body_q.numpy()
        return bq[body][:3] - bq[tcp][:3]

    r1 = rel()
    sim.step(int(round(hold / sim.settings.dt)))
    bq = sim.state_0.body_q.numpy()[body]
    return Handover(picked=picked, gripped_after=gripper_contacts(sim, ik.desc, body, world),
                    height=float(bq[2]) - table_z, slip=float(np.linalg.norm(rel() - r1)),
                    tilt=tilt_deg(bq[3:7]))
