"""The final rewrite of a scene's layers for the folder it moves to (build_scene's finalize) costs
two small layer writes, not a full garbage collection of the process (0.1-0.9 s of CPU per scene in
a process holding a library and Newton, measured by bench_scene), and the moved scene composes."""

from __future__ import annotations

import gc
import os
import time

import numpy as np
import pytest

from stages.scene.solver import Library

RULES = """[room.kitchen]
[[room.kitchen.furniture]]
category = "kitchen_counter"
count = [1, 1]
mode = "wall"
[[room.kitchen.objects]]
category = "microwave"
count = [1, 1]
on = ["kitchen_counter"]
align = true
[[room.kitchen.objects]]
category = "mug"
count = [1, 3]
on = ["kitchen_counter"]
"""


@pytest.fixture(scope="module")
def kitchen(tmp_path_factory):
    from stages.layout.build import generate_layout
    from stages.layout.spec import LayoutSpec
    from stages.scene.rules import load_rules
    from stages.scene.standin import build_library

    root = tmp_path_factory.mktemp("finalize")
    index = build_library(root / "lib", categories=["kitchen_counter", "microwave", "mug"], variants=2, seed=0)
    lay = generate_layout(LayoutSpec(rooms={"kitchen": 1}), 3, root / "layout")
    (root / "rules.toml").write_text(RULES, encoding="utf-8")
    return Library.from_index(index), lay, load_rules(root / "rules.toml")


def test_finalize_costs_less_than_a_garbage_collection_and_the_moved_scene_composes(kitchen, tmp_path):
    from pxr import Usd

    from stages.scene.build import BuildOptions, build_scene
    from usd_schemas._validate import _composition_issues

    lib, lay, rules = kitchen
    heap = [[i] for i in range(1_500_000)]  # a worker's heap: library, meshes, Newton (tracked objects)
    c = time.process_time()
    gc.collect()
    gc_cpu = time.process_time() - c
    tmp, final = tmp_path / ".tmp" / "scene_0", tmp_path / "scene_0"
    s = build_scene(lay.plan_json, lay.usd, lib, rules, np.random.default_rng(1), tmp, final,
                    BuildOptions(n_looks=1, settle=False, validate=False))
    del heap
    assert s.cpu_seconds["finalize"] < gc_cpu / 2, (s.cpu_seconds, gc_cpu)
    os.replace(tmp, final)
    stage = Usd.Stage.Open(str(final / "scene.usda"))
    assert [i.line() for i in _composition_issues(stage)] == []
    for inst in s.instances:
        prim = stage.GetPrimAtPath(f"/World/Objects/{inst.name}")
        assert prim.IsDefined() and prim.GetChildren(), inst.name   # its package's reference resolved
    assert stage.GetPrimAtPath("/World/Layout").GetChildren()
