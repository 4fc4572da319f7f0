"""USD stages for the thin-contact tests (``test_simulate_thin_contacts.py``, ``test_simulate_gap.py``):
a floor, and free boxes on it."""

from __future__ import annotations

from pathlib import Path


def floor_stage(path: Path):
    """A new Z-up, metre stage at ``path`` with ``/World`` (default prim) and a 6 x 6 m static floor
    whose top is z = 0, centred on (3, 3)."""
    from pxr import Gf, Usd, UsdGeom, UsdPhysics

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(stage.GetPrimAtPath("/World"))
    floor = UsdGeom.Cube.Define(stage, "/World/Floor")
    floor.CreateSizeAttr(1.0)
    UsdGeom.XformCommonAPI(floor).SetTranslate(Gf.Vec3d(3.0, 3.0, -0.05))
    UsdGeom.XformCommonAPI(floor).SetScale(Gf.Vec3f(6.0, 6.0, 0.1))
    UsdPhysics.CollisionAPI.Apply(floor.GetPrim())
    return stage


def add_free_box(stage, prim_path: str, center, size, mass: float) -> None:
    """A free rigid box (cube prim) of full extents ``size`` [m] centred at ``center`` [m], ``mass`` [kg]."""
    from pxr import Gf, UsdGeom, UsdPhysics

    box = UsdGeom.Cube.Define(stage, prim_path)
    box.CreateSizeAttr(1.0)
    UsdGeom.XformCommonAPI(box).SetTranslate(Gf.Vec3d(*map(float, center)))
    UsdGeom.XformCommonAPI(box).SetScale(Gf.Vec3f(*map(float, size)))
    UsdPhysics.CollisionAPI.Apply(box.GetPrim())
    UsdPhysics.RigidBodyAPI.Apply(box.GetPrim())
    UsdPhysics.MassAPI.Apply(box.GetPrim()).CreateMassAttr(mass)
