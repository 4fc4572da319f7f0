"""The basic household tasks as data: family, instruction templates, time limit and a success
predicate evaluated on the simulation's typed state.

Every predicate takes the :class:`~stages.demos.sampling.TaskInstance`, a
:class:`~stages.simulate.state.StepState` (world frame, metres, radians) at the episode's end and
``peaks`` (watched scene joint path -> largest value during the episode) and returns
``(success, reason)``; ``reason`` is a short failure category ("" on success) counted in reports.
The world's facts (support heights, cavity, button) come from the instance's
:class:`~stages.demos.kitchen.KitchenWorld`; prim paths from its placed packages.

The open/close tasks of articulated parts (microwave, fridge and oven doors, a counter drawer, the
room door) use the parts and predicates of :mod:`stages.demos.parts` (the instance's
``part``).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from stages.demos.parts import part_closed, part_opened
from stages.demos.predicates import _inside, _placed_check, _released, _upright  # noqa: F401 (re-exported)
from stages.demos.skill_bed import place_pillow_success
from stages.demos.skill_books import shelve_book_1_success, shelve_book_2_success
from stages.demos.skill_fridge import pick_place_fridge_success
from stages.demos.skill_pour import pick_pitcher_success, place_pitcher_success, pour_success
from stages.demos.skill_press import press_clock_button_success, slide_clock_switch_success
from stages.demos.skill_trash import throw_away_success
from stages.demos.skill_wardrobe import hang_on_rail_success
from stages.demos.skill_rack import place_in_rack_success
from stages.demos.skill_wipe import wipe_plate_success

log = logging.getLogger(__name__)


class Family(StrEnum):
    PICK_PLACE = "pick_place"
    OPEN_CLOSE = "open_close"
    PUSH_PULL = "push_pull"
    MULTISTAGE = "multistage"  # a sequence of the basic tasks' skills (stages.demos.multistage)


@dataclass(frozen=True, kw_only=True)
class TaskSpec:
    """name: task id (``[a-z_]+``); family; templates: instruction templates (``str.format`` with
    the instance's ``names``); max_seconds: episode time limit [s]; success: the predicate."""

    name: str
    family: Family
    templates: tuple[str, ...]
    max_seconds: float
    success: Callable


def pick_place_bowl_success(inst, state, peaks=None) -> tuple[bool, str]:
    """The mug rests in the bowl (its centre within the bowl's rim radius less 2 cm of the bowl's
    centre), upright, above the table top, released."""
    w = inst.world
    mug, bowl = w.placed["mug"].body(), w.placed["bowl"].body()
    p, b = np.asarray(state.objects[mug].position), np.asarray(state.objects[bowl].position)
    if np.linalg.norm(p[:2] - b[:2]) > w.bowl_radius - 0.02:
        return False, "object_not_in_container"
    reason = _placed_check(inst, state, mug, w.table_z - 0.01)
    return (not reason), reason


def pick_place_microwave_success(inst, state, peaks=None) -> tuple[bool, str]:
    """The mug stands inside the microwave's cavity (its centre over the cavity floor, 2 cm in from
    the edges), upright, released."""
    w = inst.world
    mug = w.placed["mug"].body()
    p = np.asarray(state.objects[mug].position)
    if not _inside(p[:2], w.cavity, 0.02) or p[2] < w.cavity_z - 0.02:
        return False, "object_not_in_container"
    reason = _placed_check(inst, state, mug, w.cavity_z - 0.02)
    return (not reason), reason


def pick_from_microwave_success(inst, state, peaks=None) -> tuple[bool, str]:
    """The mug stands on the counter top outside the microwave (centre within the counter's top,
    not over the cavity), upright, released."""
    w = inst.world
    mug = w.placed["mug"].body()
    p = np.asarray(state.objects[mug].position)
    if _inside(p[:2], w.cavity, -0.02):
        return False, "object_still_in_container"
    if not _inside(p[:2], w.counter_rect, 0.0) or abs(p[2] - w.counter_z) > 0.03:
        return False, "object_not_on_counter"
    reason = _placed_check(inst, state, mug, w.counter_z - 0.02)
    return (not reason), reason


def push_object_success(inst, state, peaks=None) -> tuple[bool, str]:
    """The object moved at least 10 cm along the push direction and is still on the table top."""
    w = inst.world
    body = w.placed["pusher"].body()
    p = np.asarray(state.objects[body].position)
    x0, y0 = inst.objects[body][:2]
    moved = float(np.dot(p[:2] - (x0, y0), np.asarray(inst.push_direction)))
    if p[2] < w.table_z - 0.01 or not _inside(p[:2], w.table_rect):
        return False, "object_fell"
    return (True, "") if moved >= 0.10 else (False, "object_not_pushed")


def press_button_success(inst, state, peaks=None) -> tuple[bool, str]:
    """The microwave's button went in by at least 60% of its travel during the episode (a momentary
    button: ``peaks`` holds its deepest position; without it, the final one)."""
    w = inst.world
    path = w.placed["microwave"].joint("button_joint")
    pressed = float((peaks or {}).get(path, state.scene_joints[path]))
    return (True, "") if pressed >= 0.6 * w.button_travel else (False, "button_not_pressed")


_PICK = ("put the {object} in the {container}", "place the {object} into the {container}",
         "pick up the {object} and put it in the {container}")

TASKS: dict[str, TaskSpec] = {t.name: t for t in (
    TaskSpec(name="pick_place_bowl", family=Family.PICK_PLACE, max_seconds=30.0,
             success=pick_place_bowl_success, templates=_PICK),
    TaskSpec(name="pick_place_microwave", family=Family.PICK_PLACE, max_seconds=30.0,
             success=pick_place_microwave_success, templates=_PICK),
    TaskSpec(name="pick_from_microwave", family=Family.PICK_PLACE, max_seconds=30.0,
             success=pick_from_microwave_success,
             templates=("take the {object} out of the {container}",
                        "move the {object} from the {container} to the counter",
                        "pick the {object} out of the {container} and put it on the counter")),
    TaskSpec(name="pick_place_fridge", family=Family.PICK_PLACE, max_seconds=60.0,
             success=pick_place_fridge_success,
             templates=("put the {object} in the fridge", "store the {object} in the fridge",
                        "take the {object} from the counter and put it on a fridge shelf")),
    TaskSpec(name="wipe_plate", family=Family.PUSH_PULL, max_seconds=60.0, success=wipe_plate_success,
             templates=("wipe the {object} with the {tool}", "clean the {object} with the {tool}",
                        "scrub the {object} clean with the {tool}")),
    TaskSpec(name="place_in_rack", family=Family.PICK_PLACE, max_seconds=60.0, success=place_in_rack_success,
             templates=("put the {object} in the {container}", "set the {object} on the {container} to dry",
                        "place the {object} on the {container}")),
    TaskSpec(name="throw_away", family=Family.PICK_PLACE, max_seconds=40.0, success=throw_away_success,
             templates=("throw the {object} in the {container}", "put the {object} into the {container}",
                        "clear the {object} off the table into the {container}")),
    # the pour skills (stages.demos.skill_pour): the stages of serve_drinks, each from the last one's state
    TaskSpec(name="pick_pitcher", family=Family.PICK_PLACE, max_seconds=40.0, success=pick_pitcher_success,
             templates=("pick up the {object}", "lift the {object} by its handle")),
    TaskSpec(name="pour_drink", family=Family.PICK_PLACE, max_seconds=40.0, success=pour_success,
             templates=("pour the drink from the {object} into the {container}", "fill the {container}")),
    TaskSpec(name="place_pitcher", family=Family.PICK_PLACE, max_seconds=30.0, success=place_pitcher_success,
             templates=("put the {object} back on the table", "set the {object} down")),
    # make the bed (stages.demos.skill_bed): the cushion on the blanket laid at the bed's head
    TaskSpec(name="place_pillow", family=Family.PICK_PLACE, max_seconds=40.0, success=place_pillow_success,
             templates=("put the {object} at the head of the {container}", "place the {object} by the pillows",
                        "move the {object} to the head of the {container}")),
    # organize books (stages.demos.skill_books): the world's k-th book from the coffee table onto the bookshelf
    TaskSpec(name="shelve_book_1", family=Family.PICK_PLACE, max_seconds=60.0, success=shelve_book_1_success,
             templates=("put the {which} {object} on the {container}", "shelve the {which} {object}",
                        "stand the {which} {object} on a board of the {container}")),
    TaskSpec(name="shelve_book_2", family=Family.PICK_PLACE, max_seconds=60.0, success=shelve_book_2_success,
             templates=("put the {which} {object} on the {container}", "shelve the {which} {object}",
                        "stand the {which} {object} on a board of the {container}")),
    # organize the wardrobe (stages.demos.skill_wardrobe): a hanger from the bed hooked over the wardrobe's rail
    TaskSpec(name="hang_on_rail", family=Family.PICK_PLACE, max_seconds=60.0, success=hang_on_rail_success,
             templates=("hang the {object} in the {container}", "hang the {object} on the rail of the {container}",
                        "put the {object} on the {container}'s rail")),
    TaskSpec(name="push_object", family=Family.PUSH_PULL, max_seconds=25.0, success=push_object_success,
             templates=("push the {object} away across the table", "slide the {object} away from you")),
    TaskSpec(name="press_button", family=Family.PUSH_PULL, max_seconds=25.0, success=press_button_success,
             templates=("press the button on the {panel}", "push the {panel} button")),
    TaskSpec(name="press_clock_button", family=Family.PUSH_PULL, max_seconds=30.0,
             success=press_clock_button_success,
             templates=("press the button on top of the {object}", "push the {object}'s button")),
    TaskSpec(name="slide_clock_switch", family=Family.PUSH_PULL, max_seconds=30.0,
             success=slide_clock_switch_success,
             templates=("slide the switch on the back of the {object}", "switch the {object}'s alarm on")),
)}


# -- open / close of articulated parts (stages.demos.parts) ------------------------------------

#: articulated task target -> (placed role in the world, part role, instruction noun)
ARTICULATED = {"microwave": ("microwave", "door", "microwave"), "fridge": ("fridge", "door", "fridge"),
               "oven": ("oven", "door", "oven"), "drawer": ("counter", "drawer", "kitchen counter"),
               "door": ("door", "door", "room"), "wardrobe": ("wardrobe", "door", "wardrobe")}
OPEN_FRACTION = 0.75  # open: the joint past this fraction of its travel
#: time limit of open/close episodes [s]: a wide door the base cannot turn is carried in up to 4 stages of ~10-15 s
OPEN_CLOSE_SECONDS = 90.0


def _opened(inst, state, peaks=None) -> tuple[bool, str]:
    return part_opened(inst.part, state, OPEN_FRACTION)


def _closed(inst, state, peaks=None) -> tuple[bool, str]:
    return part_closed(inst.part, state)


def _articulated_specs() -> list[TaskSpec]:
    specs = []
    for target in ARTICULATED:
        if target == "door":
            opens, closes = ("open the door", "open the room door"), ("close the door", "shut the room door")
        elif target == "drawer":
            opens = ("open the drawer of the {furniture}", "pull the drawer of the {furniture} open")
            closes = ("close the drawer of the {furniture}", "push the drawer of the {furniture} shut")
        else:
            opens = ("open the {furniture} door", "open the {furniture}")
            closes = ("close the {furniture} door", "shut the {furniture}")
        specs.append(TaskSpec(name=f"open_{target}", family=Family.OPEN_CLOSE, max_seconds=OPEN_CLOSE_SECONDS,
                              success=_opened, templates=opens))
        specs.append(TaskSpec(name=f"close_{target}", family=Family.OPEN_CLOSE, max_seconds=OPEN_CLOSE_SECONDS,
                              success=_closed, templates=closes))
    return specs


TASKS.update({t.name: t for t in _articulated_specs()})
#: skills of the multistage household tasks (stages.demos.multistage): tasks with experts and
#: predicates, but not basic tasks (a plain task kitchen lacks their objects or their pacing)
SKILL_TASKS = ("pick_place_fridge", "wipe_plate", "place_in_rack", "throw_away", "pick_pitcher", "pour_drink", "place_pitcher",
               "press_clock_button", "slide_clock_switch", "place_pillow", "shelve_book_1", "shelve_book_2",
               "hang_on_rail", "open_wardrobe", "close_wardrobe")
#: the tasks a basic dataset covers (every family; articulated open/close of every part kind): the
#: demos job's default
BASIC_TASKS = tuple(t for t in TASKS if t not in SKILL_TASKS)


def task(name: str) -> TaskSpec:
    """The spec of task ``name``; KeyError lists the known tasks."""
    try:
        return TASKS[name]
    except KeyError:
        raise KeyError(f"unknown task {name!r}; known: {sorted(TASKS)}") from None
