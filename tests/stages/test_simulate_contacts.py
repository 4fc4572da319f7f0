"""Contact buffers sized from the model; an overflow is an error naming the world and the count.

Runs MuJoCo-Warp on the CPU (``use_mujoco_cpu=False``): a pile of boxes with a deliberately small
``nconmax`` / ``njmax`` raises :class:`ContactOverflowError`; the demos task kitchen with the
default sizing steps without one, and its capacities cover what it used with headroom.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("newton")
pytest.importorskip("mujoco_warp")
pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")

from stages.simulate.contacts import ContactOverflowError  # noqa: E402
from stages.simulate.robot import find_panda_description, write_robot_urdf  # noqa: E402
from stages.simulate.world import SimConfig, SolverSettings, build_sim  # noqa: E402

BOX = 0.1  # [m] edge of a pile box


def write_box_pile(path: Path, n: int = 4, layers: int = 3) -> Path:
    """A 6 x 6 m floor with walls and an n x n x layers pile of 0.1 m boxes at (4, 4) [m], each
    layer 5 mm above the one below (they settle onto each other within a few steps)."""
    from pxr import Gf, Usd, UsdGeom, UsdPhysics

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(stage.GetPrimAtPath("/World"))

    def box(name, center, size, dynamic):
        cube = UsdGeom.Cube.Define(stage, f"/World/{name}")
        cube.CreateSizeAttr(1.0)
        xf = UsdGeom.XformCommonAPI(cube)
        xf.SetTranslate(Gf.Vec3d(*center))
        xf.SetScale(Gf.Vec3f(*size))
        UsdPhysics.CollisionAPI.Apply(cube.GetPrim())
        if dynamic:
            UsdPhysics.RigidBodyAPI.Apply(cube.GetPrim())
            UsdPhysics.MassAPI.Apply(cube.GetPrim()).CreateMassAttr(0.2)

    box("Floor", (3.0, 3.0, -0.05), (6.0, 6.0, 0.1), False)
    for k, (c, s) in enumerate((((3.0, -0.05, 0.5), (6.0, 0.1, 1.0)), ((3.0, 6.05, 0.5), (6.0, 0.1, 1.0)),
                                ((-0.05, 3.0, 0.5), (0.1, 6.0, 1.0)), ((6.05, 3.0, 0.5), (0.1, 6.0, 1.0)))):
        box(f"Wall{k}", c, s, False)
    for layer in range(layers):
        for i in range(n):
            for j in range(n):
                z = BOX / 2 + layer * (BOX + 0.005) + 0.002
                box(f"Box_{layer}_{i}_{j}", (4.0 + i * (BOX + 0.002), 4.0 + j * (BOX + 0.002), z),
                    (BOX, BOX, BOX), True)
    stage.Save()
    return path


@pytest.fixture(scope="module")
def desc(tmp_path_factory):
    return write_robot_urdf(tmp_path_factory.mktemp("robot"), panda_root=find_panda_description(None))


@pytest.fixture(scope="module")
def pile(tmp_path_factory):
    return write_box_pile(tmp_path_factory.mktemp("pile") / "pile.usda")


def _pile_sim(pile, desc, contact_gap: float = SimConfig.contact_gap, **solver):
    cfg = SimConfig(scenes=(pile,), spawn=(1.5, 1.5, 0.0), world_count=2, contact_gap=contact_gap,
                    solver=SolverSettings(use_mujoco_cpu=False, contact_check_every=0, **solver))
    return build_sim(cfg, desc, np.random.default_rng(0))


def test_a_small_contact_buffer_overflows_with_the_world_and_count_named(pile, desc):
    # Newton's 0.1 m gap: with the 1 cm one, Newton raises the 24 to 484 per world, over the pile's 439
    sim = _pile_sim(pile, desc, contact_gap=0.1, nconmax=24)
    sim.step(20)
    with pytest.raises(ContactOverflowError, match=r"world \d: (broadphase|narrowphase) overflow") as e:
        sim.check_contacts()
    err = e.value
    assert err.kind in ("broadphase", "narrowphase")
    assert err.world in (0, 1)
    assert err.capacity == sim.solver.mjw_data.naconmax
    assert err.count > err.capacity, (err.count, err.capacity)
    assert f"{err.count} " in str(err)


def test_the_default_sizing_holds_the_pile_and_checks_while_stepping(pile, desc):
    sim = _pile_sim(pile, desc)
    cap = sim.settings.options["contact_capacity"]
    # 48 boxes, each near its neighbours, the floor and the walls: a few hundred near pairs per world
    assert cap["near_pairs"] > 48 and cap["nconmax"] >= 1.5 * cap["near_pairs"]
    assert sim.solver.mjw_data.naconmax == 2 * cap["nconmax"]
    sim.step(60)
    sim.check_contacts()
    peaks = sim.contact_monitor.peaks()
    assert peaks["contacts"].shape == (2,) and peaks["contacts"].min() > 48  # the pile rests on contacts
    assert peaks["ncollision"] < sim.solver.mjw_data.naconmax
    assert peaks["nefc"].max() < sim.solver.mjw_data.njmax


def test_too_few_constraint_rows_is_an_error_when_checked_while_stepping(pile, desc):
    sim = _pile_sim(pile, desc, njmax=64)
    object.__setattr__(sim.solver_settings, "contact_check_every", 10)
    with pytest.raises(ContactOverflowError, match=r"world \d: \d+ constraint rows, njmax is 64") as e:
        sim.step(60)
    assert e.value.kind == "constraints" and e.value.count > 64 and e.value.capacity == 64


def test_iteration_caps_are_counted_not_raised(pile, desc):
    """The solver's iteration limits (MuJoCo-Warp's ITERATIONS / LS_ITERATIONS bits) drop no data:
    the GPU success run failed two kitchens on bit 0x400 (a linesearch cap) before this."""
    sim = _pile_sim(pile, desc, iterations=1, ls_iterations=1)
    sim.step(30)
    sticky = int(sim.contact_monitor.sticky.numpy().max())
    from mujoco_warp import OverflowType

    assert sticky & int(OverflowType.ITERATIONS | OverflowType.LS_ITERATIONS), hex(sticky)
    sim.check_contacts()  # no ContactOverflowError
    caps = sim.contact_monitor.iteration_caps()
    assert caps["solver_iteration_cap_worlds"] + caps["linesearch_iteration_cap_worlds"] >= 1, caps
    assert max(caps.values()) <= 2


# -- the demos task kitchen -----------------------------------------------------------------------


@pytest.fixture(scope="module")
def kitchen(kitchen_room):
    """The kitchen of world seed 5 from the session's kitchen catalog (tests/stages/conftest.py)."""
    return kitchen_room


def test_the_demos_kitchen_default_sizing_does_not_overflow(kitchen, desc):
    """1,024 contacts per world overflowed MuJoCo-Warp's broadphase in this kitchen on the GPU."""
    cfg = SimConfig(scenes=(kitchen.usd,), spawn=kitchen.spawn, world_count=1,
                    solver=SolverSettings(use_mujoco_cpu=False, contact_check_every=50))
    sim = build_sim(cfg, desc, np.random.default_rng(0))
    cap = sim.settings.options["contact_capacity"]
    assert cap["nconmax"] > 1024 and cap["robot_shapes"] > 10
    assert sim.settings.options["nconmax"] == cap["nconmax"]
    sim.step(150)  # checks at steps 50, 100, 150
    sim.check_contacts()
    peaks = sim.contact_monitor.peaks()
    # (77 at rest with the 1 cm contact gap, 497 with Newton's 0.1 m: stages.simulate.contacts' doc)
    assert peaks["ncollision"] > 50, "the kitchen's resting contacts were not seen"
    # headroom: at rest the kitchen uses well under the sized capacity
    assert peaks["ncollision"] * 2 < sim.solver.mjw_data.naconmax
    assert peaks["nefc"].max() * 4 < sim.solver.mjw_data.njmax
