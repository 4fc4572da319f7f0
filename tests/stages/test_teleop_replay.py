"""Teleop session on the CPU: an operator's commands (through the same validated messages the page
sends) drive the real engine, a saved episode lands in the LeRobot dataset with teleop metadata,
and ``--replay`` of the session's input log reproduces it (same actions, state within 1e-6)."""

from __future__ import annotations

import json
import threading
import time

import numpy as np
import pytest


@pytest.fixture
def kitchen(teleop_world):
    return teleop_world


def _send(session, **msg) -> None:
    from stages.teleop import parse_message

    session.submit(parse_message(json.dumps(msg)))


def _wait(pred, timeout: float = 240.0) -> None:
    t0 = time.monotonic()
    while not pred():
        if time.monotonic() - t0 > timeout:
            raise TimeoutError("teleop test: condition not met in time")
        time.sleep(0.005)


def _operator(session, script: list) -> None:
    """Sends (at recorded tick >= n: message) pairs once the recorded episode reaches tick n; the
    session stops at the end (or when this fails, so that the test does not hang)."""
    try:
        _wait(lambda: session.status()["tick"] >= 2)
        _send(session, type="episode", action="start", task="drive up to the table and lift the hand")
        _wait(lambda: session.status()["recording"])
        for at, msg in script:
            _wait(lambda at=at: session.status()["tick"] >= at)
            _send(session, **msg)
        _wait(lambda: session.status()["saved"] >= 1)
    finally:
        session.stop()


def _cmd(seq, base=(0, 0, 0), jog=(0,) * 6, mode=0, gripper=0) -> dict:
    return dict(type="cmd", seq=seq, base=list(base), jog=list(jog), mode=mode, gripper=gripper)


def _columns(root):
    import pyarrow.parquet as pq

    t = pq.read_table(sorted((root / "data").glob("*/*.parquet")))
    return np.stack(t.column("observation.state").to_numpy(zero_copy_only=False)), \
        np.stack(t.column("action").to_numpy(zero_copy_only=False))


def test_operated_episode_is_saved_and_its_replay_reproduces_it(kitchen, tmp_path):
    from stages.dataset import load_dataset
    from stages.teleop import TeleopConfig, TeleopSession, read_input_log, replay_session

    # a scripted operator sends each command once (no 0.1 s repeats as the page does): no timeout
    cfg = TeleopConfig(width=64, height=48, realtime=False, seed=11, command_timeout=None)
    s = TeleopSession(kitchen, task="pick_place_bowl", out=tmp_path / "live", config=cfg, world_seed=5)
    script = [(3, _cmd(1, base=(1, 0, 0.5))),                       # drive forward, turning
              (12, _cmd(2, base=(0, -1, 0))),                       # strafe right
              (18, _cmd(3, mode=1, jog=(0, 0, 1, 0, 0, 0))),        # manipulation: hand up
              (26, _cmd(4, mode=1, jog=(1, 0, 0, 0, 0, 0.5), gripper=1)),  # forward, yaw, close
              (34, dict(type="episode", action="save"))]
    op = threading.Thread(target=_operator, args=(s, script), daemon=True)
    op.start()
    s.run()
    op.join(5)
    assert len(s.saved) == 1
    ds_root = tmp_path / "live" / "dataset"
    meta = json.loads((ds_root / "meta" / "teleop.json").read_text())["episodes"][0]
    assert meta["input_device"] == "keyboard" and meta["ticks"] >= 34
    assert meta["latency"]["input_to_command"]["count"] >= 4
    ds = load_dataset(ds_root)
    assert ds.num_episodes == 1 and ds.num_frames == meta["frames"]
    assert ds[0]["task"] == "drive up to the table and lift the hand"
    state, action = _columns(ds_root)
    # the base drove (x, y, theta of observation.state[14:17]) and the hand rose in manipulation mode
    assert np.abs(state[-1, 14:17] - state[0, 14:17]).max() > 0.1
    modes = action[:, -1]
    assert set(np.unique(modes)) == {0.0, 1.0}
    up = state[modes == 1][:, 9]  # end-effector z in the base frame [m]
    assert up.max() - up.min() > 0.02
    assert action[-1, 17] == 1.0  # gripper closed at the end (action: 7 + 7 + 3 + gripper + mode)

    # the input log replays headless into another dataset: same actions, same states
    log = read_input_log(s.log_path)
    # a preview, the recorded episode, maybe the next preview (stopped)
    assert [e.record for e in log.episodes][:2] == [False, True]
    assert [e.outcome for e in log.episodes] in (["start", "save"], ["start", "save", "stop"])
    r = replay_session(log, kitchen, out=tmp_path / "replay")  # what `agentworld teleop --replay` runs
    assert len(r.saved) == 1
    state2, action2 = _columns(tmp_path / "replay" / "dataset")
    assert state2.shape == state.shape
    np.testing.assert_array_equal(action2, action)
    np.testing.assert_allclose(state2, state, rtol=0, atol=1e-6)
    rmeta = json.loads((tmp_path / "replay" / "dataset" / "meta" / "teleop.json").read_text())["episodes"][0]
    assert rmeta["input_device"] == "replay" and rmeta["replay_of_episode"] == 1


@pytest.mark.slow
def test_replay_command_reproduces_a_session(kitchen, tmp_path):
    """``agentworld teleop TASK --replay LOG`` (a subprocess, the kitchen's assets reused)."""
    import subprocess
    import sys
    from pathlib import Path

    from stages.teleop import TeleopConfig, TeleopSession

    cfg = TeleopConfig(width=32, height=24, realtime=False, seed=2, command_timeout=None)
    s = TeleopSession(kitchen, task="press_button", out=tmp_path / "live", config=cfg, world_seed=5)
    op = threading.Thread(target=_operator, args=(s, [(3, _cmd(1, base=(1, 0, 1))), (10, _cmd(2, mode=1, jog=(0, 1, 0, 0, 0, 0))),
                                                      (16, dict(type="episode", action="save"))]), daemon=True)
    op.start()
    s.run()
    op.join(5)
    repo = Path(__file__).resolve().parents[2]
    cmd = [sys.executable, "-m", "pipeline.cli", "teleop", "press_button", "--replay", str(s.log_path),
           "--out", str(tmp_path / "replay"), "--work", str(kitchen.usd.parent.parent)]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=900, cwd=repo)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    assert f"replayed 1 episode(s) of {s.log_path}" in run.stdout + run.stderr
    state, action = _columns(tmp_path / "live" / "dataset")
    state2, action2 = _columns(tmp_path / "replay" / "dataset")
    np.testing.assert_array_equal(action2, action)
    np.testing.assert_allclose(state2, state, rtol=0, atol=1e-6)


def _xr(hand_flex: float) -> dict:
    """An XR message (column-major 4x4s) of a head and a synthetic right hand ``hand_flex`` [rad]
    closed, the wrist 40 cm ahead of and 40 cm below the head, palm down."""
    from teleop_testutil import synthetic_hand

    head = np.eye(4)
    head[:3, 3] = (0.0, 1.6, 0.0)
    wrist = np.eye(4)
    wrist[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]  # fingers ahead (-z), palm down
    wrist[:3, 3] = (0.0, 1.2, -0.4)
    cm = lambda m: [round(float(x), 6) for x in np.asarray(m).T.ravel()]  # noqa: E731
    return dict(type="xr", head=cm(head), hands={"right": [cm(j) for j in synthetic_hand(hand_flex, wrist=wrist)]})


def test_hand_session_records_retargeted_fingers_and_replays_them(kitchen, tmp_path, shared_assets):
    """``hand="allegro"``: WebXR hand joints (validated messages, as the page sends them) are
    retargeted each tick; the input log carries the targets, and its replay (no retargeting)
    reproduces the episode (same actions, state within 1e-6); a hand the retargeting refuses is
    logged and the last targets kept."""
    pytest.importorskip("dex_retargeting", reason="dex-retargeting (pip) retargets the hands")
    from stages.teleop import TeleopConfig, TeleopSession, read_input_log, replay_session

    cfg = TeleopConfig(width=32, height=24, cameras=("head",), realtime=False, seed=3, command_timeout=None,
                       hand="allegro")
    s = TeleopSession(kitchen, task="pick_place_bowl", out=tmp_path / "live", config=cfg, world_seed=5)
    skewed = _xr(1.2)  # the wrist's rotation rows (1, 0, 0), (0.6, 0, 0.8), (0, -1, 0): unit rows (the
    skewed["hands"]["right"][0][1] = 0.6  # protocol parses it), not orthogonal (the retargeting refuses it)
    skewed["hands"]["right"][0][9] = 0.8
    op = threading.Thread(target=_operator, args=(s, [(3, _xr(0.0)), (14, _xr(1.2)), (22, skewed),
                                                      (28, dict(type="episode", action="save"))]), daemon=True)
    op.start()
    s.run()
    op.join(5)
    assert len(s.saved) == 1 and s.hand_rejected >= 1
    state, action = _columns(tmp_path / "live" / "dataset")
    hand_t, hand_q = action[:, 17:33], state[:, 17:33]  # action: arm 7, ee 7, base 3, Allegro 16, mode
    assert action.shape[1] == 34 and state.shape[1] == 33
    flex = hand_t[:, [1, 2, 3, 5, 6, 7, 9, 10, 11]].sum(axis=1)  # index, middle, ring flexion [rad]
    assert flex[20] > flex[12] + 3.0, (flex[12], flex[20])  # closed hand: the fingers flex
    np.testing.assert_array_equal(hand_t[-1], hand_t[25])  # the refused hand (from tick 22) kept the targets
    assert np.abs(hand_q[-1] - hand_t[-1]).max() < 0.1  # the simulated fingers follow
    log = read_input_log(s.log_path)
    r = replay_session(log, kitchen, out=tmp_path / "replay")
    assert len(r.saved) == 1 and r.retargeter is None
    state2, action2 = _columns(tmp_path / "replay" / "dataset")
    np.testing.assert_array_equal(action2, action)
    np.testing.assert_allclose(state2, state, rtol=0, atol=1e-6)
