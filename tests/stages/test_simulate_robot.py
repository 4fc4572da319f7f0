"""The mobile Panda description: Newton and Pinocchio agree; CLIK reaches poses."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("newton")
pytest.importorskip("pinocchio")

from stages.simulate.control import Clik, pose, top_down  # noqa: E402
from stages.simulate.robot import GripperKind, write_robot_urdf  # noqa: E402
from stages.simulate.robot_load import add_robot, build_pinocchio_model  # noqa: E402

PANDA = "robots/franka_panda__example_robot_data"
ROBOTIQ = "robots/robotiq_2f85__menagerie"


@pytest.fixture(scope="module", params=[GripperKind.PANDA_HAND, GripperKind.ROBOTIQ_2F85])
def desc(request, shared_assets, tmp_path_factory):
    return write_robot_urdf(
        tmp_path_factory.mktemp("robot"),
        gripper=request.param,
        panda_root=shared_assets / PANDA,
        robotiq_root=shared_assets / ROBOTIQ,
    )


def _matrix(t):
    from scipy.spatial.transform import Rotation

    m = np.eye(4)
    m[:3, :3] = Rotation.from_quat(t[3:7]).as_matrix()
    m[:3, 3] = t[:3]
    return m


def test_newton_and_pinocchio_forward_kinematics_agree(desc):
    import newton
    import pinocchio as pin
    import warp as wp

    spawn = (1.0, -2.0, 0.7)
    b = newton.ModelBuilder()
    idx = add_robot(b, desc, spawn_xy_yaw=spawn)
    model = b.finalize(device="cpu")
    pm = build_pinocchio_model(desc)
    pd = pm.createData()
    assert set(desc.joints) <= set(pm.names)
    c, s = np.cos(spawn[2]), np.sin(spawn[2])
    t_spawn = np.array([[c, -s, 0, spawn[0]], [s, c, 0, spawn[1]], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    rng = np.random.default_rng(3)
    worst = 0.0
    for _ in range(5):
        q = rng.uniform(np.maximum(pm.lowerPositionLimit, -2), np.minimum(pm.upperPositionLimit, 2))
        jq = model.joint_q.numpy()
        for i in range(1, pm.njoints):
            jq[idx.coord[pm.names[i]]] = q[pm.joints[i].idx_q]
        state = model.state()
        newton.eval_fk(model, wp.array(jq, dtype=float, device="cpu"), model.joint_qd, state)
        bq = state.body_q.numpy()
        pin.framesForwardKinematics(pm, pd, q)
        for link, body in idx.body.items():
            diff = _matrix(bq[body]) - t_spawn @ pd.oMf[pm.getFrameId(link)].homogeneous
            worst = max(worst, float(np.abs(diff).max()))
    assert len(idx.body) >= 18
    assert worst < 1e-5, f"Newton and Pinocchio disagree by {worst}"


def test_clik_reaches_20_random_reachable_poses(desc):
    """Targets are the forward kinematics of random in-limit arm configurations (so reachable);
    CLIK starts from the home pose and must land within 5 mm and 2 degrees, inside the limits."""
    ik = Clik(desc)
    rng = np.random.default_rng(7)
    q_home = ik.neutral()
    lo, hi = ik.lower, ik.upper
    arm_idx = [ik.q_idx[n] for n in desc.arm_joints]
    reached = 0
    for _ in range(20):
        q_goal = q_home.copy()
        q_goal[arm_idx] = rng.uniform(lo[arm_idx] * 0.8, hi[arm_idx] * 0.8) * 0.6 + q_home[arm_idx] * 0.4
        target = ik.fk(q_goal)
        res = ik.solve(target, q_home, max_iters=400, restarts=5, rng=rng)
        assert np.all(res.q >= lo - 1e-9) and np.all(res.q <= hi + 1e-9)
        if res.position_error < 0.005 and np.rad2deg(res.rotation_error) < 2.0:
            reached += 1
    assert reached == 20


def test_clik_top_down_grasp_pose_in_front_of_the_base(desc):
    ik = Clik(desc)
    target = pose((0.65, 0.1, 0.35), top_down(0.3))
    res = ik.solve(target, ik.neutral())
    assert res.success and res.position_error < 1e-3
    np.testing.assert_allclose(ik.fk(res.q)[:3, 3], target[:3, 3], atol=1e-3)


def test_missing_panda_description_names_what_was_tried(tmp_path):
    from pipeline.types import ItemError

    with pytest.raises(ItemError, match="Panda description not found"):
        write_robot_urdf(tmp_path, panda_root=tmp_path / "nowhere")


def test_solver_settings_refuse_long_explicit_steps():
    from pipeline.types import ItemError
    from stages.simulate.world import SolverKind, SolverSettings

    with pytest.raises(ItemError, match="substeps >= 8"):
        SolverSettings(kind=SolverKind.FEATHERSTONE, dt=1 / 120, substeps=1)
    ok = SolverSettings(kind=SolverKind.XPBD, dt=1 / 120, substeps=8)
    assert ok.dt / ok.substeps <= 1 / 960
    assert SolverSettings().kind == SolverKind.MUJOCO and SolverSettings().substeps == 1


def test_default_description_is_the_pip_package(shared_assets, tmp_path):
    """Without a folder the Panda comes from the pip package example-robot-data; its kinematics
    equal the shared assets' copy."""
    from importlib import metadata

    try:
        metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        pytest.skip("example-robot-data is not installed")
    default = write_robot_urdf(tmp_path / "pip")
    shared = write_robot_urdf(tmp_path / "shared", panda_root=shared_assets / PANDA)
    assert "cmeel.prefix" in default.urdf.read_text() or "site-packages" in default.urdf.read_text()
    a, b = Clik(default), Clik(shared)
    q = a.neutral()
    np.testing.assert_allclose(a.fk(q), b.fk(q), atol=1e-9)
