"""The batched demonstration engine on CPU: worlds run episodes independently, and each recorded
episode equals a single-world replay of the same instance (state, action and camera frames).

Two layouts: ``per_world`` (one MuJoCo C model per world, the CPU default) with 4 worlds and five
episodes of four tasks, world 0 running two in a row (its second episode starts from a reset while
the others keep running); and ``batched`` (one MuJoCo-Warp model of several worlds, the GPU layout)
with 2 worlds, world 1 reset to a new episode while world 0 is mid-episode. Episodes are cut short
by time limits (the experts are mid-motion when they stop: driving, reaching), so the comparison
covers driving, arm motion and the resets at CPU cost.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest


@pytest.fixture(scope="module")
def room(kitchen_room):
    """The kitchen of world seed 5 from the session's kitchen catalog (tests/stages/conftest.py)."""
    pytest.importorskip("newton")
    pytest.importorskip("newton_usd_schemas", reason="Newton's USD importer needs newton-usd-schemas")
    return kitchen_room


def _run(room, work: Path, layout: str, queues: dict[int, list], program_procs: int = 0, *,
         program_wait: float | None = None, program_yield: float | None = 0.002, hold_policy=None,
         stats_out: list | None = None) -> dict:
    """Run an engine of len(queues) worlds; queues: world -> [(task, seed, max_seconds)].
    Returns (task, seed) -> dict(frames=[...], result=EpisodeResult, world=w)."""
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    eng = BatchEngine(room, panda_root=None, work_dir=work,
                      config=EngineConfig(worlds=len(queues), width=64, height=48, layout=layout,
                                          program_procs=program_procs, program_wait=program_wait,
                                          program_yield=program_yield))
    eng.hold_policy = hold_policy
    out: dict = {}

    def begin(w, inst):
        rec = out[(inst.task, inst.seed)] = {"frames": [], "world": w}
        return rec["frames"].append

    def end(w, inst, res):
        out[(inst.task, inst.seed)]["result"] = res

    stats = eng.run(Listed(room, queues), begin=begin, end=end)
    assert stats.episodes == sum(len(q) for q in queues.values())
    if stats_out is not None:
        stats_out.append(stats)
    return out


# two worlds of one MuJoCo-Warp model: world 1 ends an episode at 0.1 s and is reset (at the next
# sync point, 0.2 s) to a new one while world 0 is mid-episode until 0.4 s
TWO_WORLDS = {0: [("press_button", 3, 0.4)], 1: [("push_object", 5, 0.1), ("press_button", 6, 0.2)]}


@pytest.fixture(scope="module")
def batched_two(room, tmp_path_factory) -> dict:
    """TWO_WORLDS run once in the ``batched`` layout, programs in threads, no holds: the reference
    of the reset, worker-process and hold tests (the engine is deterministic)."""
    return _run(room, tmp_path_factory.mktemp("batched_two"), "batched", TWO_WORLDS)


def _assert_same_episode(a: dict, b: dict, key, *, exact_images: bool = True) -> None:
    """Same result, state and action; images equal. With ``exact_images`` False (one batched model):
    state and action within 1e-5 (MuJoCo-Warp keeps all worlds' contacts in one buffer, and another
    world's reset can reorder them: float sums then differ in the last bit) and images within
    1 mm / 2 levels on at most 0.2% of the pixels (the ray tracer's BVH spans all worlds)."""
    fa, fb = a["frames"], b["frames"]
    assert len(fa) == len(fb) > 0, key
    ra, rb = a["result"], b["result"]
    assert (ra.success, ra.reason, ra.frames, ra.sim_seconds) == (rb.success, rb.reason, rb.frames, rb.sim_seconds)
    for i, (x, y) in enumerate(zip(fa, fb, strict=True)):
        tol = 0.0 if exact_images else 1e-5
        np.testing.assert_allclose(x.state(), y.state(), rtol=0, atol=tol, err_msg=f"{key} frame {i} state")
        np.testing.assert_allclose(x.action(), y.action(), rtol=0, atol=tol, err_msg=f"{key} frame {i} action")
        for cam in x.rgb:
            if exact_images:
                np.testing.assert_array_equal(x.rgb[cam], y.rgb[cam], err_msg=f"{key} frame {i} {cam}")
                np.testing.assert_array_equal(x.depth_mm[cam], y.depth_mm[cam], err_msg=f"{key} frame {i} {cam}")
                continue
            for im_a, im_b, tol in ((x.rgb[cam], y.rgb[cam], 2), (x.depth_mm[cam], y.depth_mm[cam], 1)):
                diff = np.abs(im_a.astype(np.int32) - im_b.astype(np.int32))
                assert diff.max() <= tol and (diff > 0).mean() <= 0.002, (key, i, cam, diff.max())


def test_four_worlds_record_what_single_world_replays_record(room, tmp_path):
    # world 0's second episode starts from a reset (at about 0.6 s) while world 1 runs on to 1.0 s
    queues = {0: [("press_button", 3, 0.6), ("pick_place_bowl", 8, 0.5)],
              1: [("pick_place_bowl", 4, 1.0)],
              2: [("push_object", 5, 0.7)],
              3: [("press_button", 6, 0.4)]}
    batched = _run(room, tmp_path / "b", "per_world", queues)
    assert {k: v["world"] for k, v in batched.items()} == {
        ("press_button", 3): 0, ("pick_place_bowl", 8): 0, ("pick_place_bowl", 4): 1,
        ("push_object", 5): 2, ("press_button", 6): 3}
    # every episode ran to its own time limit, frames at 30 fps from its own reset
    for (task, seed), rec in batched.items():
        limit = next(lim for q in queues.values() for t, s, lim in q if (t, s) == (task, seed))
        assert rec["result"].reason == "timeout" and len(rec["frames"]) == int(limit * 30) + 1
        assert rec["frames"][0].rgb["head"].shape == (48, 64, 3)
    # the robot moved (the comparison is not of idle worlds)
    moved = [np.abs(r["frames"][-1].state() - r["frames"][0].state()).max() for r in batched.values()]
    assert min(moved) > 0.01
    # single-world replays, each episode alone in a fresh engine's one world
    for key in batched:
        lim = next(lim for q in queues.values() for t, s, lim in q if (t, s) == key)
        single = _run(room, tmp_path / f"s_{key[0]}_{key[1]}", "per_world", {0: [(*key, lim)]})
        _assert_same_episode(batched[key], single[key], key)


def test_a_world_reset_mid_run_leaves_the_other_world_of_a_batched_model_untouched(room, batched_two,
                                                                                   tmp_path):
    # TWO_WORLDS: world 1 is reset to a new episode at 0.2 s while world 0 is mid-episode until 0.4 s
    batched = batched_two
    alone_0 = _run(room, tmp_path / "s0", "batched", {0: [("press_button", 3, 0.4)]})
    alone_1 = _run(room, tmp_path / "s1", "batched", {0: [("press_button", 6, 0.2)]})
    _assert_same_episode(batched[("press_button", 3)], alone_0[("press_button", 3)], "world 0",
                         exact_images=False)
    _assert_same_episode(batched[("press_button", 6)], alone_1[("press_button", 6)], "world 1 after reset",
                         exact_images=False)
    assert np.abs(batched[("press_button", 3)]["frames"][-1].state()
                  - batched[("press_button", 3)]["frames"][0].state()).max() > 0.01


def test_world_programs_in_worker_processes_record_what_threads_record(room, batched_two, tmp_path):
    # the experts run in 2 worker processes (shared-memory state and commands); same episodes
    threads = batched_two
    procs = _run(room, tmp_path / "p", "batched", TWO_WORLDS, program_procs=2)
    assert set(threads) == set(procs)
    for key in threads:
        _assert_same_episode(threads[key], procs[key], key)


@pytest.mark.parametrize("layout", ["per_world", "batched"])
def test_held_worlds_record_what_unheld_worlds_record(room, batched_two, tmp_path, layout):
    # a world held while its program "plans" (here: held by a fixed policy for 1-3 sync periods at
    # chosen requests) stands still while the other steps on; its episode is unchanged
    plan = {(0, 2): 1, (0, 5): 3, (1, 3): 2}
    stats: list = []
    held = _run(room, tmp_path / "h", layout, TWO_WORLDS, hold_policy=lambda w, k: plan.get((w, k), 0),
                stats_out=stats)
    free = batched_two if layout == "batched" else _run(room, tmp_path / "f", layout, TWO_WORLDS)
    assert stats[0].holds == 3 and stats[0].held_steps >= 6 * 50  # 6 sync periods of 50 steps
    assert set(held) == set(free)
    for key in free:
        _assert_same_episode(held[key], free[key], key, exact_images=layout == "per_world")


@pytest.mark.slow  # 40 s on 2 cores; CI keeps test_world_programs_in_worker_processes_record_what_threads_record
def test_late_programs_in_worker_processes_are_held_and_record_what_threads_record(room, batched_two,
                                                                                   tmp_path):
    # program_wait=0: every world whose program has not answered at once is held until it has
    threads = batched_two
    stats: list = []
    procs = _run(room, tmp_path / "p", "batched", TWO_WORLDS, program_procs=2, program_wait=0.0,
                 stats_out=stats)
    assert stats[0].holds > 0
    assert set(threads) == set(procs)
    for key in threads:
        _assert_same_episode(threads[key], procs[key], key, exact_images=False)


@pytest.mark.slow  # 19 s on 2 cores; CI keeps test_held_worlds_record_what_unheld_worlds_record
def test_planning_programs_parked_at_checkpoints_are_held_at_once_and_record_what_threads_record(
        room, batched_two, tmp_path):
    # one worker runs both worlds' programs; program_yield=0 parks a program at its first
    # checkpoint (an IK solve, a path search) of every resume: the worker tells the engine, which
    # holds that world without waiting (program_wait 30 s would otherwise wait for it), and runs
    # the other world's request before it goes on with the parked one; episodes are unchanged
    threads = batched_two
    stats: list = []
    procs = _run(room, tmp_path / "p", "batched", TWO_WORLDS, program_procs=1, program_wait=30.0,
                 program_yield=0.0, stats_out=stats)
    assert stats[0].yields > 0 and stats[0].holds >= stats[0].yields
    assert set(threads) == set(procs)
    for key in threads:
        _assert_same_episode(threads[key], procs[key], key, exact_images=False)


def test_compact_readback_equals_the_host_conversion(room, tmp_path):
    # the engine records RGB and depth converted on the device; they equal render() + depth_m_to_mm
    from stages.dataset import depth_m_to_mm
    from stages.engine import BatchEngine, EngineConfig

    eng = BatchEngine(room, panda_root=None, work_dir=tmp_path,
                      config=EngineConfig(worlds=2, width=64, height=48, layout="batched"))
    rig = eng.banks[0].rig
    full, compact = rig.render(), rig.render_compact()
    assert set(full) == set(compact) == {"wrist", "head", "third_person"}
    for name, fr in full.items():
        rgb, mm = compact[name]
        assert rgb.shape == (2, 48, 64, 3) and mm.shape == (2, 48, 64) and mm.dtype == np.uint16
        np.testing.assert_array_equal(rgb, fr.rgb)
        np.testing.assert_array_equal(mm, depth_m_to_mm(fr.depth))
        assert (mm > 0).mean() > 0.5 and rgb.std() > 5  # real images, not blank


def test_lockstep_resumes_worlds_in_order_and_counts_steps():
    from stages.engine import Lockstep

    ls = Lockstep(3)
    log: list[tuple[int, int]] = []
    clock = {"step": 0}

    def program(w: int, waits: list[int]):
        def main():
            for n in waits:
                log.append((w, clock["step"]))
                ls.wait_steps(w, n)
            log.append((w, clock["step"]))
        return main

    plans = {0: [5, 5], 1: [3], 2: [7, 1]}
    for w, waits in plans.items():
        ls.start(w, program(w, waits))
    while ls.alive():
        ls.resume_ready()
        k = ls.min_pending()
        if k is None:
            break
        clock["step"] += k
        ls.advance(k)
    ls.shutdown()
    # each world resumed exactly when its requested steps had run
    assert [e for e in log if e[0] == 0] == [(0, 0), (0, 5), (0, 10)]
    assert [e for e in log if e[0] == 1] == [(1, 0), (1, 3)]
    assert [e for e in log if e[0] == 2] == [(2, 0), (2, 7), (2, 8)]
    # at one step, worlds resume in world order
    assert log[:3] == [(0, 0), (1, 0), (2, 0)]


def test_a_program_parks_at_a_checkpoint_only_when_its_scheduler_says_so_and_goes_on_from_there():
    from stages.engine import Lockstep
    from stages.simulate.cooperative import checkpoint

    trace: list = []

    def program(w):
        def fn():
            trace.append((w, "plan"))
            checkpoint()
            trace.append((w, "planned"))
            ls.wait_steps(w, 3)
            trace.append((w, "stepped"))
        return fn

    ls = Lockstep(2, yield_check=lambda w, seconds: w == 0 and seconds >= 0.0)
    for w in (0, 1):
        ls.start(w, program(w))
    ls._resume(0)  # world 0 parks at its checkpoint, mid-computation; world 1 runs meanwhile
    assert ls.slots[0].busy and trace == [(0, "plan")]
    ls._resume(1)
    assert not ls.slots[1].busy and ls.pending(1) == 3 and trace[-1] == (1, "planned")
    ls._resume(0)
    assert not ls.slots[0].busy and ls.pending(0) == 3 and trace[-1] == (0, "planned")
    assert ls.yields == 1
    ls.shutdown()
    checkpoint()  # the engine's thread has no scheduler: a no-op


def test_command_buffers_write_and_read_the_joints_by_name():
    from types import SimpleNamespace

    from stages.simulate.control import CommandBuffers

    arm = [f"a{i}" for i in range(7)]
    grip = SimpleNamespace(finger_joints=["f0", "f1"], finger_targets=lambda c: np.full(2, 0.04 * (1 - c)))
    desc = SimpleNamespace(arm_joints=arm, gripper=grip)
    coord = {n: i for i, n in enumerate(["x", "y", "f1", *arm[::-1], "f0"])}  # not in control order
    c, worlds = len(coord) + 2, 3
    buf = CommandBuffers(desc, coord, c, -np.ones(7), np.ones(7), np.zeros(worlds * c, np.float32),
                         np.zeros((worlds, 3), np.float32))
    q = np.array([0.1, -0.2, 0.3, 1.7, -0.5, 0.6, -3.0])
    buf.set_arm_targets(q, world=1)
    buf.set_gripper(0.5, world=2)
    expect = np.zeros(worlds * c, np.float32)
    for i, n in enumerate(arm):
        expect[c + coord[n]] = np.clip(q[i], -1, 1)
    for n in grip.finger_joints:
        expect[2 * c + coord[n]] = 0.02
    np.testing.assert_array_equal(buf._targets, expect)
    np.testing.assert_array_equal(buf.arm_targets(1), np.clip(q, -1, 1).astype(np.float32))
    np.testing.assert_array_equal(buf.finger_targets(2), np.float32([0.02, 0.02]))
    buf.set_arm_targets(np.zeros(7))  # every world
    assert not buf._targets[[w * c + coord[n] for w in range(worlds) for n in arm]].any()


def test_a_failing_program_names_its_world():
    from stages.engine import Lockstep

    ls = Lockstep(2)
    ls.start(0, lambda: ls.wait_steps(0, 1))

    def bad():
        raise ValueError("boom")

    ls.start(1, bad)
    with pytest.raises(RuntimeError, match="world 1: its program failed: ValueError"):
        ls.resume_ready()
    ls.shutdown()
    assert ls.is_done(0) and ls.is_done(1)


def test_shards_written_by_writer_processes_equal_shards_written_by_the_engine(room, tmp_path):
    """The engine hands its frames (views of the render buffers) to a ShardPool: the shards are the
    same files as those the engine's process writes itself."""
    import hashlib

    from stages.dataset import EpisodeInfo
    from stages.dataset.pool import open_shards
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    queues = {0: [("press_button", 3, 0.5), ("push_object", 5, 0.4)], 1: [("pick_place_bowl", 4, 0.6)]}
    files = {}
    config = EngineConfig(worlds=2, width=64, height=48, layout="per_world")
    eng = BatchEngine(room, panda_root=None, work_dir=tmp_path / "e", config=config)  # each episode resets
    for procs in (0, 2):
        with open_shards(tmp_path / f"shards{procs}", ["w0", "w1"], config.dataset_spec(), procs) as shards:
            def begin(w, inst):
                shards[w].begin_episode(EpisodeInfo(task=inst.instruction, task_kind=inst.task, scene_id="k",
                                                    seed=inst.seed))
                return shards[w].add_frame

            def end(w, inst, res, shards=shards):
                shards[w].end_episode(success=True)  # timeouts kept: the files are compared

            eng.run(Listed(room, queues), begin=begin, end=end)
        root = tmp_path / f"shards{procs}"
        files[procs] = {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
                        for p in sorted(root.rglob("*")) if p.is_file() and p.name != "agentworld.json"}
    assert files[0] == files[2]
    assert sum(k.endswith(".mp4") for k in files[0]) == 3 * 3  # 3 episodes x 3 cameras


@pytest.mark.slow  # 32 s on 2 cores (CI time); run with -m slow
def test_a_run_cut_by_max_steps_leaves_no_recording_to_the_next_run(room, tmp_path):
    """An episode a run abandons (``max_steps``) records nothing more. With worker processes and
    holds, the next run's first frame steps (its world still planning, not yet held) went to the
    abandoned episode's sink: a closed shard in the GPU benchmark, whose timed run then failed."""
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed

    eng = BatchEngine(room, panda_root=None, work_dir=tmp_path / "e",
                      config=EngineConfig(worlds=1, width=64, height=48, layout="batched", program_procs=1,
                                          program_wait=0.01))
    first: list = []
    eng.run(Listed(room, {0: [("press_button", 3, 2.0)]}), begin=lambda w, inst: first.append,
            max_steps=8 * eng.sync_period)
    assert first, "the first run recorded frames before it was cut"
    cut = len(first)
    second: list = []
    eng.run(Listed(room, {0: [("push_object", 5, 0.2)]}), begin=lambda w, inst: second.append)
    assert len(first) == cut
    assert second


def test_an_episode_whose_expert_raises_fails_alone(room, tmp_path, caplog):
    """An unexpected exception in one episode's expert (a bug, a bad instance) ends that episode as
    failed with reason "error" and its traceback in the log; the world goes on to its next episode
    (a run of many worlds is not lost to one)."""
    import logging

    from stages.demos.multistage import sample_task
    from stages.engine import BatchEngine, EngineConfig

    eng = BatchEngine(room, panda_root=None, work_dir=tmp_path,
                      config=EngineConfig(worlds=1, width=32, height=24, layout="per_world"))
    queue = [sample_task("press_button", room, 4), sample_task("press_button", room, 3)]
    results = {}

    def act(inst, drv):
        if inst.seed == 3:
            raise ValueError("boom")
        drv.step(0.2)

    with caplog.at_level(logging.ERROR, logger="stages.engine.programs"):
        stats = eng.run(lambda w: queue.pop() if queue else None, act=act,
                        end=lambda w, t, r: results.__setitem__(t.seed, r))
    assert stats.episodes == 2 and set(results) == {3, 4}
    assert (results[3].success, results[3].reason, results[3].detail) == (False, "error", "ValueError: boom")
    assert results[4].reason != "error" and results[4].sim_seconds >= 0.2 - 1e-6
    assert any("the episode raised" in r.getMessage() and r.exc_info for r in caplog.records)
