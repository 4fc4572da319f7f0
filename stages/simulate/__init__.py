"""Simulate stage: scenes in Newton with a mobile manipulator, IK and cameras.

Public API (heavy imports happen inside the modules' functions; importing this package loads
neither warp nor newton)::

    from stages.simulate.robot import write_robot_urdf, GripperKind
    from stages.simulate.world import SimConfig, SolverSettings, build_sim
    from stages.simulate.control import RobotControl, Clik, move_ee, pose, top_down
    from stages.simulate.sensors import CameraRig, CameraSpec, robot_cameras, look_at
    from stages.simulate.state import read_state
    from stages.simulate.record import UsdRecorder

    desc = write_robot_urdf(out_dir, gripper="panda_hand", panda_root=None)  # pip example-robot-data
    sim = build_sim(SimConfig(scenes=(scene_usd,), world_count=1, device="cpu"), desc, rng)
    ctl = RobotControl(sim)                      # base velocity, arm targets, gripper 0..1
    ctl.set_base_velocity(0.3, 0.0, 0.0)         # (vx, vy, v_theta) in the base frame
    sim.step(100)                                # 100 x settings.dt
    st = read_state(sim, contacts=True)          # joints, EE pose, base (x, y, theta), objects
    rig = CameraRig(sim, robot_cameras(desc) + [CameraSpec(name="third", pose=look_at(eye, target))])
    frames = rig.render()                        # rgb, depth, shape index; labels via frames[n].labels(...)
    ik = Clik(desc); move_ee(sim, ctl, ik, pose(p, top_down()), duration=1.0)

Modules: ``robot`` (the embodiment URDF), ``robot_load`` (its loading into Newton and Pinocchio), ``world``
(scene loading, free spawn, replication, solver, stepping), ``control`` (drives, CLIK),
``sensors`` (cameras, lights), ``state`` (typed per-step state), ``record`` (USD recording),
``demo_scene`` (a furnished room authored as USD, for tests and benchmarks).
"""
