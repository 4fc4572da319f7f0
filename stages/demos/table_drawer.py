"""The hands' drawer tasks (``open_drawer``, ``close_drawer`` of :mod:`stages.demos.table_tasks`):
the top drawer of the catalog's ``kitchen_counter_00`` standing on the floor before the robot
(:func:`write_counter_scene`); the episode starts with the hand before the counter, palm towards it
(:func:`_ready_posture`); the bar handle is horizontal, so the hand comes at it palm first (fingers
down, the bar across them), hooks its fingers round it (the hook synergy: the Allegro's thumb folded
away) and pulls the drawer out, letting go as the base backs off (:func:`open_drawer_hand`), or
pushes the open drawer shut with the open hand (:func:`close_drawer_hand`). Success
(:meth:`CounterScene.judge`, once the drawer is at rest): the drawer out at least ``DRAWER_OPEN`` /
at most ``DRAWER_CLOSED`` and the hand no longer holding the handle.

Frames: world, Z up, metres, radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stages.demos.table_rig import Outcome, TableRig, TaskFailure, hook, open_hand

DRAWER = "drawer_4_2"  # kitchen_counter_00's top drawer (its bar handle 0.72 m high, along the counter's width)
# [m] where the closed drawer's bar handle is (the robot at the origin, facing +X), per task: the hand
# pulls the bar back to 0.42 m or pushes it from 0.56-0.62 m (a horizontal palm nearer the base is
# out of the Panda's reach at this height)
DRAWER_BAR_XY = {"open_drawer": (0.62, 0.0), "close_drawer": (0.74, 0.0)}
DRAWER_ALONG = 0.05  # [m] the bar this far down the fingers from the TCP when the palm is on it
DRAWER_READY_X = 0.42  # [m] the drawer tasks' start: the TCP this far before the base (see _ready_posture)
DRAWER_OPEN = 0.12  # [m] an open drawer is out at least this far
DRAWER_CLOSED = 0.02  # [m] a closed drawer at most this far
DRAWER_REST_SPEED = 0.005  # [m/s] a drawer slower than this is at rest (judged only then)


@dataclass(frozen=True, kw_only=True)
class CounterScene:
    """The drawer tasks' scene: usd; joint: the drawer joint's prim path; bar: the closed drawer's
    bar handle centre (3,) [m]; slide: the drawer's opening direction (3,); travel: its joint's upper
    limit [m]; radius: the bar's radius [m]; links: the drawer's body prim path."""

    usd: Path
    joint: str
    bar: np.ndarray
    slide: np.ndarray
    radius: float
    body: str

    def coord(self, sim) -> int:
        j = next(j for j, p in sim.scene.joint_path.items() if p == self.joint)
        return int(sim.model.joint_q_start.numpy()[j])

    def travel(self, sim) -> float:
        j = next(j for j, p in sim.scene.joint_path.items() if p == self.joint)
        return float(sim.model.joint_limit_upper.numpy()[int(sim.model.joint_qd_start.numpy()[j])])

    def opening(self, sim) -> float:
        """How far the drawer is out [m]."""
        return float(sim.state_0.joint_q.numpy()[self.coord(sim)])

    def speed(self, sim) -> float:
        """The drawer's speed along its slide [m/s]."""
        j = next(j for j, p in sim.scene.joint_path.items() if p == self.joint)
        return abs(float(sim.state_0.joint_qd.numpy()[int(sim.model.joint_qd_start.numpy()[j])]))

    def come_to_rest(self, sim, *, speed: float = DRAWER_REST_SPEED, max_seconds: float = 2.0) -> float:
        """Step ``sim`` until the drawer moves slower than ``speed`` [m/s], at most ``max_seconds``
        [s]; returns the seconds waited."""
        t0, every = sim.time, 25
        while self.speed(sim) >= speed and sim.time - t0 < max_seconds:
            sim.step(every)
        return sim.time - t0

    def reset(self, rig: TableRig, rng: np.random.Generator) -> dict:
        """An episode's start: the base +-3 cm and +-0.08 rad off its spawn pose, the drawer shut
        (open_drawer) or out 12-18 cm (close_drawer), the arm and hand in their drawer-ready
        posture (:func:`_ready_posture`)."""
        from stages.demos.session import set_coords

        base = (rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03), rng.uniform(-0.08, 0.08))
        out = 0.0 if rig.task == "open_drawer" else float(rng.uniform(0.12, 0.18))
        rig.sim.reset(base=base)
        rig.ctl.reset()
        set_coords(rig.sim, {self.coord(rig.sim): out, **_ready_posture(rig, base)})
        rig.sim.step(50)
        return {"base": np.round(base, 4).tolist(), "drawer": round(out, 4)}

    def judge(self, rig: TableRig, *, opened: bool, detail: dict) -> Outcome:
        """Success of a drawer episode, judged once the drawer has come to rest (at most 2 s more:
        a drawer let go while moving slides on, and one pushed by the opening fingers slid shut
        over 3 s): out at least ``DRAWER_OPEN`` (``opened``) or at most ``DRAWER_CLOSED``, at rest,
        and not held (the thumb and two fingers, or with the hook synergy three fingers, touching
        it). Reasons: not_opened, not_closed, drawer_moving, still_held."""
        from stages.demos.hand_grasps import contact_fingers, is_held

        waited = self.come_to_rest(rig.sim)
        q, v = self.opening(rig.sim), self.speed(rig.sim)
        touching = contact_fingers(rig.sim, rig.desc.gripper.hand, rig.sim.body_of_path(self.body))
        held = is_held(touching) or len(touching - {"thumb", "palm"}) >= 3
        reason = ("not_opened" if opened and q < DRAWER_OPEN else "not_closed" if not opened and q > DRAWER_CLOSED
                  else "drawer_moving" if v >= DRAWER_REST_SPEED else "still_held" if held else "")
        touching = sorted(touching)
        return Outcome(success=not reason, reason=reason,
                       detail={**detail, "drawer": round(q, 4), "drawer_speed": round(v, 4),
                               "rest_wait": round(waited, 2), "touching": touching})


def write_counter_scene(path: Path, asset, *, bar_xy=(0.62, 0.0), drawer: str = DRAWER) -> CounterScene:
    """Author the drawer tasks' scene at ``path``: floor and ``asset`` (a counter package) on it,
    turned to face the robot (its front towards -X), placed so that ``drawer``'s bar handle is at
    ``bar_xy`` [m] when the drawer is shut."""
    from stages.demos.hand_scene import OBJECT_PRIM, table_world, write_object_world

    handle = next((h for h in asset.info.get("handles", ()) if h["link"] == drawer), None)
    if handle is None or tuple(handle["bar_axis"]) != (0.0, 1.0, 0.0):
        raise ValueError(f"{asset.usd}: no horizontal bar handle on link {drawer!r}")
    c = np.asarray(handle["center"], float)
    yaw = math.pi   # the asset's front (+X) faces the robot
    pos = (bar_xy[0] + c[0], bar_xy[1] + c[1], 0.0)
    path = Path(path)
    w = table_world(table_xy=(-3.0, -3.0), table_size=(0.1, 0.1), table_height=0.05)   # no table in reach
    write_object_world(path, w, asset, pos, yaw)
    return CounterScene(usd=path, joint=f"{OBJECT_PRIM}/joints/{drawer}_joint",
                        bar=np.array([bar_xy[0], bar_xy[1], c[2]]), slide=np.array([-1.0, 0.0, 0.0]),
                        radius=float(handle["grip_width"]) / 2, body=f"{OBJECT_PRIM}/{drawer}")


def _palm_on_bar() -> np.ndarray:
    """TCP rotation (3, 3) with the palm facing +X (the counter), the fingers pointing down and a bar
    along world Y lying across them (along the TCP's Y)."""
    return np.stack([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]], axis=1)


def _ready_posture(rig: TableRig, base) -> dict[int, float]:
    """The drawer tasks' start posture for the base at ``base`` (x, y, yaw) [m, rad]: the TCP
    ``DRAWER_READY_X`` before the base at the grasp's height, the palm towards the counter,
    fingers down (:func:`_palm_on_bar`), the hand open along its hook synergy (:func:`~stages.demos.table_rig.hook`).
    Sets the arm's and fingers' targets; returns their joints' coordinates (model index -> rad)
    for :func:`stages.demos.session.set_coords`. (The arm's home posture holds a hand's 18 cm
    fingers level at 0.78 m reaching 0.70 m out: into the drawer's front, where they hooked the
    bar and dragged the drawer before the expert started.)"""
    from stages.simulate.control import Clik, pose

    sim, ik, sc = rig.sim, rig.ik, rig.scene
    x, y, yaw = base
    p = np.array([x + DRAWER_READY_X * math.cos(yaw), y + DRAWER_READY_X * math.sin(yaw), sc.bar[2] + DRAWER_ALONG])
    res = ik.solve(Clik.world_to_root(sim.spawn, pose(p, _palm_on_bar())), ik.from_sim(sim), max_iters=600,
                   restarts=10, rng=np.random.default_rng(0))
    if not res.success:
        raise RuntimeError(f"table tasks: the drawer-ready pose at {np.round(p, 3)} is out of reach "
                           f"(error {res.position_error:.4f} m)")
    arm = ik.arm_q(res.q)
    rig.ctl.set_arm_targets(arm)
    fingers = hook(rig, 0.0)
    return {sim.world_coord(n): float(v) for n, v in zip((*rig.desc.arm_joints, *rig.desc.gripper.finger_joints),
                                                        (*arm, *fingers), strict=True)}


def _move(rig: TableRig, p: np.ndarray, duration: float, segments: int, settle: float = 0.0) -> None:
    from stages.simulate.control import move_ee

    try:
        move_ee(rig.sim, rig.ctl, rig.ik, p, duration, segments=segments, settle=settle)
    except RuntimeError as e:
        raise TaskFailure("ik_unreachable", str(e)) from None


def open_drawer_hand(rig: TableRig, *, along: float = DRAWER_ALONG, gap: float = 0.006, pull: float = 0.20) -> dict:
    """Palm first onto the bar handle (the bar ``along`` [m] down the fingers from the TCP, ``gap``
    [m] in front of the palm), close the fingers round it (the hook synergy, :func:`~stages.demos.table_rig.hook`), pull
    the drawer out ``pull`` [m], then drive the base back and open the hand on the way
    (:func:`_back_off`)."""
    from stages.simulate.control import pose

    sc, rot = rig.scene, _palm_on_bar()
    bar = sc.bar + sc.slide * sc.opening(rig.sim)
    tcp = bar - along * rot[:, 0] - (sc.radius + gap) * rot[:, 2]
    _move(rig, pose(tcp - 0.10 * rot[:, 2], rot), 1.5, 3, 0.1)
    _move(rig, pose(tcp, rot), 0.8, 2, 0.1)
    for c in np.linspace(0.1, 1.0, 10):
        hook(rig, float(c))
        rig.sim.step(25)
    rig.sim.step(100)
    _move(rig, pose(tcp + pull * sc.slide, rot), 2.0, 4, 0.2)
    pulled = sc.opening(rig.sim)
    _back_off(rig, open_for=0.4)   # the arm held: a palm any nearer the base is out of reach with the base turned
    return {"pulled": round(pulled, 4)}


def _back_off(rig: TableRig, speed: float = 0.3, duration: float = 0.6, *, open_for: float = 0.0) -> None:
    """Drive the base straight back ``speed`` [m/s], the arm held, opening the hand along its hook
    synergy in the first ``open_for`` [s], for ``open_for + duration`` [s]; then stop and wait
    0.3 s (the hand leaves a drawer that slides on out after it). Opening the hooked fingers in
    place swept their tips into the drawer's front and pushed the free-running drawer shut (3 of
    10 Allegro episodes, record-table seed 0; opened 18.7 cm, shut within 3 s); the hand going back
    at 0.3 m/s as they open drags the drawer 2-4 cm further out instead."""
    rig.ctl.set_base_velocity(-speed, 0.0, 0.0)
    if open_for > 0.0:
        open_hand(rig, open_for, hooked=True)
    rig.sim.step(int(round(duration / rig.sim.settings.dt)))
    rig.ctl.set_base_velocity(0.0, 0.0, 0.0)
    rig.sim.step(int(round(0.3 / rig.sim.settings.dt)))


def close_drawer_hand(rig: TableRig, *, along: float = DRAWER_ALONG, gap: float = 0.004, past: float = 0.01) -> dict:
    """The open palm onto the open drawer's bar handle (the bar ``along`` [m] down the fingers from the
    TCP, as for opening), push the drawer ``past`` [m] beyond shut (its stop holds it), back away."""
    from stages.simulate.control import pose

    sc, rot = rig.scene, _palm_on_bar()
    bar = sc.bar + sc.slide * sc.opening(rig.sim)
    tcp = bar - along * rot[:, 0] - (sc.radius + gap) * rot[:, 2]
    hook(rig, 0.0)
    _move(rig, pose(tcp - 0.10 * rot[:, 2], rot), 1.5, 3, 0.1)
    _move(rig, pose(tcp, rot), 0.6, 2)
    shut = sc.bar - along * rot[:, 0] - (sc.radius + gap) * rot[:, 2] - past * sc.slide
    _move(rig, pose(shut, rot), 2.0, 4, 0.2)
    pushed = sc.opening(rig.sim)
    _move(rig, pose(shut - 0.12 * rot[:, 2], rot), 0.8, 2, 0.3)
    return {"pushed_to": round(pushed, 4)}
