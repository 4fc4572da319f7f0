"""Multistage household tasks as data: a task is a sequence of skills, each a basic task's expert,
with a language instruction and a success predicate per stage and for the whole task.

A task file (``stages/demos/multistage/<name>.toml``, or any folder passed to
:func:`load_multistage_dir`)::

    name = "heat_food"
    room = "kitchen"
    max_seconds = 150.0                    # the whole episode's time limit [s]
    templates = ["heat the food in the microwave", ...]
    [[stage]]
    skill = "pick_place_microwave"         # a basic task (stages.demos.tasks.TASKS)
    instruction = "put the mug in the microwave"
    [[stage]]
    skill = "close_microwave"
    instruction = "close the microwave door"
    final = true                           # (default) its predicate must still hold at the end

Optional: ``objects_from = k`` (task key, 1-based, default 1): the stage whose sampled instance
places the objects at the episode's start (store_food opens the fridge first, then takes the mug
from where its second stage's skill starts it); ``final = false`` (stage key): a stage whose
result a later stage undoes (the fridge opened, then closed again) is checked when it ends, not
at the episode's end.

Semantics (the solver apart from the data, as the scene rules):

- the episode starts from the first stage's instance (:func:`~stages.demos.sampling.sample_instance`
  of its skill with the episode's seed): robot start, object poses (those of stage
  ``objects_from``); its scene joints are every
  stage's set-up (a close stage's part starts open), an earlier stage's value first;
- each stage runs its skill's expert from the state the previous stage left: its instance is the
  skill's instance for the same seed with the *current* object poses and scene joint positions
  (a door left open at 88 deg is closed from 88 deg), then checks the skill's success predicate
  at once; a failure ends the episode with the reason ``s<k>_<skill>.<reason>`` (counted by stage);
- the whole task succeeds when every ``final`` stage's predicate holds on the final state (a mug
  put into the microwave must still be inside when its button is pressed);
- the engine records the stage of every frame (``subtask_index``) and the stages' instructions as
  the episode's ``subtasks``.

Frame: world, Z up, metres, radians.
"""

from __future__ import annotations

import logging
import math
import re
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from stages.demos.driver import Driver, ExpertFailure
from stages.demos.experts import EXPERTS
from stages.demos.record import EpisodeTimeout
from stages.demos.sampling import TaskInstance, sample_instance
from stages.demos.tasks import TASKS, Family, TaskSpec

log = logging.getLogger(__name__)

TASKS_DIR = Path(__file__).with_name("multistage")
"""folder of the shipped multistage task files"""
ROOMS = ("kitchen", "living_room", "bedroom")
_NAME_RE = re.compile(r"^[a-z][a-z0-9_]*$")


class MultistageError(ValueError):
    """A task file that cannot be used; the message names the file and lists every problem."""


@dataclass(frozen=True)
class Stage:
    """skill: the basic task whose expert and predicate the stage uses; instruction: its language;
    final: its predicate is part of the whole task's (False: a later stage undoes it)."""

    skill: str
    instruction: str
    final: bool = True


@dataclass(frozen=True)
class MultistageSpec:
    """name; room: where it happens; max_seconds: episode time limit [s]; templates: the whole
    task's instructions; stages: in order; source: the file it came from; objects_from: the
    stage (0-based) whose instance places the objects at the start."""

    name: str
    room: str
    max_seconds: float
    templates: tuple[str, ...]
    stages: tuple[Stage, ...]
    source: str = ""
    objects_from: int = 0

    @property
    def subtasks(self) -> tuple[str, ...]:
        return tuple(s.instruction for s in self.stages)

    def task_spec(self) -> TaskSpec:
        """The engine's view of the task: family multistage, its time limit and whole-task predicate."""
        return TaskSpec(name=self.name, family=Family.MULTISTAGE, templates=self.templates,
                        max_seconds=self.max_seconds, success=lambda inst, state, peaks=None:
                        whole_task_success(self, inst, state, peaks))


def parse_multistage(data: dict, source: str) -> MultistageSpec:
    """A spec from a task file's table; :class:`MultistageError` lists every problem."""
    problems: list[str] = []
    known = {"name", "room", "max_seconds", "templates", "stage", "objects_from"}
    problems += [f"unknown key {k!r}" for k in sorted(set(data) - known)]
    name = data.get("name")
    if not isinstance(name, str) or not _NAME_RE.match(name):
        problems.append(f"name must match [a-z][a-z0-9_]*, got {name!r}")
    elif name in TASKS:
        problems.append(f"name {name!r} is a basic task")
    room = data.get("room")
    if room not in ROOMS:
        problems.append(f"room must be one of {ROOMS}, got {room!r}")
    limit = data.get("max_seconds")
    if not isinstance(limit, (int, float)) or isinstance(limit, bool) or not 0 < limit <= 3600:
        problems.append(f"max_seconds must be a number in (0, 3600], got {limit!r}")
    templates = data.get("templates")
    if not (isinstance(templates, list) and templates and all(isinstance(t, str) and t.strip() for t in templates)):
        problems.append("templates must be a non-empty list of non-empty strings")
    stages = data.get("stage")
    out: list[Stage] = []
    if not (isinstance(stages, list) and stages):
        problems.append("needs at least one [[stage]]")
    else:
        for k, st in enumerate(stages, 1):
            if not isinstance(st, dict):
                problems.append(f"stage {k}: must be a table")
                continue
            extra = sorted(set(st) - {"skill", "instruction", "final"})
            problems += [f"stage {k}: unknown key {x!r}" for x in extra]
            skill, text = st.get("skill"), st.get("instruction")
            if skill not in TASKS or skill not in EXPERTS:
                problems.append(f"stage {k}: unknown skill {skill!r}; known: {sorted(TASKS)}")
            if not (isinstance(text, str) and text.strip()):
                problems.append(f"stage {k}: instruction must be a non-empty string")
            final = st.get("final", True)
            if not isinstance(final, bool):
                problems.append(f"stage {k}: final must be true or false, got {final!r}")
            out.append(Stage(str(skill), str(text), bool(final)))
    first = data.get("objects_from", 1)
    if not isinstance(first, int) or isinstance(first, bool) or not 1 <= first <= max(1, len(out)):
        problems.append(f"objects_from must be a stage number 1..{max(1, len(out))}, got {first!r}")
    if problems:
        raise MultistageError(f"{source}: " + "; ".join(problems))
    return MultistageSpec(name=name, room=room, max_seconds=float(limit), templates=tuple(templates),
                          stages=tuple(out), source=source, objects_from=int(first) - 1)


def load_multistage_dir(folder: Path) -> dict[str, MultistageSpec]:
    """Every ``*.toml`` task file of ``folder`` by task name (a repeated name is an error)."""
    specs: dict[str, MultistageSpec] = {}
    for path in sorted(Path(folder).glob("*.toml")):
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
            raise MultistageError(f"{path}: {e}") from None
        spec = parse_multistage(data, str(path))
        if spec.name in specs:
            raise MultistageError(f"{path}: task {spec.name!r} is also defined in {specs[spec.name].source}")
        specs[spec.name] = spec
    return specs


MULTISTAGE: dict[str, MultistageSpec] = load_multistage_dir(TASKS_DIR)
"""the shipped multistage tasks by name"""


def is_task(name: str) -> bool:
    """A basic or a shipped multistage task."""
    return name in TASKS or name in MULTISTAGE


def task_spec(name: str) -> TaskSpec:
    """The :class:`TaskSpec` of a basic or multistage task (KeyError lists both kinds)."""
    if name in MULTISTAGE:
        return MULTISTAGE[name].task_spec()
    if name in TASKS:
        return TASKS[name]
    raise KeyError(f"unknown task {name!r}; known: {sorted(TASKS) + sorted(MULTISTAGE)}")


def sample_task(name: str, world, seed: int) -> TaskInstance:
    """The episode of a basic or multistage task ``name`` in ``world`` from ``seed``: a multistage
    episode starts as its first stage's instance, with the task's name and instruction."""
    spec = MULTISTAGE.get(name)
    if spec is None:
        return sample_instance(name, world, seed)
    stage_insts = [sample_instance(st.skill, world, seed) for st in spec.stages]
    rng = np.random.default_rng([int(seed), 16])
    text = spec.templates[int(rng.integers(len(spec.templates)))]
    ids = tuple(dict.fromkeys(a for si in stage_insts for a in si.asset_ids))
    joints: dict[str, float] = {}
    for si in reversed(stage_insts):  # every stage's scene set-up; an earlier stage's wins
        joints.update(si.joints)
    return replace(stage_insts[0], task=name, instruction=text, asset_ids=ids, joints=joints,
                   objects=stage_insts[spec.objects_from].objects)


def stage_instance(stage: Stage, inst: TaskInstance, state=None) -> TaskInstance:
    """The instance stage ``stage`` of multistage episode ``inst`` runs: its skill's instance for
    the episode's seed, with the current object poses and scene joint positions of ``state``
    (a :class:`~stages.simulate.state.StepState`) when given (None: as sampled). Its
    ``start_base`` stays as sampled: only a reset reads it, and a stage does not reset."""
    si = sample_instance(stage.skill, inst.world, inst.seed)
    if state is None:
        return replace(si, instruction=stage.instruction)
    objects = {}
    for body in si.objects:
        o = state.objects[body]
        w, x, y, z = (float(v) for v in o.orientation)
        yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        objects[body] = (*(float(v) for v in o.position), yaw)
    joints = {p: float(state.scene_joints[p]) for p in si.joints}
    return replace(si, instruction=stage.instruction, objects=objects, joints=joints)


def run_stages(spec: MultistageSpec, inst: TaskInstance, d: Driver, *, peaks: Callable[[], dict],
               on_stage: Callable[[int], None]) -> None:
    """Run the stages of ``spec`` in episode ``inst`` through driver ``d``: ``on_stage(k)`` as
    stage ``k`` (0-based) begins, its skill's expert from the current state, its predicate at once
    (``peaks()``: the watched joints' peaks so far). Raises :class:`ExpertFailure` with reason
    ``s<k+1>_<skill>.<reason>`` when a stage's expert fails, runs out of time or misses its goal."""
    from stages.simulate.state import read_state

    for k, stage in enumerate(spec.stages):
        tag = f"s{k + 1}_{stage.skill}"
        on_stage(k)
        si = stage_instance(stage, inst, read_state(d.sim) if k else None)
        try:
            EXPERTS[stage.skill](si, d)
            d.step(0.3)
        except ExpertFailure as e:
            raise ExpertFailure(f"{tag}.{e.reason}", str(e)) from None
        except EpisodeTimeout as e:
            raise ExpertFailure(f"{tag}.timeout", str(e)) from None
        ok, reason = TASKS[stage.skill].success(si, read_state(d.sim), peaks=peaks())
        if not ok:
            raise ExpertFailure(f"{tag}.{reason}", f"stage {k + 1} ({stage.instruction}) missed its goal")
        log.debug("%s seed %d: stage %d (%s) done at %.1f s", spec.name, inst.seed, k + 1, stage.skill,
                  d.sim.time)


def whole_task_success(spec: MultistageSpec, inst: TaskInstance, state, peaks=None) -> tuple[bool, str]:
    """Every ``final`` stage's predicate on the final state (reason ``final_s<k>_<skill>.<reason>``
    of the first that fails)."""
    for k, stage in enumerate(spec.stages, 1):
        if not stage.final:
            continue
        ok, reason = TASKS[stage.skill].success(stage_instance(stage, inst), state, peaks=peaks)
        if not ok:
            return False, f"final_s{k}_{stage.skill}.{reason}"
    return True, ""


#: skills whose objects a task kitchen parks only when asked (``write_kitchen(household=True)``)
HOUSEHOLD_SKILLS = ("wipe_plate", "place_in_rack", "throw_away")


def needs_household(tasks) -> bool:
    """Whether any of ``tasks`` (names) is a multistage task with a household skill's stage."""
    return any(st.skill in HOUSEHOLD_SKILLS for t in tasks if t in MULTISTAGE for st in MULTISTAGE[t].stages)


def needs_drink(tasks) -> bool:
    """Whether any of ``tasks`` (names) is a pour skill or a multistage task with a pour stage: its
    kitchen parks a pitcher with the drink and a cup (``write_kitchen(drink=True)``)."""
    from stages.demos.sampling import POUR_SKILLS

    return uses_skills(tasks, POUR_SKILLS)


def uses_skills(tasks, skills) -> bool:
    """Whether any of ``tasks`` (names) is one of ``skills`` or a multistage task with a stage of one."""
    return any(t in skills or (t in MULTISTAGE and any(st.skill in skills for st in MULTISTAGE[t].stages))
               for t in tasks)


#: skills whose alarm clock a task kitchen parks only when asked (``write_kitchen(clock=True)``)
CLOCK_SKILLS = ("press_clock_button", "slide_clock_switch")


def needs_clock(tasks) -> bool:
    """Whether any of ``tasks`` (names) is a clock skill or a multistage task with a clock skill's stage."""
    return uses_skills(tasks, CLOCK_SKILLS)


def needs_wardrobe(tasks) -> bool:
    """Whether any of ``tasks`` (names) is a wardrobe skill or a multistage task with one: its bedroom world
    steps with multi-CCD contacts (``house_bedroom(multiccd=True)``: the hanger crept on the blanket)."""
    from stages.demos.sampling import WARDROBE_SKILLS

    return uses_skills(tasks, WARDROBE_SKILLS)
