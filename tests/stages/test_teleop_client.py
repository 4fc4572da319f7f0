"""The browser-free operator (:mod:`stages.teleop.client`): the page's protocol from Python drives a
real session through the real server (real simulation and rendering, CPU) and receives its frames;
this is what ``bench_teleop.py --client python`` measures with on a host without a browser."""

from __future__ import annotations

import numpy as np
import pytest

from teleop_testutil import ServerThread, wait_for


def test_parse_frame_reads_the_servers_frame_message():
    from stages.teleop.client import FrameError, parse_frame
    from stages.teleop.server import encode_frame

    rgb = {"head": np.full((12, 16, 3), 200, np.uint8), "wrist": np.zeros((12, 16, 3), np.uint8)}
    frame, jpegs = parse_frame(encode_frame(70000, rgb, 80))
    assert frame == 70000 and list(jpegs) == ["head", "wrist"]
    assert all(v[:2] == b"\xff\xd8" for v in jpegs.values())  # JPEG start-of-image
    with pytest.raises(FrameError):
        parse_frame(b"AWF0" + bytes(8))
    with pytest.raises(FrameError):
        parse_frame(encode_frame(1, rgb, 80)[:-10])


def test_python_client_drives_a_real_session_and_receives_frames(teleop_world, tmp_path):
    from stages.teleop import TeleopConfig, TeleopSession
    from stages.teleop.client import TeleopClient

    cfg = TeleopConfig(width=64, height=48, seed=3)
    session = TeleopSession(teleop_world, task="pick_place_bowl", out=tmp_path / "out", config=cfg, world_seed=5)
    srv = ServerThread(session)
    session.start()
    try:
        with TeleopClient(srv.url) as c:
            c.wait(lambda: c.frames >= 3, what="the first frames")
            assert set(c.last_images) == {"wrist", "head", "third_person"}
            assert all(im.shape == (48, 64, 3) and im.dtype == np.uint8 for im in c.last_images.values())
            # its acknowledgements reach the session: render-to-display latencies
            wait_for(lambda: session.status()["display_ms"] is not None, what="acknowledged frames")
            c.key_down("KeyW")
            wait_for(lambda: session.current_command().base == (1.0, 0.0, 0.0), what="W held")
            seq = session.current_command().seq
            wait_for(lambda: session.current_command().seq >= seq + 2, what="the 0.1 s repeats")
            assert session.current_command().base == (1.0, 0.0, 0.0)
            c.key_up("KeyW")
            c.key_down("KeyM")  # manipulation
            c.key_down("KeyG")  # gripper closed
            c.key_down("KeyR")  # hand up
            wait_for(lambda: session.current_command().jog == (0.0, 0.0, 1.0, 0.0, 0.0, 0.0), what="R held")
            cmd = session.current_command()
            assert (cmd.mode, cmd.gripper, cmd.base) == (1, 1, (0.0, 0.0, 0.0))
            c.key_up("KeyR")
            c.episode("start", "drive")
            wait_for(lambda: session.status()["recording"], what="recording")
            n = c.frames
            c.wait(lambda: c.frames >= n + 3, what="frames while recording")
            # the session's status messages are periodic: the client sees recording on the next one
            c.wait(lambda: c.status is not None and c.status["recording"], what="a status that says recording")
            assert c.status["task"] == "pick_place_bowl"
            c.episode("discard")
            wait_for(lambda: not session.status()["recording"], what="the discard")
        assert not c.errors, c.errors
        assert srv.server.stats["rejected"] == 0 and srv.server.stats["frames_sent"] >= c.frames
    finally:
        session.stop()
        session.join(120)
        srv.close()


@pytest.mark.slow  # ~100 s on the shared 2-core machine: MuJoCo-Warp's CPU kernels step one world slowly
def test_python_client_on_the_gpu_code_path_on_cpu(teleop_world, tmp_path):
    """The session as ``--device cuda`` builds it (the batched layout: MuJoCo-Warp, WorldHold, the
    render in the engine's thread, frames delivered at the next frame step), run on the CPU: the
    client gets frames and its keys drive the base."""
    from stages.teleop import TeleopConfig, TeleopSession
    from stages.teleop.client import TeleopClient

    cfg = TeleopConfig(width=32, height=24, cameras=("head",), layout="batched")
    session = TeleopSession(teleop_world, task="pick_place_bowl", out=tmp_path / "out", config=cfg, world_seed=5)
    ecfg = session.engine.config
    assert ecfg.resolved_layout() == "batched" and not ecfg.background_render
    assert session.engine.banks[0].hold is not None  # MuJoCo-Warp's world hold: the batched engine
    srv = ServerThread(session)
    session.start()
    try:
        with TeleopClient(srv.url) as c:
            c.wait(lambda: c.frames >= 2, what="the first frames")
            assert c.last_images["head"].shape == (24, 32, 3)
            c.key_down("KeyQ")  # turn left
            t0 = session.status()["tick"]
            wait_for(lambda: session.status()["tick"] >= t0 + 4, what="4 ticks of Q")
            c.key_up("KeyQ")
            n = c.frames
            c.wait(lambda: c.frames >= n + 2, what="frames after the turn")
        assert not c.errors, c.errors
    finally:
        session.stop()
        session.join(120)
        srv.close()
    import json

    ticks = [json.loads(line) for line in session.log_path.read_text().splitlines()]
    assert sum(t.get("kind") == "tick" and t["base"] == [0.0, 0.0, 1.0] for t in ticks) >= 4  # Q applied


def test_cli_cameras_option_is_checked(tmp_path, capsys):
    from stages.teleop.cli import main

    with pytest.raises(SystemExit) as e:
        main(["pick_place_bowl", "--out", str(tmp_path), "--cameras", "head,nose"])
    assert e.value.code == 2 and "--cameras 'head,nose'" in capsys.readouterr().err
    assert not (tmp_path / "logs").exists()  # refused before anything was built
