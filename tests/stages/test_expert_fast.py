"""Issue 12's fast paths of the scripted experts' planning and IK give the same results as the
code before it (kept in ``expert_reference.py``), bit for bit, on real inputs: the gripper poses
that ``part_planning.plan_stage`` tries on the teleop kitchen's fridge, microwave and oven (every
candidate base of their first stage), and the plans themselves on the simulated kitchen.

- ``Clik.solve`` (one kinematics pass per iteration, sliced Jacobian, numpy wrappers skipped);
- ``Clik.solve_many`` / ``clik_lanes.lockstep`` (solves in lockstep, batched algebra);
- ``part_planning.reach``, ``plan_stage`` and ``choose_base`` (candidates in lockstep).
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

pytest.importorskip("pinocchio")


@pytest.fixture(scope="module")
def ik(tmp_path_factory):
    from stages.simulate.control import Clik
    from stages.simulate.robot import find_panda_description, write_robot_urdf

    desc = write_robot_urdf(tmp_path_factory.mktemp("robot"), panda_root=find_panda_description(None))
    return Clik(desc)


def _first_stage(part, grid, task: str, q: float | None = None):
    """(q0, qs, mode, grid) of the first stage ``articulated._swing`` plans for ``task`` ("open"
    or "close") on a part at joint value ``q`` (default: closed to open, 70 % open to close)."""
    from stages.demos import articulated as art
    from stages.demos.part_planning import swept_grid

    vertical = abs(float(np.asarray(part.axis)[2])) > 0.7
    if task == "open":
        q = part.closed if q is None else q
        q1, mode = part.closed + 0.9 * part.travel, "grasp"
    else:
        q = part.closed + 0.7 * part.travel if q is None else q
        q1, mode = (part.closed, "push") if vertical else (part.closed + art.EDGE_LIFT_TO, "edge")
    step = math.copysign(math.radians(6.0), q1 - q)
    qs = [float(v) for v in np.arange(q + step, q1 + 0.5 * step, step)]
    if mode == "push":
        qs.append(part.closed - art.PUSH_OVERSHOOT)
    return q, qs, mode, swept_grid(grid, part, min(q, q1), max(q, q1))


@pytest.fixture(scope="module")
def requests(teleop_world, ik):
    """Solve requests (root-frame target 4x4, q0 (nq,), restarts) of reaches from every candidate
    base of the first stages of opening / closing the kitchen's fridge, microwave and oven: the
    first target of each with 6 restarts from the robot's neutral arm, the next ones warm-started
    from the previous target's reference solution."""
    import expert_reference as ref
    from stages.demos.part_grasps import door_pitch, drawer_pitch, gesture, grips
    from stages.demos.part_planning import _swing_bases
    from stages.demos.sampling import world_part
    from stages.simulate.control import Clik

    out = []
    spawn = teleop_world.spawn
    x0, y0, yaw0 = spawn
    for which, task in (("fridge", "open"), ("microwave", "close"), ("oven", "close")):
        part = world_part(teleop_world, which)
        q0, qs, mode, grid = _first_stage(part, teleop_world.grid(), task)
        vertical = abs(float(np.asarray(part.axis)[2])) > 0.7
        z = float(part.handle_at(q0)[2])
        p0 = door_pitch(z) if vertical else drawer_pitch(z)
        for base in _swing_bases(part, grid, q0, qs)[:6]:
            pitch, along = grips(part, base, p0, vertical, edge=mode == "edge")[0]
            approach, arc = gesture(part, q0, qs, pitch, mode, along)
            q = ik.neutral()
            c, s = math.cos(yaw0), math.sin(yaw0)
            dx, dy = base[0] - x0, base[1] - y0
            local = (c * dx + s * dy, -s * dx + c * dy, base[2] - yaw0)
            for name, v in zip(ik.desc.base_joints, local, strict=True):
                q[ik.q_idx[name]] = v
            for k, t in enumerate(approach + arc):
                target = Clik.world_to_root(spawn, t)
                out.append((target, q, 6 if k == 0 else 0))
                res = ref.clik_solve(ik, target, q, restarts=6 if k == 0 else 0, rng=np.random.default_rng(k))
                if res.position_error > 0.004:
                    break
                q = res.q
    return out


def _same(a, b) -> bool:
    return (np.array_equal(a.q, b.q) and a.position_error == b.position_error
            and a.rotation_error == b.rotation_error and a.iterations == b.iterations
            and a.success == b.success)


def test_clik_solve_equals_the_plain_loop(ik, requests):
    """Every request, with and without restarts: the same q, errors, iterations, success; the
    requests include unreachable targets (failed, stalled solves)."""
    import expert_reference as ref

    results = []
    for target, q0, restarts in requests:
        a = ik.solve(target, q0, restarts=restarts, rng=np.random.default_rng(3))
        b = ref.clik_solve(ik, target, q0, restarts=restarts, rng=np.random.default_rng(3))
        assert _same(a, b), (a, b)
        results.append(a)
    assert len(requests) > 50
    assert any(r.success for r in results) and any(r.position_error > 0.004 for r in results)
    assert any(r.iterations == 300 or not r.success for r in results)


@pytest.mark.parametrize("width", [1, 5, 32])
def test_solves_in_lockstep_equal_lone_solves(ik, requests, width: int):
    """``Clik.solve_many`` (lanes taken as they free up, ``width`` at a time) returns what each
    request's lone reference solve returns, restarts included (one rng per lane)."""
    import expert_reference as ref

    for restarts in (0, 6):
        group = [(t, q) for t, q, r in requests if r == restarts]
        res = ik.solve_many([t for t, _ in group], [q for _, q in group], restarts=restarts,
                            rngs=[np.random.default_rng(i) for i in range(len(group))], width=width)
        for i, ((t, q), a) in enumerate(zip(group, res, strict=True)):
            b = ref.clik_solve(ik, t, q, restarts=restarts, rng=np.random.default_rng(i))
            assert _same(a, b), (i, a, b)


def test_lockstep_with_few_iterations_equals_lone_solves(ik, requests):
    """Solves that run out of iterations (max_iters 3) end on the last iterate's kinematics."""
    import expert_reference as ref

    group = requests[:40]
    res = ik.solve_many([t for t, _, _ in group], [q for _, q, _ in group], max_iters=3)
    for (t, q, _), a in zip(group, res, strict=True):
        assert _same(a, ref.clik_solve(ik, t, q, max_iters=3))
    assert any(r.iterations == 3 for r in res)


@pytest.fixture(scope="module")
def sim_world(teleop_world, tmp_path_factory):
    pytest.importorskip("newton")
    from stages.demos.session import DemoSettings, DemoWorld

    d = tmp_path_factory.mktemp("expert_fast")
    return DemoWorld(teleop_world, panda_root=None, work_dir=d, settings=DemoSettings(record_images=False))


def _driver(sim_world, task: str, seed: int = 1):
    from stages.demos.driver import Driver
    from stages.demos.sampling import sample_instance

    inst = sample_instance(task, sim_world.world, seed)
    sim_world.reset(inst)
    return inst, Driver(sim_world.sim, sim_world.ctl, sim_world.ik, sim_world.cmd, sim_world.recorder,
                        np.random.default_rng(seed))


def _plan_equal(a, b) -> bool:
    return (a[0] == b[0] and a[1] == b[1] and a[2] == b[2] and a[4] == b[4] and len(a[3]) == len(b[3])
            and all(np.array_equal(x, y) for x, y in zip(a[3], b[3], strict=True)))


@pytest.mark.parametrize("task", ["open_microwave", pytest.param("close_oven", marks=pytest.mark.slow),
                                  pytest.param("open_fridge", marks=pytest.mark.slow)])
def test_plan_stage_and_reach_equal_the_reference(sim_world, task: str):
    """The first stage's plan (base, grip, waypoints reached, arm solutions) on the simulated
    kitchen equals the reference's, and so does ``reach`` from the planned base."""
    import expert_reference as ref
    from stages.demos.experts import _grid
    from stages.demos.part_grasps import gesture
    from stages.demos.part_planning import plan_stage, reach

    inst, d = _driver(sim_world, task)
    part = inst.part
    which = "open" if task.startswith("open") else "close"
    q_start = float(inst.joints.get(part.joint_path, part.closed))
    q0, qs, mode, grid = _first_stage(part, _grid(inst), which, q_start)
    a = plan_stage(d, part, grid, q0, qs, mode)
    b = ref.plan_stage(d, part, grid, q0, qs, mode)
    assert _plan_equal(a, b)
    assert a[2] >= 2
    approach, arc = gesture(part, q0, qs, a[1], mode, a[4])
    targets = approach + arc
    for base in (a[0], (a[0][0] + 0.05, a[0][1], a[0][2] + 0.3)):
        x, y = reach(d, base, targets), ref.reach(d, base, targets)
        assert len(x) == len(y) and all(np.array_equal(u, v) for u, v in zip(x, y, strict=True))


def test_choose_base_equals_the_first_reaching_candidate(sim_world):
    """The drawer's base pose: the first free candidate (in order) from which the reference's
    ``reach`` gets every target, as the sequential search found it."""
    import expert_reference as ref
    from stages.demos.driver import ROBOT_RADIUS
    from stages.demos.experts import _grid
    from stages.demos.part_grasps import GRASP_BACK, drawer_pitch, handle_pose, heading, lateral, toward_hinge
    from stages.demos.part_planning import choose_base, is_free

    inst, d = _driver(sim_world, "open_drawer")
    part, grid = inst.part, _grid(inst)

    def targets(base, pitch):
        return [handle_pose(part, part.closed, pitch, GRASP_BACK), handle_pose(part, part.closed, pitch)]

    p0 = drawer_pitch(float(part.handle[2]))
    cands = [(dn, dl, 0.0, p0 + dp) for dp in (0.0, math.radians(-10), math.radians(15))
             for dn in (0.72, 0.66, 0.78, 0.60, 0.84) for dl in (0.0, 0.05, -0.05, 0.1, -0.1)]
    base, pitch = choose_base(d, part, grid, cands, targets)
    n, lat, h = np.asarray(part.front, float), lateral(part), np.asarray(part.handle, float)
    face, sgn, blocked = heading(-n), toward_hinge(part), grid.inflate(ROBOT_RADIUS)
    for dn, dl, dyaw, p in cands:
        pt = h + dn * n + dl * lat
        b = (float(pt[0]), float(pt[1]), face + sgn * dyaw)
        if is_free(grid, blocked, b[0], b[1]) and len(ref.reach(d, b, targets(b, p))) == 2:
            assert (b, p) == (base, pitch)
            break
    else:
        pytest.fail("the reference finds no base")
