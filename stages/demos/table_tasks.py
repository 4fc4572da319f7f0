"""Table tasks of the dexterous hands and the dual-arm platform: one scene per embodiment-task pair,
its scripted expert, success predicate and failure reasons, and a recorder of LeRobot frames.

Pairs (``PAIRS``: "<embodiment>/<task>"):

- ``allegro`` / ``shadow`` (the mobile Panda with the hand, :mod:`stages.simulate.hands`):
  ``pick_place_mug``, ``pick_place_can``: a catalog mug or can on a 0.55 m table; the grasp
  synthesis of :mod:`stages.demos.hand_grasps` (shape fit, top power grasp, closing synergy until
  the contact check passes), lift, carry to a target spot on the table, set down, open, withdraw
  (:func:`pick_place_hand`). Success: the object stands (within 10 deg of upright) on the table
  within ``PLACE_TOL`` of the target and no finger touches it.
  ``open_drawer``, ``close_drawer``: the top drawer of the catalog's ``kitchen_counter_00``
  standing on the floor before the robot (:func:`write_counter_scene`); the episode starts with the
  hand before the counter, palm towards it (:func:`_ready_posture`); the bar handle is horizontal,
  so the hand comes at it palm first (fingers down, the bar across them), hooks its fingers round
  it (the hook synergy: the Allegro's thumb folded away) and pulls the drawer out, letting go as
  the base backs off (:func:`open_drawer_hand`), or pushes the open drawer shut with the open hand
  (:func:`close_drawer_hand`). Success (:meth:`CounterScene.judge`, once the drawer is at rest):
  the drawer out at least ``DRAWER_OPEN`` / at most ``DRAWER_CLOSED`` and the hand no longer
  holding the handle (the contact check; a drawer that slides on out may still brush the open
  fingers).
- ``aloha`` (the dual-arm platform, :mod:`stages.simulate.dual_arm`): ``lift_tray`` and
  ``hand_over``, the experts and success predicates of :mod:`stages.demos.bimanual`.

Episodes run in a :class:`stages.simulate.world.Sim` of one world (MuJoCo C on the CPU), built once
per pair; each episode resets it and places the object at random (:meth:`TableRig.reset`). They do
not run on the batched engine (:mod:`stages.engine`): its worlds are kitchens with the mobile Panda
(its robot, free objects and watched joints are the kitchen's), see the module
:mod:`stages.demos.table_record`.

Frames (:class:`TableRecorder`, a pre-step callback, ``fps``): the dataset layout of the embodiment
(:class:`stages.dataset.DatasetSpec`): the hands record their joint positions and targets
(``hand_joints``), the dual-arm platform both arms (``arms = ("left", "right")``). The base stands
still (velocity command 0) and the mode is manipulation (1) throughout.

Frames: world, Z up, metres, radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

HANDS = ("allegro", "shadow")
HAND_TASKS = ("pick_place_mug", "pick_place_can", "open_drawer", "close_drawer")
ARM_TASKS = ("lift_tray", "hand_over")
PAIRS = tuple(f"{h}/{t}" for h in HANDS for t in HAND_TASKS) + tuple(f"aloha/{t}" for t in ARM_TASKS)
PACKAGES = {"pick_place_mug": "mug_04", "pick_place_can": "can_00", "open_drawer": "kitchen_counter_00",
            "close_drawer": "kitchen_counter_00"}
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
PLACE_TOL = 0.04  # [m] the placed object's axis from the target spot
LIFT_SECONDS = 2.0  # [s] the lift after the grasp
CARRY_SETTLE = 0.2  # [s] the held object comes to rest after the lift and after the carry
CARRY_SECONDS = 2.4  # [s] the carry to the target spot (14-20 cm; 1.6 s let a top-grasped mug turn in the hand)
PRE_GRASP_STANDOFF = 0.16  # [m] above the grasp (at 0.10 the Allegro's open thumb, 11 cm down, hit the mug)
HAND_OBJECT_XY = (0.72, 0.0)  # [m] where the hand tasks' object stands (the robot at the origin, facing +X)
HAND_TABLE_XY = (0.90, 0.0)  # [m] the table (0.6 m deep): its near edge 12 cm before the object's nominal spot


class TaskFailure(RuntimeError):
    """The expert could not finish: ``reason`` is a short category (grasp_missed, dropped, ...)."""

    def __init__(self, reason: str, detail: str = "") -> None:
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason = reason


@dataclass(frozen=True, kw_only=True)
class Outcome:
    """success; reason ("" on success); detail: what was measured (for the report)."""

    success: bool
    reason: str
    detail: dict = field(default_factory=dict)


# --------------------------------------------------------------------------------------------
# commands that remember what they were told (the action's gripper column)
# --------------------------------------------------------------------------------------------


def _remembering(cls):
    """A subclass of control class ``cls`` that keeps the last gripper command per arm."""

    class Remembering(cls):
        def __init__(self, sim) -> None:
            super().__init__(sim)
            self.commands: dict[str | None, float] = {}

        def set_gripper(self, command: float, world: int | None = None, arm: str | None = None) -> None:
            if arm is None:
                super().set_gripper(command, world)
                for k in list(self.commands) or [None]:
                    self.commands[k] = float(command)
            else:
                super().set_gripper(command, world, arm)
                self.commands[arm] = float(command)

        def reset(self) -> None:
            super().reset()
            self.commands = {k: 0.0 for k in self.commands}

    return Remembering


# --------------------------------------------------------------------------------------------
# the rigs: one simulation per pair
# --------------------------------------------------------------------------------------------


@dataclass(eq=False)
class TableRig:
    """One pair's simulation: ``sim``, its control ``ctl`` and IK ``ik``, the robot description
    ``desc``, the table scene ``scene`` (hand tasks: :class:`stages.demos.hand_scene.TableScene`;
    dual-arm: :class:`stages.demos.bimanual.TableScene`), the object's nominal position ``home_xy``."""

    pair: str
    sim: object
    ctl: object
    ik: object
    desc: object
    scene: object
    home_xy: tuple[float, float]
    asset_ids: tuple[str, ...] = ()

    @property
    def embodiment(self) -> str:
        return self.pair.split("/")[0]

    @property
    def task(self) -> str:
        return self.pair.split("/")[1]

    @property
    def body(self) -> int:
        return self.sim.body_of_path(self.scene.body)

    def reset(self, rng: np.random.Generator) -> dict:
        """Start an episode: robot at its start posture, hand / grippers open, the object at a random
        pose near ``home_xy`` (hands: +-3 cm, any yaw for the can, +-60 deg for the mug; dual-arm:
        the ranges of the bimanual slow test); let it settle 0.1 s. Returns the episode's sample
        (object xy, yaw, and a hand task's target spot)."""
        from stages.demos import bimanual as bm

        x0, y0 = self.home_xy
        if self.task in ("open_drawer", "close_drawer"):
            return self.scene.reset(self, rng)
        if self.embodiment == "aloha":
            xy = (x0 + rng.uniform(-0.04, 0.04), y0 + rng.uniform(-0.03, 0.03))
            yaw = rng.uniform(-0.2, 0.2)
            bm.reset_episode(self.sim, self.ctl, self.scene, xy, yaw)
            sample = {"xy": xy, "yaw": yaw}
        else:
            xy = (x0 + rng.uniform(-0.03, 0.03), y0 + rng.uniform(-0.03, 0.03))
            # the mug's handle (mug_04's at +Y at yaw 0) within 0.8 rad of across the fingers
            yaw = rng.uniform(-math.pi, math.pi) if self.task == "pick_place_can" else \
                float(rng.choice([0.0, math.pi]) + rng.uniform(-0.8, 0.8))
            # place target: across the table's centre line, 14-20 cm to the side
            side = rng.choice([-1.0, 1.0])
            target = (xy[0] + rng.uniform(-0.03, 0.03), xy[1] + side * rng.uniform(0.14, 0.20))
            bm.reset_episode(self.sim, self.ctl, self.scene, xy, yaw)
            sample = {"xy": xy, "yaw": yaw, "target": target}
        self.sim.step(50)
        return {k: np.round(np.asarray(v, float), 4).tolist() for k, v in sample.items()}


def build_rig(pair: str, work_dir: Path, *, assets: dict | None = None, shared_assets: Path | None = None,
              seed: int = 0) -> TableRig:
    """The simulation of ``pair`` (one of ``PAIRS``) in ``work_dir`` (scene and robot files).
    ``assets``: package id -> :class:`stages.demos.packages.CatalogAsset` (the hand tasks' mug and
    can)."""
    from stages.simulate.world import SimConfig, build_sim

    if pair not in PAIRS:
        raise ValueError(f"table tasks: unknown pair {pair!r}; known {PAIRS}")
    emb, task = pair.split("/")
    work_dir = Path(work_dir)
    work_dir.mkdir(parents=True, exist_ok=True)
    if emb == "aloha":
        from stages.demos import bimanual as bm
        from stages.simulate.bimanual_control import BimanualControl, BimanualIk
        from stages.simulate.dual_arm import write_dual_arm_urdf

        obj, x0 = (bm.TraySpec(), 0.46) if task == "lift_tray" else (bm.BlockSpec(), 0.42)
        scene = bm.write_table_scene(work_dir / "scene.usda", obj, obj_xy=(x0, 0.0))
        desc = write_dual_arm_urdf(work_dir / "robot", shared_assets=shared_assets)
        sim = build_sim(SimConfig(scenes=(scene.usd,), spawn=(0.0, 0.0, 0.0)), desc, np.random.default_rng(seed))
        ctl = _remembering(BimanualControl)(sim)
        ctl.commands = {a: 0.0 for a in desc.arms}
        return TableRig(pair=pair, sim=sim, ctl=ctl, ik=BimanualIk(desc), desc=desc, scene=scene,
                        home_xy=(x0, 0.0), asset_ids=(obj.label,))
    from stages.demos.hand_scene import write_table_scene
    from stages.simulate.control import Clik, RobotControl
    from stages.simulate.robot import write_robot_urdf

    pkg = PACKAGES[task]
    if not assets or pkg not in assets:
        raise ValueError(f"table tasks: {pair} needs the catalog package {pkg} (assets)")
    if task in ("open_drawer", "close_drawer"):
        scene = write_counter_scene(work_dir / "scene.usda", assets[pkg], bar_xy=DRAWER_BAR_XY[task])
    else:
        scene = write_table_scene(work_dir / "scene.usda", assets[pkg], table_xy=HAND_TABLE_XY,
                                  object_xy=HAND_OBJECT_XY)
    desc = write_robot_urdf(work_dir / "robot", gripper=emb, shared_assets=shared_assets)
    sim = build_sim(SimConfig(scenes=(scene.usd,), spawn=(0.0, 0.0, 0.0)), desc, np.random.default_rng(seed))
    ctl = _remembering(RobotControl)(sim)
    ctl.commands = {None: 0.0}
    return TableRig(pair=pair, sim=sim, ctl=ctl, ik=Clik(desc), desc=desc, scene=scene, home_xy=HAND_OBJECT_XY,
                    asset_ids=(pkg,))


# --------------------------------------------------------------------------------------------
# the hands' pick & place
# --------------------------------------------------------------------------------------------


def _held_fingers(rig: TableRig) -> set[str]:
    from stages.demos.hand_grasps import contact_fingers

    return contact_fingers(rig.sim, rig.desc.gripper.hand, rig.body)


def _open_hand(rig: TableRig, duration: float, *, hook: bool = False) -> None:
    """Open the hand from its current command to 0 in ``duration`` [s], along the hook synergy
    with ``hook``."""
    sim, ctl = rig.sim, rig.ctl
    steps = max(1, int(round(duration / sim.settings.dt)))
    c0 = ctl.commands.get(None, 1.0)
    for i in range(0, steps, 10):
        c = c0 * (1.0 - min(1.0, (i + 10) / steps))
        _hook(rig, c) if hook else ctl.set_gripper(c)
        sim.step(10)


def pick_place_hand(rig: TableRig, target_xy, *, lift: float = 0.10, place_gap: float = 0.004) -> dict:
    """The hand's pick & place expert: top power grasp of the object (grasp synthesis), lift
    ``lift`` [m], carry it to ``target_xy`` (2,) [m], set it down ``place_gap`` [m] above where it
    was grasped (these three min-jerk, :func:`~stages.demos.hand_grasps.move_ee_smooth`), open,
    withdraw up. Raises :class:`TaskFailure` (grasp_missed, dropped,
    ik_unreachable); returns what it measured."""
    from stages.demos import hand_grasps as hg
    from stages.simulate.control import move_ee

    sim, ctl, ik, hand = rig.sim, rig.ctl, rig.ik, rig.desc.gripper.hand
    body = rig.body
    shape = hg.fit_upright(hg.object_points(sim, body))
    if not shape.upright:
        raise TaskFailure("tipped", "the object does not stand upright before the grasp")
    plans = hg.top_grasp_plans(shape, hand, sim.spawn[:2], standoff=PRE_GRASP_STANDOFF)

    def move(p, duration, segments, settle=0.0, smooth=False):
        try:
            if smooth:   # the object in the hand: min-jerk progress, no jolt at the starts and stops
                hg.move_ee_smooth(sim, ctl, ik, p, duration, settle=settle)
            else:
                move_ee(sim, ctl, ik, p, duration, segments=segments, settle=settle)
        except RuntimeError as e:
            raise TaskFailure("ik_unreachable", str(e)) from None

    for k, plan in enumerate(plans):   # 8 waypoints: with 3 the wrist's turn dipped the hand 13 cm
        try:
            move(plan.pre_grasp, 1.5, 8, 0.1)
            break
        except TaskFailure:
            if k == len(plans) - 1:
                raise
    move(plan.grasp, 0.8, 2, 0.1)
    z0 = float(sim.state_0.body_q.numpy()[body][2])
    closing = hg.close_until_contact(sim, ctl, hand, body, settle=0.5)
    ctl.commands[None] = closing.command
    if closing.contact_command is None:
        raise TaskFailure("grasp_missed", f"contact check never passed (touching {sorted(closing.touching)})")
    up = plan.grasp.copy()
    up[2, 3] += lift
    move(up, LIFT_SECONDS, 4, CARRY_SETTLE, smooth=True)
    lifted = float(sim.state_0.body_q.numpy()[body][2]) - z0
    if lifted < 0.5 * lift:
        raise TaskFailure("dropped", f"lifted {lifted:.3f} m of {lift:.2f}")
    shift = np.array([target_xy[0] - shape.center[0], target_xy[1] - shape.center[1], 0.0])
    carry = up.copy()
    carry[:3, 3] += shift
    move(carry, CARRY_SECONDS, 4, CARRY_SETTLE, smooth=True)
    carried = float(sim.state_0.body_q.numpy()[body][2]) - z0
    if carried < 0.5 * lift:
        raise TaskFailure("dropped", f"in the carry (at {carried:.3f} m of {lift:.2f})")
    down = plan.grasp.copy()
    down[:3, 3] += shift + [0.0, 0.0, place_gap]
    move(down, 0.8, 2, 0.1, smooth=True)
    _open_hand(rig, 0.5)
    away = down.copy()
    away[2, 3] += 0.12
    move(away, 0.8, 2, 0.3)
    return {"lifted": round(lifted, 4), "carried": round(carried, 4), "contact_command": closing.contact_command}


def judge_place(rig: TableRig, target_xy, *, max_tilt: float = 10.0) -> Outcome:
    """Success of a hand pick & place: the object stands within ``max_tilt`` [deg] of upright on the
    table, its axis within ``PLACE_TOL`` of ``target_xy``, no finger touching it."""
    from stages.demos import hand_grasps as hg
    from stages.demos.bimanual import tilt_deg

    sim, body = rig.sim, rig.body
    q = sim.state_0.body_q.numpy()[body]
    tilt = tilt_deg(q[3:7])
    shape = hg.fit_upright(hg.object_points(sim, body))
    err = float(np.linalg.norm(shape.center[:2] - np.asarray(target_xy, float)))
    on_table = abs(shape.bottom - rig.scene.table_height) < 0.01
    touching = sorted(_held_fingers(rig))
    detail = {"place_error": round(err, 4), "tilt": round(tilt, 2), "bottom": round(shape.bottom, 4),
              "touching": touching}
    reason = ("tipped" if tilt > max_tilt else "not_on_table" if not on_table else
              "missed_target" if err > PLACE_TOL else "still_held" if touching else "")
    return Outcome(success=not reason, reason=reason, detail=detail)


# --------------------------------------------------------------------------------------------
# the hands' drawer
# --------------------------------------------------------------------------------------------


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
    fingers down (:func:`_palm_on_bar`), the hand open along its hook synergy (:func:`_hook`).
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
    fingers = _hook(rig, 0.0)
    return {sim.world_coord(n): float(v) for n, v in zip((*rig.desc.arm_joints, *rig.desc.gripper.finger_joints),
                                                        (*arm, *fingers), strict=True)}


def _hook(rig: TableRig, command: float) -> np.ndarray:
    """Command the hand to ``command`` in [0, 1] along its hook synergy (a bar handle gripped by
    the fingers, :meth:`stages.simulate.hands.HandInfo.synergy`); the action's gripper column
    records ``command``. Returns the finger targets (n,) [rad]."""
    q = rig.desc.gripper.hand.synergy(command, hook=True)
    rig.ctl.set_finger_targets(q)
    rig.ctl.commands[None] = float(command)
    return q


def _move(rig: TableRig, p: np.ndarray, duration: float, segments: int, settle: float = 0.0) -> None:
    from stages.simulate.control import move_ee

    try:
        move_ee(rig.sim, rig.ctl, rig.ik, p, duration, segments=segments, settle=settle)
    except RuntimeError as e:
        raise TaskFailure("ik_unreachable", str(e)) from None


def open_drawer_hand(rig: TableRig, *, along: float = DRAWER_ALONG, gap: float = 0.006, pull: float = 0.20) -> dict:
    """Palm first onto the bar handle (the bar ``along`` [m] down the fingers from the TCP, ``gap``
    [m] in front of the palm), close the fingers round it (the hook synergy, :func:`_hook`), pull
    the drawer out ``pull`` [m], then drive the base back and open the hand on the way
    (:func:`_back_off`)."""
    from stages.simulate.control import pose

    sc, rot = rig.scene, _palm_on_bar()
    bar = sc.bar + sc.slide * sc.opening(rig.sim)
    tcp = bar - along * rot[:, 0] - (sc.radius + gap) * rot[:, 2]
    _move(rig, pose(tcp - 0.10 * rot[:, 2], rot), 1.5, 3, 0.1)
    _move(rig, pose(tcp, rot), 0.8, 2, 0.1)
    for c in np.linspace(0.1, 1.0, 10):
        _hook(rig, float(c))
        rig.sim.step(25)
    rig.sim.step(100)
    _move(rig, pose(tcp + pull * sc.slide, rot), 2.0, 4, 0.2)
    pulled = sc.opening(rig.sim)
    _back_off(rig, open_hand=0.4)   # the arm held: a palm any nearer the base is out of reach with the base turned
    return {"pulled": round(pulled, 4)}


def _back_off(rig: TableRig, speed: float = 0.3, duration: float = 0.6, *, open_hand: float = 0.0) -> None:
    """Drive the base straight back ``speed`` [m/s], the arm held, opening the hand along its hook
    synergy in the first ``open_hand`` [s], for ``open_hand + duration`` [s]; then stop and wait
    0.3 s (the hand leaves a drawer that slides on out after it). Opening the hooked fingers in
    place swept their tips into the drawer's front and pushed the free-running drawer shut (3 of
    10 Allegro episodes, record-table seed 0; opened 18.7 cm, shut within 3 s); the hand going back
    at 0.3 m/s as they open drags the drawer 2-4 cm further out instead."""
    rig.ctl.set_base_velocity(-speed, 0.0, 0.0)
    if open_hand > 0.0:
        _open_hand(rig, open_hand, hook=True)
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
    _hook(rig, 0.0)
    _move(rig, pose(tcp - 0.10 * rot[:, 2], rot), 1.5, 3, 0.1)
    _move(rig, pose(tcp, rot), 0.6, 2)
    shut = sc.bar - along * rot[:, 0] - (sc.radius + gap) * rot[:, 2] - past * sc.slide
    _move(rig, pose(shut, rot), 2.0, 4, 0.2)
    pushed = sc.opening(rig.sim)
    _move(rig, pose(shut - 0.12 * rot[:, 2], rot), 0.8, 2, 0.3)
    return {"pushed_to": round(pushed, 4)}


# --------------------------------------------------------------------------------------------
# one episode
# --------------------------------------------------------------------------------------------


def instruction(rig: TableRig, sample: dict) -> str:
    if rig.task == "lift_tray":
        return "lift the tray with both hands and hold it level"
    if rig.task == "hand_over":
        return "pick up the block with the right gripper and hand it to the left gripper"
    if rig.task in ("open_drawer", "close_drawer"):
        return f"{rig.task.split('_')[0]} the top drawer of the counter"
    obj = rig.task.removeprefix("pick_place_")
    side = "left" if sample["target"][1] > sample["xy"][1] else "right"
    return f"pick up the {obj} and place it to the {side}"


def run_expert(rig: TableRig, sample: dict) -> Outcome:
    """Run the pair's expert from the state :meth:`TableRig.reset` left and judge the episode."""
    from stages.demos import bimanual as bm

    try:
        if rig.task == "lift_tray":
            fig = bm.lift_tray(rig.sim, rig.ctl, rig.ik, rig.scene)
            return Outcome(success=fig.success(), reason="" if fig.success() else _tray_reason(fig),
                           detail=_rounded(vars(fig)))
        if rig.task == "hand_over":
            fig = bm.hand_over(rig.sim, rig.ctl, rig.ik, rig.scene)
            return Outcome(success=fig.success(), reason="" if fig.success() else _handover_reason(fig),
                           detail=_rounded(vars(fig)))
        if rig.task == "open_drawer":
            fig = open_drawer_hand(rig)
            return rig.scene.judge(rig, opened=True, detail=fig)
        if rig.task == "close_drawer":
            fig = close_drawer_hand(rig)
            return rig.scene.judge(rig, opened=False, detail=fig)
        fig = pick_place_hand(rig, sample["target"])
        out = judge_place(rig, sample["target"])
        return Outcome(success=out.success, reason=out.reason, detail={**fig, **out.detail})
    except TaskFailure as e:
        return Outcome(success=False, reason=e.reason, detail={"error": str(e)})
    except RuntimeError as e:   # the bimanual experts' CLIK: "waypoint ... unreachable"
        if "unreachable" in str(e):
            return Outcome(success=False, reason="ik_unreachable", detail={"error": str(e)})
        raise


def _tray_reason(fig) -> str:
    if min(fig.lift, fig.lift_held) < 0.095:
        return "not_lifted" if fig.lift < 0.095 else "dropped"
    if fig.tilt_max >= 5.0:
        return "tilted"
    if fig.slip >= 0.005:
        return "slipped"
    return "lost_grip"


def _handover_reason(fig) -> str:
    if fig.picked < 0.10:
        return "pick_failed"
    if fig.gripped_after.get("left") != 2:
        return "not_received"
    if fig.gripped_after.get("right", 0):
        return "not_released"
    if fig.height < 0.10:
        return "dropped"
    return "tilted" if fig.tilt >= 5.0 else "slipped"


def _rounded(d: dict) -> dict:
    return {k: round(float(v), 4) if isinstance(v, float | np.floating) else v for k, v in d.items()}
