"""Multistage tasks as data (issue 16): task files parse into skills with per-stage language,
bad files fail with one message naming the file and every problem, and the demos job accepts the
shipped tasks."""

from __future__ import annotations

import pytest

from stages.demos.multistage import (
    MULTISTAGE,
    MultistageError,
    is_task,
    load_multistage_dir,
    parse_multistage,
    task_spec,
)
from stages.demos.tasks import TASKS, Family

GOOD = """
name = "heat_it"
room = "kitchen"
max_seconds = 120.0
templates = ["heat it"]
[[stage]]
skill = "pick_place_microwave"
instruction = "put the mug in the microwave"
[[stage]]
skill = "close_microwave"
instruction = "close the microwave"
"""


def test_the_shipped_heat_food_task_is_three_basic_skills():
    spec = MULTISTAGE["heat_food"]
    assert [s.skill for s in spec.stages] == ["pick_place_microwave", "close_microwave", "press_button"]
    assert spec.subtasks == ("put the mug in the microwave", "close the microwave door",
                             "press the microwave's start button")
    assert all(s.skill in TASKS for s in spec.stages)
    ts = task_spec("heat_food")
    assert ts.family is Family.MULTISTAGE and ts.max_seconds == 150.0
    assert is_task("heat_food") and is_task("press_button") and not is_task("fly")


def test_a_task_file_loads_from_a_folder(tmp_path):
    (tmp_path / "a.toml").write_text(GOOD)
    specs = load_multistage_dir(tmp_path)
    assert list(specs) == ["heat_it"] and len(specs["heat_it"].stages) == 2
    (tmp_path / "b.toml").write_text(GOOD)
    with pytest.raises(MultistageError, match=r"b\.toml: task 'heat_it' is also defined in .*a\.toml"):
        load_multistage_dir(tmp_path)


def test_a_bad_task_file_names_the_file_and_every_problem(tmp_path):
    bad = {"name": "Heat", "room": "garage", "max_seconds": -1, "templates": [], "colour": "red",
           "stage": [{"skill": "juggle", "instruction": ""}, "oops"]}
    with pytest.raises(MultistageError) as e:
        parse_multistage(bad, "tasks/heat.toml")
    msg = str(e.value)
    assert msg.startswith("tasks/heat.toml: ") and "\n" not in msg
    for part in ("unknown key 'colour'", "name must match", "room must be one of", "max_seconds",
                 "templates must be", "stage 1: unknown skill 'juggle'", "stage 1: instruction",
                 "stage 2: must be a table"):
        assert part in msg, part
    with pytest.raises(MultistageError, match="is a basic task"):
        parse_multistage({**bad, "name": "press_button"}, "x.toml")
    (tmp_path / "broken.toml").write_text("name = ")
    with pytest.raises(MultistageError, match="broken.toml"):
        load_multistage_dir(tmp_path)


def test_the_demos_job_accepts_multistage_tasks():
    from stages.demos.job import DemosConfig

    assert DemosConfig(tasks=("heat_food", "press_button")).tasks == ("heat_food", "press_button")
    with pytest.raises(ValueError, match="multistage"):
        DemosConfig(tasks=("heat_the_house",))



def test_store_food_opens_the_fridge_first_and_checks_it_closed_at_the_end():
    spec = MULTISTAGE["store_food"]
    assert [s.skill for s in spec.stages] == ["open_fridge", "pick_place_fridge", "close_fridge"]
    assert [s.final for s in spec.stages] == [False, True, True] and spec.objects_from == 1
    assert task_spec("store_food").family is Family.MULTISTAGE


def test_final_and_objects_from_are_checked():
    import tomllib

    data = tomllib.loads(GOOD)
    spec = parse_multistage({**data, "objects_from": 2, "stage": [{**data["stage"][0], "final": False},
                                                                   data["stage"][1]]}, "ok.toml")
    assert spec.objects_from == 1 and [s.final for s in spec.stages] == [False, True]
    with pytest.raises(MultistageError) as e:
        parse_multistage({**data, "objects_from": 3, "stage": [{**data["stage"][0], "final": "no"}]}, "x.toml")
    assert "objects_from must be a stage number 1..1, got 3" in str(e.value)
    assert "stage 1: final must be true or false" in str(e.value)


def test_a_store_food_episode_starts_closed_with_the_mug_on_the_counter(kitchen_room):
    """The episode's scene joints: the fridge closed (open_fridge's set-up wins over the later
    stages' open door); the mug where pick_place_fridge takes it from (objects_from = 2); the
    shelf it goes to lies inside the fridge, behind the door's opening."""
    from stages.demos.multistage import sample_task, stage_instance
    from stages.demos.sampling import sample_instance

    inst = sample_task("store_food", kitchen_room, 3)
    door = kitchen_room.placed["fridge"].joint("door_0_joint")
    assert inst.joints[door] == 0.0
    pick = sample_instance("pick_place_fridge", kitchen_room, 3)
    mug = kitchen_room.placed["mug"].body()
    assert inst.objects[mug] == pick.objects[mug]
    assert abs(inst.objects[mug][2] - kitchen_room.counter_z - 0.002) < 1e-9
    assert pick.joints[door] > 1.2  # open (0.9 of its 90 deg) for the pick-and-place alone
    shelf = stage_instance(MULTISTAGE["store_food"].stages[1], inst).place
    fx0, fy0, fx1, fy1 = kitchen_room.placed["fridge"].footprint()
    x0, y0, x1, y1 = shelf.rect
    assert fx0 < x0 < shelf.spot[0] < x1 < fx1 and fy0 < y0 < shelf.spot[1] < y1 < fy1
    assert 0.5 <= shelf.z <= 1.2


def test_clean_dishes_is_the_wipe_checked_when_it_ends():
    spec = MULTISTAGE["clean_dishes"]
    assert [(s.skill, s.final) for s in spec.stages] == [("wipe_plate", False), ("place_in_rack", True)]
    assert "wipe_plate" in TASKS


def test_only_household_skill_tasks_ask_for_the_household_objects():
    from stages.demos.multistage import needs_household
    from stages.demos.tasks import TASKS

    assert needs_household(["clean_dishes"]) and needs_household(["pick_place_bowl", "clean_table"])
    assert not needs_household(list(TASKS)) and not needs_household(["heat_food", "store_food", "tidy_kitchen"])
