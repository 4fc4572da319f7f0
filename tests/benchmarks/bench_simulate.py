"""Benchmark: simulate stage overhead vs. a bare Newton scene of the same size.

For each world count: world-steps/s of the furnished demo room + mobile Panda built through
``stages.simulate`` (scene USD via add_usd, robot URDF, drives, base-velocity pre-step kernel),
of the same scene USD and robot URDF loaded straight into Newton and stepped in a plain loop
("direct": the cost of our layer alone), and of a bare Newton scene built with the ModelBuilder
(ground, four walls, as many free boxes as the scene has free bodies, the same robot with the
same drives, no pre-step; "bare": the cost of the furnished scene's content plus our layer), all with the same
solver settings;
plus RGB-D frames/s of one 128x128 camera per world for both (same render settings: shadows on,
no backface culling; ours with the scene's mapped UsdLux lights, bare with one directional light).
ratio = bare / ours (our overhead). MuJoCo-Warp capacities are ours (njmax / nconmax per world as
``stages.simulate.contacts`` sized them for the scene) for all three, so none drops contacts.
Timings are medians of repeats. Writes ``bench_results/simulate.json``.

Run on the GPU machine::

    python tests/benchmarks/bench_simulate.py --device cuda --worlds 1 64 1024 4096
    # or: AGENTWORLD_BENCH_DEVICE=cuda pytest -m benchmark tests/benchmarks/bench_simulate.py

On CPU (default) it runs 1 world (MuJoCo C) and optionally 2-4 (MuJoCo-Warp on CPU).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
SHARED = Path(os.environ.get("AGENTWORLD_SHARED_ASSETS", REPO.parent / "shared" / "assets"))
CLUTTER = 20  # loose objects in the furnished room (the reference scene had 20)


def _sync(device):
    import warp as wp

    wp.synchronize_device(device)


def _time_steps(step, device, n_steps: int, repeats: int) -> float:
    """Median seconds per step."""
    step(5)
    _sync(device)
    out = []
    for _ in range(repeats):
        t = time.perf_counter()
        step(n_steps)
        _sync(device)
        out.append((time.perf_counter() - t) / n_steps)
    return statistics.median(out)


def _ours(device: str, worlds: int, tmp: Path, scene: Path | None = None):
    """The demo room with CLUTTER loose boxes, or ``scene`` (e.g. a composed scene.usda) with the
    robot at a free spawn pose."""
    from stages.simulate.control import RobotControl
    from stages.simulate.demo_scene import write_demo_room
    from stages.simulate.robot import write_robot_urdf
    from stages.simulate.world import SimConfig, build_sim

    if scene is None:
        scene = write_demo_room(
            tmp / "room.usda", shared_assets=SHARED, clutter=CLUTTER, rng=np.random.default_rng(0)
        ).usd
        spawn = (1.0, 1.0, 0.0)
    else:
        spawn = None
    desc = write_robot_urdf(tmp, panda_root=SHARED / "robots/franka_panda__example_robot_data")
    sim = build_sim(
        SimConfig(scenes=(Path(scene),), world_count=worlds, device=device, spawn=spawn),
        desc,
        np.random.default_rng(0),
    )
    ctl = RobotControl(sim)
    ctl.set_base_velocity(0.2, 0.0, 0.1)
    return sim, desc


def _bare(device: str, worlds: int, desc, n_free: int, solver_settings):
    """ModelBuilder only: ground, walls, n_free boxes, the robot URDF; same solver settings."""
    import newton
    import warp as wp

    b = newton.ModelBuilder()
    for cx, cy, hx, hy in (
        (3, -0.05, 3.1, 0.05),
        (3, 5.05, 3.1, 0.05),
        (-0.05, 2.5, 0.05, 2.5),
        (6.05, 2.5, 0.05, 2.5),
    ):
        b.add_shape_box(
            body=-1, xform=wp.transform((cx, cy, 1.25), wp.quat_identity()), hx=hx, hy=hy, hz=1.25
        )
    rng = np.random.default_rng(0)
    for _ in range(n_free):
        body = b.add_body(
            xform=wp.transform((rng.uniform(0.5, 5.5), rng.uniform(1.8, 4.5), 0.1), wp.quat_identity())
        )
        b.add_shape_box(body=body, hx=0.06, hy=0.06, hz=0.06)
    from stages.simulate.robot_load import add_robot

    add_robot(b, desc, spawn_xy_yaw=(1.0, 1.0, 0.0))  # the same drives and gravity compensation
    return _finalize_and_loop(b, device, worlds, solver_settings, ground=True)


def _direct(device: str, worlds: int, desc, scene: Path, spawn, solver_settings):
    """The same scene USD and robot URDF straight into Newton (add_usd, add_urdf, replicate, the
    solver loop): what our layer adds is scene/label bookkeeping, drives and the pre-step."""
    import newton

    b = newton.ModelBuilder()
    newton.solvers.SolverMuJoCo.register_custom_attributes(b)
    b.default_shape_cfg.ke, b.default_shape_cfg.kd = 4.0e4, 400.0
    b.add_usd(str(scene), load_visual_shapes=True, hide_collision_shapes=True)
    from stages.simulate.robot_load import add_robot

    add_robot(b, desc, spawn_xy_yaw=tuple(spawn))
    return _finalize_and_loop(b, device, worlds, solver_settings, ground=False)


def _finalize_and_loop(b, device: str, worlds: int, solver_settings, *, ground: bool):
    import newton

    main = newton.ModelBuilder()
    newton.solvers.SolverMuJoCo.register_custom_attributes(main)
    main.replicate(b, worlds)
    if ground:
        main.add_ground_plane()
    model = main.finalize(device=device)
    from stages.simulate.world import _make_solver

    solver, _, _, _, _ = _make_solver(model, solver_settings, device, worlds)
    s0, s1, ctrl = model.state(), model.state(), model.control()
    newton.eval_fk(model, model.joint_q, model.joint_qd, s0)
    state = {"s0": s0, "s1": s1}
    dt = solver_settings.dt

    def step(n):
        for _ in range(n):
            state["s0"].clear_forces()
            solver.step(state["s0"], state["s1"], ctrl, None, dt)
            state["s0"], state["s1"] = state["s1"], state["s0"]

    return model, step, state


def _render_rate(sensor, model, state, rays, transforms, images, repeats: int) -> float:
    """Median seconds per render of all views."""
    out = []
    for i in range(repeats + 1):
        t = time.perf_counter()
        model.bvh_refit_shapes(state)
        sensor.update(state, transforms, rays, color_image=images[0], forward_depth_image=images[1])
        _sync(model.device)
        if i:
            out.append(time.perf_counter() - t)
    return statistics.median(out)


def run(
    device: str,
    world_counts: list[int],
    *,
    steps: int = 50,
    repeats: int = 3,
    width: int = 128,
    scene: Path | None = None,
) -> dict:
    import tempfile

    import newton
    import warp as wp
    from newton.sensors import SensorCamera

    from stages.simulate.sensors import CameraRig, CameraSpec

    results = {
        "device": device,
        "scene": str(scene) if scene else f"demo room + {CLUTTER} boxes",
        "image": [width, width],
        "rows": [],
    }
    for n in world_counts:
        with tempfile.TemporaryDirectory() as td:
            t0 = time.perf_counter()
            sim, desc = _ours(device, n, Path(td), scene)
            build_s = time.perf_counter() - t0
            ours_dt = _time_steps(sim.step, device, steps, repeats)
            rig = CameraRig(
                sim,
                [CameraSpec(name="head", width=width, height=width, link="head_camera", vertical_fov=1.2)],
                segmentation=False,
            )
            rig.render(to_numpy=False)
            _sync(device)
            rt = []
            for _ in range(repeats):
                t = time.perf_counter()
                rig.render(to_numpy=False)
                _sync(device)
                rt.append(time.perf_counter() - t)
            ours_render = statistics.median(rt)
            # the scene's free bodies (FREE joints) of world 0 become free boxes in the bare scene
            jt = sim.model.joint_type.numpy()
            jw = sim.model.joint_world.numpy()
            n_free = int(np.sum((jt == int(newton.JointType.FREE)) & (jw == 0)))
            sized = dataclasses.replace(sim.solver_settings, njmax=sim.settings.options["njmax"],
                                        nconmax=sim.settings.options["nconmax"])
            _, direct_step, _ = _direct(device, n, desc, Path(sim.settings.scenes[0]), sim.spawn, sized)
            direct_dt = _time_steps(direct_step, device, steps, repeats)
            model, bare_step, bstate = _bare(device, n, desc, n_free, sized)
            bare_dt = _time_steps(bare_step, device, steps, repeats)
            # the same render settings as CameraRig (shadows, both faces), one directional light
            cfg = SensorCamera.RenderConfig(enable_shadows=True, enable_backface_culling=False)
            sensor = SensorCamera(model, load_textures=False, default_render_config=cfg)
            sensor.create_default_light()
            rays = SensorCamera.compute_camera_rays_pinhole(width, width, camera_fov=1.2, device=device)
            tf = wp.array(
                [wp.transform((1.0, 1.0, 1.4), wp.quat_identity())] * n, dtype=wp.transformf, device=device
            )
            imgs = (
                sensor.allocate_image_color(n, width, width),
                sensor.allocate_image_depth_forward(n, width, width),
            )
            bare_render = _render_rate(sensor, model, bstate["s0"], rays, tf, imgs, repeats)
        row = {
            "worlds": n,
            "build_s": round(build_s, 2),
            "ours_world_steps_per_s": n / ours_dt,
            "bare_world_steps_per_s": n / bare_dt,
            "step_ratio_bare_over_ours": (n / bare_dt) / (n / ours_dt),
            "direct_world_steps_per_s": n / direct_dt,
            "step_ratio_direct_over_ours": ours_dt / direct_dt,
            "ours_rgbd_frames_per_s": n / ours_render,
            "bare_rgbd_frames_per_s": n / bare_render,
            "render_ratio_bare_over_ours": ours_render / bare_render,
            "bodies_per_world": sim.bodies_per_world,
            "shapes_per_world": sim.shapes_per_world,
            "settings": sim.settings.to_json(),
        }
        print(
            f"[simulate] {device} worlds={n}: ours {row['ours_world_steps_per_s']:.0f} world-steps/s, "
            f"direct {row['direct_world_steps_per_s']:.0f} (ratio {row['step_ratio_direct_over_ours']:.2f}), "
            f"bare {row['bare_world_steps_per_s']:.0f} (ratio {row['step_ratio_bare_over_ours']:.2f}); "
            f"RGB-D ours {row['ours_rgbd_frames_per_s']:.0f} frames/s, "
            f"bare {row['bare_rgbd_frames_per_s']:.0f}"
        )
        results["rows"].append(row)
    out = REPO / "bench_results" / "simulate.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(results, indent=2, default=str))
    return results


@pytest.mark.benchmark
def test_bench_simulate(shared_assets):
    device = os.environ.get("AGENTWORLD_BENCH_DEVICE", "cpu")
    counts = [1] if device == "cpu" else [1, 64, 1024, 4096]
    res = run(device, counts)
    for row in res["rows"]:
        assert row["ours_world_steps_per_s"] > 0 and row["bare_world_steps_per_s"] > 0
        assert row["ours_rgbd_frames_per_s"] > 0


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--worlds", type=int, nargs="+", default=None)
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--scene", type=Path, default=None, help="a scene USD (default: the demo room)")
    a = ap.parse_args()
    sys.path.insert(0, str(REPO))
    run(
        a.device,
        a.worlds or ([1] if a.device == "cpu" else [1, 64, 1024, 4096]),
        steps=a.steps,
        scene=a.scene,
    )
