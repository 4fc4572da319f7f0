"""Table tasks of the dexterous hands and the dual-arm platform: one scene per embodiment-task pair,
its scripted expert, success predicate and failure reasons, and a recorder of LeRobot frames.

Pairs (``PAIRS``: "<embodiment>/<task>"):

- ``allegro`` / ``shadow`` (the mobile Panda with the hand, :mod:`stages.simulate.hands`):
  ``pick_place_mug``, ``pick_place_can``: a catalog mug or can on a 0.55 m table; the grasp
  synthesis of :mod:`stages.demos.hand_grasps` (shape fit, top power grasp, closing synergy until
  the contact check passes), lift, carry to a target spot on the table, set down, open, withdraw
  (:func:`pick_place_hand`). Success: the object stands (within 10 deg of upright) on the table
  within ``PLACE_TOL`` of the target and no finger touches it.
  ``open_drawer``, ``close_drawer``: the top drawer of the catalog's ``kitchen_counter_00``: the
  hand hooks the bar handle and pulls, or pushes the drawer shut with the open hand (the scene,
  experts and success predicate in :mod:`stages.demos.table_drawer`).
- ``aloha`` (the dual-arm platform, :mod:`stages.simulate.dual_arm`): ``lift_tray`` and
  ``hand_over``, the experts and success predicates of :mod:`stages.demos.bimanual`.

The rig (:class:`~stages.demos.table_rig.TableRig`): episodes run in a
:class:`stages.simulate.world.Sim` of one world (MuJoCo C on the CPU), built once per pair; each
episode resets it and places the object at random (:meth:`TableRig.reset`). They do
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

from pathlib import Path

import numpy as np

from stages.demos.table_drawer import (DRAWER_BAR_XY, DRAWER_CLOSED, DRAWER_OPEN, close_drawer_hand,
                                       open_drawer_hand, write_counter_scene)
from stages.demos.table_rig import Outcome, TableRig, TaskFailure, _remembering, open_hand

__all__ = ["DRAWER_CLOSED", "DRAWER_OPEN", "HANDS", "PACKAGES", "PAIRS", "Outcome", "TableRig", "TaskFailure",
           "build_rig", "instruction", "judge_place", "pick_place_hand", "run_expert"]

HANDS = ("allegro", "shadow")
HAND_TASKS = ("pick_place_mug", "pick_place_can", "open_drawer", "close_drawer")
ARM_TASKS = ("lift_tray", "hand_over", "open_double_door")
PAIRS = tuple(f"{h}/{t}" for h in HANDS for t in HAND_TASKS) + tuple(f"aloha/{t}" for t in ARM_TASKS)
PACKAGES = {"pick_place_mug": "mug_04", "pick_place_can": "can_00", "open_drawer": "kitchen_counter_00",
            "close_drawer": "kitchen_counter_00", "open_double_door": "wardrobe_01"}
DOORS_XY = (0.70, 0.0)  # [m] the double door's handles' midpoint (nearer, the ViperX's wrist cannot turn to push)
PLACE_TOL = 0.04  # [m] the placed object's axis from the target spot
LIFT_SECONDS = 2.0  # [s] the lift after the grasp
CARRY_SETTLE = 0.2  # [s] the held object comes to rest after the lift and after the carry
CARRY_SECONDS = 2.4  # [s] the carry to the target spot (14-20 cm; 1.6 s let a top-grasped mug turn in the hand)
PRE_GRASP_STANDOFF = 0.16  # [m] above the grasp (at 0.10 the Allegro's open thumb, 11 cm down, hit the mug)
HAND_OBJECT_XY = (0.72, 0.0)  # [m] where the hand tasks' object stands (the robot at the origin, facing +X)
HAND_TABLE_XY = (0.90, 0.0)  # [m] the table (0.6 m deep): its near edge 12 cm before the object's nominal spot


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

        if task == "open_double_door":
            return _double_door_rig(pair, work_dir, assets, shared_assets, seed)
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


def _double_door_rig(pair: str, work_dir: Path, assets: dict | None, shared_assets: Path | None,
                     seed: int) -> TableRig:
    """The dual-arm platform before the catalog's two-door wardrobe (:mod:`stages.demos.double_door`)."""
    from stages.demos.double_door import PACKAGE, write_double_door_scene
    from stages.embodiment.clik import ClikConfig
    from stages.simulate.bimanual_control import BimanualControl, BimanualIk
    from stages.simulate.dual_arm import write_dual_arm_urdf
    from stages.simulate.world import SimConfig, build_sim

    if not assets or PACKAGE not in assets:
        raise ValueError(f"table tasks: {pair} needs the catalog package {PACKAGE} (assets)")
    scene = write_double_door_scene(work_dir / "scene.usda", assets[PACKAGE], handles_xy=DOORS_XY)
    desc = write_dual_arm_urdf(work_dir / "robot", shared_assets=shared_assets)
    sim = build_sim(SimConfig(scenes=(scene.usd,), spawn=(0.0, 0.0, 0.0)), desc, np.random.default_rng(seed))
    ctl = _remembering(BimanualControl)(sim)
    ctl.commands = {a: 0.0 for a in desc.arms}
    # the gripper turning from the handle's grip to pointing down converges slowly: 600 iterations
    ik = BimanualIk(desc, ClikConfig(max_iters=600))
    return TableRig(pair=pair, sim=sim, ctl=ctl, ik=ik, desc=desc, scene=scene, home_xy=DOORS_XY,
                    asset_ids=(PACKAGE,))


# --------------------------------------------------------------------------------------------
# the hands' pick & place
# --------------------------------------------------------------------------------------------


def _held_fingers(rig: TableRig) -> set[str]:
    from stages.demos.hand_grasps import contact_fingers

    return contact_fingers(rig.sim, rig.desc.gripper.hand, rig.body)


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

    # the first plan whose whole path the arm can follow from here (a failed pre-grasp move leaves the
    # arm part-way, near a joint limit: record-table seed 1 episode 4 then missed its carry's waypoint)
    plans = sorted(plans, key=lambda pl: not _path_reachable(rig, _pick_place_chain(pl, shape, target_xy, lift,
                                                                                    place_gap)))
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
    open_hand(rig, 0.5)
    away = down.copy()
    away[2, 3] += 0.12
    move(away, 0.8, 2, 0.3)
    return {"lifted": round(lifted, 4), "carried": round(carried, 4), "contact_command": closing.contact_command}


def _pick_place_chain(plan, shape, target_xy, lift: float, place_gap: float) -> list[tuple[np.ndarray, int]]:
    """The TCP poses (4, 4) of :func:`pick_place_hand` for grasp ``plan``, each with its number of
    IK waypoints: pre-grasp, grasp, lift, carry, set-down."""
    up = plan.grasp.copy()
    up[2, 3] += lift
    shift = np.array([target_xy[0] - shape.center[0], target_xy[1] - shape.center[1], 0.0])
    carry, down = up.copy(), plan.grasp.copy()
    carry[:3, 3] += shift
    down[:3, 3] += shift + [0.0, 0.0, place_gap]
    return [(plan.pre_grasp, 8), (plan.grasp, 2), (up, 4), (carry, 4), (down, 2)]


def _path_reachable(rig: TableRig, chain, *, tol: float = 0.005, rot_tol: float = float(np.deg2rad(2.0))) -> bool:
    """Whether the arm can follow ``chain`` (TCP pose (4, 4), waypoints) from where it is now, the
    way :func:`stages.simulate.control.move_ee` goes (straight lines, slerped orientations, each
    waypoint's CLIK from the one before), solved without stepping the simulation."""
    from scipy.spatial.transform import Rotation, Slerp

    from stages.simulate.control import Clik, pose

    sim, ik = rig.sim, rig.ik
    q = ik.with_arm(ik.from_sim(sim), rig.ctl.arm_targets())
    start = ik.fk(q)
    for target, segments in chain:
        goal = Clik.world_to_root(sim.spawn, target)
        slerp = Slerp([0.0, 1.0], Rotation.from_matrix(np.stack([start[:3, :3], goal[:3, :3]])))
        for k in range(1, segments + 1):
            a = k / segments
            res = ik.solve(pose(start[:3, 3] + a * (goal[:3, 3] - start[:3, 3]), slerp([a]).as_matrix()[0]), q,
                           max_iters=600)
            if res.position_error > tol or res.rotation_error > rot_tol:
                return False
            q = res.q
        start = goal
    return True


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
# one episode
# --------------------------------------------------------------------------------------------


def instruction(rig: TableRig, sample: dict) -> str:
    if rig.task == "lift_tray":
        return "lift the tray with both hands and hold it level"
    if rig.task == "hand_over":
        return "pick up the block with the right gripper and hand it to the left gripper"
    if rig.task in ("open_drawer", "close_drawer"):
        return f"{rig.task.split('_')[0]} the top drawer of the counter"
    if rig.task == "open_double_door":
        return "open both doors of the wardrobe, one with each arm"
    obj = rig.task.removeprefix("pick_place_")
    side = "left" if sample["target"][1] > sample["xy"][1] else "right"
    return f"pick up the {obj} and place it to the {side}"


def run_expert(rig: TableRig, sample: dict) -> Outcome:
    """Run the pair's expert from the state :meth:`TableRig.reset` left and judge the episode."""
    from stages.demos import bimanual as bm
    from stages.demos import double_door as dd

    try:
        if rig.task == "lift_tray":
            fig = bm.lift_tray(rig.sim, rig.ctl, rig.ik, rig.scene)
            return Outcome(success=fig.success(), reason="" if fig.success() else _tray_reason(fig),
                           detail=_rounded(vars(fig)))
        if rig.task == "hand_over":
            fig = bm.hand_over(rig.sim, rig.ctl, rig.ik, rig.scene)
            return Outcome(success=fig.success(), reason="" if fig.success() else _handover_reason(fig),
                           detail=_rounded(vars(fig)))
        if rig.task == "open_double_door":
            fig = dd.open_doors(rig.sim, rig.ctl, rig.ik, rig.scene)
            ok, reason, detail = dd.judge_doors(rig.scene.angles(rig.sim))
            return Outcome(success=ok, reason=reason, detail={**vars(fig), **detail})
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
