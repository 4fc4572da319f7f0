"""A fingertip pressed into a thin convex hull gets an active contact (build_sim, MuJoCo's C library).

The alarm clock's button cap (a 26 mm disc, 5 mm thick, 20 sides: a convex-hull mesh collider) let
the Panda's box fingertips pass through it: with Newton's default contact gap of 0.1 m per shape,
MuJoCo (3.9+ semantics: the gap widens the detection distance) ran its convex collision with a
0.1 m margin, and for a box 3 mm into the thin hull it returned a separated contact (distance
+2 mm, inactive) instead of the penetration. :class:`~stages.simulate.world.SimConfig`'s
``contact_gap`` (default :data:`~stages.simulate.world.CONTACT_GAP`) keeps the detection distance
at 1 cm, where the depth is right. (MuJoCo-Warp, the batched engine's GPU solver, got the depth
right with either gap; the slow test below checks it on the CPU.)
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("newton")
pytest.importorskip("mujoco")
pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")

from contact_testutil import add_free_box, floor_stage  # noqa: E402
from stages.simulate.robot import find_panda_description, write_robot_urdf  # noqa: E402
from stages.simulate.world import SimConfig, build_sim  # noqa: E402

DISC_R, DISC_H, SIDES = 0.013, 0.005, 20   # the clock's button cap [m]
TIP = (0.0175, 0.007, 0.0235)              # a Panda fingertip pad box (full extents) [m]
DISC_AT = (4.0, 4.0, 0.80)                 # the cap's centre [m]


def write_disc_scene(path: Path) -> Path:
    """A floor, a fixed thin disc (convex-hull mesh collider) at DISC_AT and a free fingertip-sized
    box (cube prim) beside it."""
    from pxr import Gf, UsdGeom, UsdPhysics

    stage = floor_stage(path)
    disc = UsdGeom.Mesh.Define(stage, "/World/Disc")
    a = [2 * math.pi * k / SIDES for k in range(SIDES)]
    x, y, z = DISC_AT
    pts = [Gf.Vec3f(x + DISC_R * math.cos(t), y + DISC_R * math.sin(t), z + s * DISC_H / 2)
           for s in (-1, 1) for t in a]
    disc.CreatePointsAttr(pts)
    faces = [[SIDES - 1 - k for k in range(SIDES)], [SIDES + k for k in range(SIDES)]]
    faces += [[k, (k + 1) % SIDES, SIDES + (k + 1) % SIDES, SIDES + k] for k in range(SIDES)]
    disc.CreateFaceVertexCountsAttr([len(f) for f in faces])
    disc.CreateFaceVertexIndicesAttr([i for f in faces for i in f])
    UsdPhysics.CollisionAPI.Apply(disc.GetPrim())
    UsdPhysics.MeshCollisionAPI.Apply(disc.GetPrim()).CreateApproximationAttr("convexHull")
    add_free_box(stage, "/World/Tip", (DISC_AT[0] + 0.3, DISC_AT[1], TIP[2] / 2), TIP, 0.02)
    stage.Save()
    return path


@pytest.fixture(scope="module")
def disc_sim(tmp_path_factory):
    desc = write_robot_urdf(tmp_path_factory.mktemp("robot"), panda_root=find_panda_description(None))
    scene = write_disc_scene(tmp_path_factory.mktemp("disc") / "disc.usda")
    return build_sim(SimConfig(scenes=(scene,), spawn=(1.5, 1.5, 0.0)), desc, np.random.default_rng(0))


@pytest.mark.parametrize("depth", [0.001, 0.003])
def test_a_fingertip_box_inside_a_thin_hull_gets_an_active_contact(disc_sim, depth):
    import mujoco

    sim = disc_sim
    m, d = sim.solver.mj_model, sim.solver.mj_data
    name = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b): b for b in range(m.nbody)}
    tip_body = next(b for n, b in name.items() if n and "Tip" in n)
    tip_geom = int(np.nonzero(m.geom_bodyid == tip_body)[0][0])
    disc_geom = next(g for g in range(m.ngeom) if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH)
    adr = m.jnt_qposadr[m.body_jntadr[tip_body]]
    # the tip's bottom ``depth`` below the cap's top, off its centre as a fingertip lands
    x, y, z = DISC_AT
    d.qpos[adr:adr + 3] = (x + 0.003, y + 0.002, z + DISC_H / 2 + TIP[2] / 2 - depth)
    d.qpos[adr + 3:adr + 7] = (1.0, 0.0, 0.0, 0.0)
    mujoco.mj_forward(m, d)
    pair = [c for c in d.contact[:d.ncon] if {int(c.geom1), int(c.geom2)} == {tip_geom, disc_geom}]
    assert pair, "no contact between the fingertip box and the disc"
    dist = min(float(c.dist) for c in pair)
    assert dist == pytest.approx(-depth, abs=3e-4), f"contact distance {dist:+.4f} m, overlap {depth:.3f} m"
    assert any(int(c.exclude) == 0 for c in pair), "the contact is inactive (in the gap)"


def test_the_gap_is_recorded_and_small(disc_sim):
    assert disc_sim.settings.options["contact_gap"] <= 0.02
    assert float(disc_sim.model.shape_gap.numpy().max()) <= 0.02



@pytest.mark.slow
def test_mujoco_warp_gives_the_same_active_contact(tmp_path):
    """The batched engine's solver (MuJoCo-Warp, here on the CPU) sees a 3 mm overlap too (it did with
    the 0.1 m gap as well: only MuJoCo's C library, the one-world CPU path, lost the contact)."""
    pytest.importorskip("mujoco_warp")
    import mujoco
    import newton

    from stages.simulate.world import SolverSettings

    depth = 0.003
    desc = write_robot_urdf(tmp_path / "robot", panda_root=find_panda_description(None))
    scene = write_disc_scene(tmp_path / "disc.usda")
    sim = build_sim(SimConfig(scenes=(scene,), spawn=(1.5, 1.5, 0.0),
                              solver=SolverSettings(use_mujoco_cpu=False, contact_check_every=0)),
                    desc, np.random.default_rng(0))
    tip = next(b for b, p in sim.scene.body_path.items() if p.endswith("/Tip"))
    s = int(sim.model.joint_q_start.numpy()[int(np.nonzero(sim.model.joint_child.numpy() == tip)[0][0])])
    q = sim.state_0.joint_q.numpy()
    x, y, z = DISC_AT
    q[s:s + 7] = (x + 0.003, y + 0.002, z + DISC_H / 2 + TIP[2] / 2 - depth, 0.0, 0.0, 0.0, 1.0)  # xyz, xyzw
    sim.state_0.joint_q.assign(q)
    newton.eval_fk(sim.model, sim.state_0.joint_q, sim.state_0.joint_qd, sim.state_0)
    sim.step(1)
    d, m = sim.solver.mjw_data, sim.solver.mj_model
    n = int(d.nacon.numpy()[0])
    geom, dist = d.contact.geom.numpy()[:n], d.contact.dist.numpy()[:n]
    disc = next(g for g in range(m.ngeom) if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH)
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) or "" for b in range(m.nbody)]
    tip_body = next(b for b, nm in enumerate(names) if "Tip" in nm)
    tip_geoms = set(np.nonzero(m.geom_bodyid == tip_body)[0].tolist())
    pair = [float(dist[i]) for i in range(n) if disc in geom[i] and tip_geoms & set(geom[i].tolist())]
    assert pair, "no contact between the fingertip box and the disc"
    assert min(pair) == pytest.approx(-depth, abs=5e-4), f"contact distance {min(pair):+.4f} m"
