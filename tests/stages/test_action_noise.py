"""DART action noise (stages/engine/action_noise.py) on the batched engine, CPU, one kitchen.

The robot executes the expert's command plus a held random offset while the frames record the
clean command: recorded arm targets equal the clean ones at every upload, the uploaded targets
are the clean ones plus the offset (clipped), and the measured arm follows the offset. Noise off
(or zero noise) records the same frames as an engine without the config, and the same seed records
the same episode, alone or beside another world. Episodes are push_object's first 2 s (the arm
tucks while the base sets off: with ``mode_aware`` off, arm noise acts from the first step).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from stages.engine.action_noise import ActionNoise, NoiseProcess

EPISODE = ("push_object", 1, 2.0)  # task, seed, time limit [s]
ARM_ONLY = ActionNoise(arm_std=0.02, base_std=(0.0, 0.0, 0.0), hold_seconds=0.3, mode_aware=False)


@pytest.fixture(scope="module")
def room(kitchen_room):
    pytest.importorskip("newton")
    pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")
    return kitchen_room


def _run(room, work: Path, noise: ActionNoise | None, queues: dict[int, list] | None = None, *,
         layout: str = "auto", program_procs: int = 0, steady: tuple[int, int] | None = None) -> dict:
    """Run ``queues`` (world -> [(task, seed, limit)]; default EPISODE in one world) without images;
    per (task, seed): frames, result, and the arm targets uploaded to the simulation at each frame
    step (what the next steps execute), read in a pre-step hook after the controller's upload.
    ``steady`` (first, last) frames: the expert's commands ask for no noise between them
    (``Commands.steady``, set by the hook as an expert would; programs in threads)."""
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    queues = queues or {0: [EPISODE]}
    eng = BatchEngine(room, panda_root=None, work_dir=work,
                      config=EngineConfig(worlds=len(queues), record_images=False, action_noise=noise,
                                          layout=layout, program_procs=program_procs))
    out: dict = {}
    uploads: dict[int, dict[int, np.ndarray]] = {w: {} for w in queues}
    for w, (bank, i) in enumerate(eng._where):
        ctl = bank.ctl
        arm = ctl._at(ctl._arm_idx, i)

        def hook(sim, w=w, arm=arm):
            step = int(eng.steps[w])
            if uploads[w] and step < max(uploads[w]):  # the world was reset: a new episode
                uploads[w].clear()
            uploads[w].setdefault(step, sim.control.joint_target_q.numpy()[arm].copy())
            if steady is not None:
                eng.side.cmds[w].steady = steady[0] <= step * eng.config.fps / eng.steps_per_second < steady[1]

        bank.sim.pre_step.append(hook)

    def begin(w, inst):
        rec = out[(inst.task, inst.seed)] = {"frames": []}
        return rec["frames"].append

    def end(w, inst, res):
        rec = out[(inst.task, inst.seed)]
        rec["result"] = res
        S = eng.steps_per_second
        steps = [-(-k * S // eng.config.fps) for k in range(len(rec["frames"]))]  # frame k's step
        rec["uploaded"] = np.array([uploads[w][s] for s in steps])

    eng.run(Listed(room, queues), begin=begin, end=end)
    return out


def _field(frames, name: str) -> np.ndarray:
    return np.array([getattr(f, name) for f in frames], float)


@pytest.fixture(scope="module")
def runs(room, tmp_path_factory) -> dict:
    """EPISODE without the config, with zero noise and twice with ARM_ONLY noise (~10 s)."""
    d = tmp_path_factory.mktemp("action_noise")
    key = EPISODE[:2]
    return {name: _run(room, d / name, noise)[key] for name, noise in
            (("none", None), ("zero", ActionNoise(arm_std=0.0, base_std=(0.0, 0.0, 0.0))),
             ("noisy", ARM_ONLY), ("noisy_again", ARM_ONLY))}


def _assert_same(a: dict, b: dict) -> None:
    ra, rb = a["result"], b["result"]
    assert ((ra.success, ra.reason, ra.frames, ra.sim_seconds)
            == (rb.success, rb.reason, rb.frames, rb.sim_seconds))
    assert len(a["frames"]) == len(b["frames"]) > 30
    for i, (x, y) in enumerate(zip(a["frames"], b["frames"], strict=True)):
        np.testing.assert_array_equal(x.state(), y.state(), err_msg=f"frame {i} state")
        np.testing.assert_array_equal(x.action(), y.action(), err_msg=f"frame {i} action")


def test_the_robot_executes_noise_while_the_frames_record_the_clean_command(runs):
    clean, noisy = runs["none"], runs["noisy"]
    assert len(noisy["frames"]) == len(clean["frames"]) == 61  # 2 s at 30 fps, frame 0 included
    rec = _field(noisy["frames"], "arm_joint_target")
    # the recorded action is the expert's command: here (the tuck is open loop in joint space) the
    # same targets the noise-free run records, while the uploaded targets are off by the noise
    np.testing.assert_array_equal(rec, _field(clean["frames"], "arm_joint_target"))
    np.testing.assert_array_equal(clean["uploaded"], rec.astype(np.float32))
    off = noisy["uploaded"] - rec
    assert (np.abs(off).max(axis=1) > 1e-3).all(), "every frame executes an offset"
    assert 0.01 < np.abs(off).mean() < 0.03 and np.abs(off).max() < 0.12  # N(0, 0.02 rad) per joint
    # a draw is held 0.3 s = 9 or 10 frames: at most 7 distinct offsets in 61 frames
    assert 5 <= len({tuple(np.round(o, 6)) for o in off}) <= 7
    # the measured arm follows target + offset: the noisy run's joints minus the clean run's track
    # the offset uploaded one frame earlier
    dq = _field(noisy["frames"], "arm_joint_pos") - _field(clean["frames"], "arm_joint_pos")
    a, b = dq[1:], off[:-1]
    assert np.corrcoef(a.ravel(), b.ravel())[0, 1] > 0.85
    assert np.abs(a - b).mean() < 0.4 * np.abs(b).mean()


def test_a_steady_expert_executes_its_commands_without_noise_and_the_draws_go_on(room, runs, tmp_path):
    # the expert asks for no noise over frames 20-40 (the drawer's grasp does, Driver.steady): the
    # uploads there are the clean commands; before and after, the noisy run's own (the draws in order)
    key = EPISODE[:2]
    quiet = _run(room, tmp_path, ARM_ONLY, steady=(20, 40))[key]
    noisy, clean = runs["noisy"], runs["none"]
    assert len(quiet["frames"]) == len(noisy["frames"]) == 61
    rec = _field(quiet["frames"], "arm_joint_target")
    np.testing.assert_array_equal(rec, _field(clean["frames"], "arm_joint_target"))
    off = quiet["uploaded"] - rec
    assert np.abs(off[22:38]).max() < 1e-6, "no noise while steady"
    assert (np.abs(off[:19]).max(axis=1) > 1e-3).all() and (np.abs(off[42:]).max(axis=1) > 1e-3).all()
    np.testing.assert_array_equal(quiet["uploaded"][:19], noisy["uploaded"][:19])
    np.testing.assert_array_equal(off[45:], (noisy["uploaded"] - rec)[45:])


def test_base_noise_stays_off_within_the_quiet_radius_of_the_drive_stop(room, tmp_path):
    # base DART with base_quiet_radius: per physics step, the base offset in force is zero while the
    # expert's base is within the radius of its path's end (Commands.stop_distance, set by
    # Driver.follow) and drawn (nonzero while driving) farther out
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    radius = 0.6
    noise = ActionNoise(arm_std=0.0, base_std=(0.1, 0.1, 0.15), hold_seconds=0.1, base_quiet_radius=radius)
    eng = BatchEngine(room, panda_root=None, work_dir=tmp_path,
                      config=EngineConfig(worlds=1, record_images=False, action_noise=noise))
    bank, i = eng._where[0]
    seen: list[tuple[float, bool, bool]] = []  # (stop distance [m], driving, base offset nonzero)

    def hook(sim):
        cmd = eng.side.cmds[0]
        seen.append((float(cmd.stop_distance), cmd.mode == 0 and bool(np.any(cmd.base_velocity != 0)),
                     bool(np.any(bank.ctl._base_off[i] != 0))))

    bank.sim.pre_step.append(hook)
    eng.run(Listed(room, {0: [("push_object", 1, 8.0)]}), begin=lambda w, inst: (lambda f: None),
            end=lambda w, inst, res: None)
    d = np.array([x[0] for x in seen])
    driving, offset = np.array([x[1] for x in seen]), np.array([x[2] for x in seen])
    near, far = driving & (d < radius), driving & (d >= radius) & np.isfinite(d)
    assert near.sum() > 100 and far.sum() > 100, (near.sum(), far.sum())
    assert not offset[np.isinf(d)].any(), "no base noise outside a drive"
    assert not offset[d < radius].any(), "no base noise near the stop"
    assert offset[far].mean() > 0.95, "base noise on the drive farther out"
    with pytest.raises(ValueError, match="base_quiet_radius"):
        ActionNoise(base_quiet_radius=-0.1)


def test_noise_off_and_zero_noise_record_the_frames_of_an_engine_without_noise(runs):
    _assert_same(runs["none"], runs["zero"])
    np.testing.assert_array_equal(runs["none"]["uploaded"], runs["zero"]["uploaded"])


def test_the_same_seed_records_the_same_noisy_episode(runs):
    _assert_same(runs["noisy"], runs["noisy_again"])
    np.testing.assert_array_equal(runs["noisy"]["uploaded"], runs["noisy_again"]["uploaded"])


def test_a_noisy_episode_is_the_same_beside_another_world(room, runs, tmp_path):
    # world 1 runs EPISODE after a short one (it starts at a later sync point) while world 0 runs
    # another noisy episode: the two worlds' redraws fall on different steps
    queues = {0: [("push_object", 7, 1.5)], 1: [("press_button", 3, 0.1), EPISODE]}
    two = _run(room, tmp_path, ARM_ONLY, queues)
    _assert_same(runs["noisy"], two[EPISODE[:2]])
    np.testing.assert_array_equal(runs["noisy"]["uploaded"], two[EPISODE[:2]]["uploaded"])


def test_noise_in_one_batched_model_is_the_same_with_programs_in_worker_processes(room, tmp_path):
    # MuJoCo-Warp's batched layout (the GPU's), the experts in threads and in a worker process
    # (commands in shared memory, events over pipes): the same noisy recordings, noise applied
    queues = {0: [("push_object", 7, 0.6)], 1: [("press_button", 3, 0.1), ("push_object", 1, 0.6)]}
    threads = _run(room, tmp_path / "t", ARM_ONLY, queues, layout="batched")
    procs = _run(room, tmp_path / "p", ARM_ONLY, queues, layout="batched", program_procs=1)
    assert threads.keys() == procs.keys() and len(threads) == 3
    for key, a in threads.items():
        b = procs[key]
        assert len(a["frames"]) == len(b["frames"]) and a["result"].reason == b["result"].reason
        for x, y in zip(a["frames"], b["frames"], strict=True):  # one model: contacts may reorder sums
            np.testing.assert_allclose(x.state(), y.state(), rtol=0, atol=1e-5, err_msg=str(key))
            np.testing.assert_allclose(x.action(), y.action(), rtol=0, atol=1e-5, err_msg=str(key))
        np.testing.assert_allclose(a["uploaded"], b["uploaded"], rtol=0, atol=1e-5, err_msg=str(key))
        off = a["uploaded"] - _field(a["frames"], "arm_joint_target")
        assert (np.abs(off).max(axis=1) > 1e-3).all(), key


def test_noise_process_holds_draws_gates_by_mode_and_seeds_by_episode():
    cfg = ActionNoise(arm_std=0.02, base_std=(0.05, 0.05, 0.1), hold_seconds=0.3)
    p, q = NoiseProcess(cfg, 2, 500), NoiseProcess(cfg, 2, 500)
    assert p.hold_steps == 150 and p.steps_to_redraw(0) == 150 and p.steps_to_redraw(149) == 1
    p.begin(0, "push_object", 1)
    q.begin(1, "push_object", 1)
    drive = np.array([0.3, 0.0, 0.0])
    a0, b0 = p.offsets(0, 0, 0, drive)
    assert not a0.any() and b0.any()  # driving: base noise only
    a1, b1 = p.offsets(0, 149, 1, np.zeros(3))
    assert a1.any() and not b1.any()  # manipulation: arm noise only, the same draw
    a2, _ = p.offsets(0, 150, 1, np.zeros(3))
    assert not np.array_equal(a1, a2)  # redrawn after 0.3 s
    # the same (task, seed) gives the same draws in any world; another seed or task others
    np.testing.assert_array_equal(q.offsets(1, 150, 1, np.zeros(3))[0], a2)
    q.begin(1, "push_object", 2)
    assert not np.array_equal(q.offsets(1, 0, 1, np.zeros(3))[0], a1)
    p.end(0)
    assert not any(x.any() for x in p.offsets(0, 300, 1, drive))
    with pytest.raises(ValueError, match="hold_seconds"):
        ActionNoise(hold_seconds=0.0)
    with pytest.raises(ValueError, match="finite and >= 0"):
        ActionNoise(base_std=(0.05, -0.1, 0.0))


def test_the_demos_job_validates_action_noise_naming_the_job_file(tmp_path):
    from pipeline import JobError, load_job

    job = tmp_path / "dart.toml"
    head = ('[job]\nname = "j"\n[[step]]\nname = "demos"\nkind = "demos"\n[step.config]\n'
            'tasks = ["push_object"]\n[step.config.action_noise]\n')
    job.write_text(head + "arm_std = 0.01\nbase_std = [0.02, 0.02, 0.05]\nhold_seconds = 0.5\n")
    noise = load_job(job).steps[0].config.action_noise
    assert noise.engine() == ActionNoise(arm_std=0.01, base_std=(0.02, 0.02, 0.05), hold_seconds=0.5)
    job.write_text(head + "arm_std = -0.01\nhold_seconds = 0\n")
    both = r"dart\.toml: .*action_noise\.arm_std.*action_noise\.hold_seconds"
    with pytest.raises(JobError, match=both) as e:
        load_job(job)
    assert "\n" not in str(e.value)


@pytest.mark.parametrize("mixed", [False, True])
def test_the_demos_items_carry_the_noise_to_their_engines(kitchen_catalog, tmp_path, mixed):
    from pipeline import load_results
    from pipeline.types import PlanContext
    from stages.demos.job import DemosConfig, plan_demos
    from stages.demos.mixed import ActionNoiseSpec

    prev = {s: load_results(kitchen_catalog, s) for s in ("catalog", "assets")}
    ctx = PlanContext(job_file=tmp_path / "job.toml", job_dir=tmp_path, work_dir=kitchen_catalog, seed=0,
                      previous=prev)
    spec = ActionNoiseSpec(arm_std=0.01, base_std=(0.1, 0.1, 0.15), hold_seconds=0.3)
    for noise in (None, spec):
        items = plan_demos(DemosConfig(tasks=("push_object",), mixed=mixed, action_noise=noise), ctx)
        assert len(items) == 1 and items[0].params.action_noise == noise
    assert items[0].params.action_noise.engine() == ActionNoise(arm_std=0.01, base_std=(0.1, 0.1, 0.15))
