"""The basic household tasks as data: family, instruction templates, what the episode starts with,
and a success predicate evaluated on the simulation's typed state.

Every predicate takes the :class:`~stages.demos.sampling.TaskInstance` and a
:class:`~stages.simulate.state.StepState` (world frame, metres, radians) and returns
``(success, reason)``; ``reason`` is a short failure category ("" on success) counted in reports.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

DRAWER_JOINT = "/World/Cabinet/DrawerJoint"
DOOR_JOINT = "/World/Cabinet/DoorJoint"
MUG = "/World/Mug"
BLOCK = "/World/Block"
BUTTON_JOINT = "/World/ButtonJoint"


class Family(StrEnum):
    PICK_PLACE = "pick_place"
    OPEN_CLOSE = "open_close"
    PUSH_PULL = "push_pull"


@dataclass(frozen=True, kw_only=True)
class TaskSpec:
    """name: task id (``[a-z_]+``); family; templates: instruction templates (``str.format`` with
    the instance's ``names``); max_seconds: episode time limit [s]; success: the predicate."""

    name: str
    family: Family
    templates: tuple[str, ...]
    max_seconds: float
    success: Callable


def _drawer_opening(state) -> float:
    """Drawer opening [m] (the joint is at 0 closed and negative when pulled out)."""
    return -float(state.scene_joints[DRAWER_JOINT])


def _door_angle(state) -> float:
    """Door opening [rad] (negative joint rotation opens it)."""
    return -float(state.scene_joints[DOOR_JOINT])


def _released(state, obj: str, min_gap: float = 0.03) -> bool:
    """The gripper is open and away from the object (the object is not held)."""
    ee = np.asarray(state.robot.ee_pose.position)
    gap = np.linalg.norm(ee - np.asarray(state.objects[obj].position))
    return state.robot.gripper_opening > 0.06 and gap > min_gap


def open_drawer_success(inst, state) -> tuple[bool, str]:
    """Open: the drawer is out by at least 75% of its travel."""
    ok = _drawer_opening(state) >= 0.75 * inst.room.drawer_travel
    return (True, "") if ok else (False, "drawer_not_open")


def close_drawer_success(inst, state) -> tuple[bool, str]:
    """Closed: the drawer is within 2 cm of closed."""
    return (True, "") if _drawer_opening(state) <= 0.02 else (False, "drawer_not_closed")


def open_door_success(inst, state) -> tuple[bool, str]:
    """Open: the door is open by at least 75% of its range."""
    return (True, "") if _door_angle(state) >= 0.75 * inst.room.door_range else (False, "door_not_open")


def close_door_success(inst, state) -> tuple[bool, str]:
    """Closed: the door is within 5 deg of closed."""
    return (True, "") if _door_angle(state) <= np.deg2rad(5.0) else (False, "door_not_closed")


def pick_place_bowl_success(inst, state) -> tuple[bool, str]:
    """The mug rests inside the bowl's inner radius, upright (tilt < 30 deg), above the table top,
    and the hand has let go of it."""
    p = np.asarray(state.objects[MUG].position)
    bowl = np.asarray(inst.room.bowl_xy)
    if np.linalg.norm(p[:2] - bowl) > inst.room.bowl_inner_radius:
        return False, "object_not_in_container"
    if p[2] < inst.room.table_height - 0.01:
        return False, "object_fell"
    w, x, y, z = state.objects[MUG].orientation
    up_z = 1 - 2 * (x * x + y * y)
    if up_z < np.cos(np.deg2rad(30.0)):
        return False, "object_tipped"
    if not _released(state, MUG):
        return False, "object_still_held"
    return True, ""


def push_object_success(inst, state) -> tuple[bool, str]:
    """The block moved at least 10 cm along the push direction and is still on the table."""
    p = np.asarray(state.objects[BLOCK].position)
    d = np.asarray(inst.push_direction)
    moved = float(np.dot(p[:2] - np.asarray(inst.block_xy), d))
    if p[2] < inst.room.table_height - 0.01:
        return False, "object_fell"
    return (True, "") if moved >= 0.10 else (False, "object_not_pushed")


def press_button_success(inst, state) -> tuple[bool, str]:
    """The button is pressed in by at least 60% of its travel (it has no spring: it stays in)."""
    pressed = float(state.scene_joints[BUTTON_JOINT])
    return (True, "") if pressed >= 0.6 * inst.room.button_travel else (False, "button_not_pressed")


TASKS: dict[str, TaskSpec] = {t.name: t for t in (
    TaskSpec(name="pick_place_bowl", family=Family.PICK_PLACE, max_seconds=25.0,
             success=pick_place_bowl_success,
             templates=("put the {object} in the {container}", "place the {object} into the {container}",
                        "pick up the {object} and put it in the {container}")),
    TaskSpec(name="open_drawer", family=Family.OPEN_CLOSE, max_seconds=20.0, success=open_drawer_success,
             templates=("open the drawer of the {furniture}", "pull the {furniture} drawer open")),
    TaskSpec(name="close_drawer", family=Family.OPEN_CLOSE, max_seconds=20.0, success=close_drawer_success,
             templates=("close the drawer of the {furniture}", "push the {furniture} drawer shut")),
    TaskSpec(name="open_door", family=Family.OPEN_CLOSE, max_seconds=25.0, success=open_door_success,
             templates=("open the door of the {furniture}", "swing the {furniture} door open")),
    TaskSpec(name="close_door", family=Family.OPEN_CLOSE, max_seconds=25.0, success=close_door_success,
             templates=("close the door of the {furniture}", "swing the {furniture} door shut")),
    TaskSpec(name="push_object", family=Family.PUSH_PULL, max_seconds=20.0, success=push_object_success,
             templates=("push the {object} away across the table", "slide the {object} away from you")),
    TaskSpec(name="press_button", family=Family.PUSH_PULL, max_seconds=20.0, success=press_button_success,
             templates=("press the button on the {panel}", "push the {panel} button")),
)}


def task(name: str) -> TaskSpec:
    """The spec of task ``name``; KeyError lists the known tasks."""
    try:
        return TASKS[name]
    except KeyError:
        raise KeyError(f"unknown task {name!r}; known: {sorted(TASKS)}") from None
