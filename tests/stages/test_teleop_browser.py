"""The teleop page in a real browser (Chromium from the OS packages, driven by Playwright) against
the real server and session: requests without the token are refused, keys drive the base and the
hand, a saved episode lands in the dataset and loads with lerobot's ``LeRobotDataset``. A second
test sends hostile messages over a real WebSocket: they are rejected, the simulation runs on."""

from __future__ import annotations

import json
import shutil
import urllib.error
import urllib.request

import numpy as np
import pytest

from teleop_testutil import ServerThread, chromium, enter_xr, launch_page, save_episode, wait_for


@pytest.fixture
def kitchen(teleop_world):
    return teleop_world


def _status(url: str) -> int:
    try:
        with urllib.request.urlopen(url, timeout=10) as r:
            return r.status
    except urllib.error.HTTPError as e:
        return e.code


def test_browser_drives_the_robot_and_saves_an_episode(kitchen, tmp_path):
    chromium()  # skips without the OS's Chromium
    sync_api = pytest.importorskip("playwright.sync_api", reason="Playwright (pip) drives the browser")
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    from stages.teleop import TeleopConfig, TeleopSession

    cfg = TeleopConfig(width=64, height=48, seed=3)
    session = TeleopSession(kitchen, task="pick_place_bowl", out=tmp_path / "out", config=cfg, world_seed=5)
    srv = ServerThread(session)
    session.start()
    try:
        base = srv.base
        # without the token (or with a wrong one) every path is refused
        for path in ("", "static/teleop.js", "static/teleop.css", "ws", "nothing"):
            assert _status(base + path) == 401, path
            assert _status(base + path + "?token=wrong") == 401, path
        assert _status(srv.url) == 200
        with sync_api.sync_playwright() as pw:
            browser, page, errors = launch_page(pw)
            assert page.goto(base).status == 401
            assert page.goto(srv.url).status == 200
            # polled with evaluate (the page's content policy forbids the eval of wait_for_function)
            wait_for(lambda: page.evaluate("() => window.teleopState.connected && window.teleopState.frames > 2"),
                     what="the page's first frames")
            assert _status(srv.base + "ws?token=" + srv.server.token) == 409  # one operator at a time
            page.fill("#instruction", "drive to the table")
            page.click("#btn-start")
            wait_for(lambda: session.status()["recording"], what="recording")
            page.click("#views")  # focus away from the text field

            def hold(key: str, ticks: int) -> None:
                t0 = session.status()["tick"]
                page.keyboard.down(key)
                wait_for(lambda: session.status()["tick"] >= t0 + ticks, what=f"{ticks} ticks of {key}")
                page.keyboard.up(key)

            hold("KeyW", 8)   # forward
            hold("KeyQ", 6)   # turn left
            page.keyboard.press("KeyM")  # manipulation
            hold("KeyR", 8)   # hand up
            page.keyboard.press("KeyG")  # close the gripper
            t0 = session.status()["tick"]
            wait_for(lambda: session.status()["tick"] >= t0 + 3, what="ticks after the gripper")
            st = page.evaluate("window.teleopState")
            page.click("#btn-save")
            wait_for(lambda: session.status()["saved"] >= 1, what="the saved episode")
            wait_for(lambda: (tmp_path / "out" / "dataset" / "meta" / "teleop.json").is_file(), what="the merge")
            assert page.text_content("#st-ep") is not None
            browser.close()
        assert not errors, errors
    finally:
        session.stop()
        session.join(120)
        srv.close()
    root = tmp_path / "out" / "dataset"
    meta = json.loads((root / "meta" / "teleop.json").read_text())["episodes"][0]
    disp, inp = meta["latency"]["render_to_display"], meta["latency"]["input_to_command"]
    print(f"\nteleop browser: display {st['fps']:.1f} fps, sim {st['status']['fps']} fps; "
          f"render->display p50 {disp['p50_ms']} ms p95 {disp['p95_ms']} ms; "
          f"input->command p50 {inp['p50_ms']} ms p95 {inp['p95_ms']} ms")
    assert meta["input_device"] == "keyboard" and disp["count"] > 5 and inp["count"] > 5
    ds = LeRobotDataset("agentworld/teleop", root=root)
    assert ds.num_episodes == 1 and ds.num_frames == meta["frames"]
    item = ds[ds.num_frames - 1]
    assert item["task"] == "drive to the table"
    assert tuple(item["observation.images.head"].shape) == (3, 48, 64)
    action = np.stack([ds.hf_dataset[i]["action"].numpy() for i in range(ds.num_frames)])
    state = np.stack([ds.hf_dataset[i]["observation.state"].numpy() for i in range(ds.num_frames)])
    # action: arm targets (7), ee target (7), base velocity (3) [m/s, m/s, rad/s], gripper, mode
    assert (action[:, 14] > 0.4).sum() >= 5         # W: forward at 0.5 m/s
    assert (action[:, 16] > 0.9).sum() >= 3         # Q: turning left at 1 rad/s
    assert np.hypot(*(state[-1, 14:16] - state[0, 14:16])) > 0.05  # the base moved [m]
    assert abs(state[-1, 16] - state[0, 16]) > 0.05   # and turned [rad]
    manip = action[:, 18] == 1
    assert manip.sum() >= 8 and np.ptp(state[manip, 9]) > 0.02  # R: the hand rose [m]
    assert action[-1, 17] == 1.0                     # G: gripper closed


def test_hostile_messages_are_rejected_and_the_simulation_runs_on(kitchen, tmp_path):
    """Over HTTPS/WSS with the self-signed certificate that ``--host`` off loopback uses."""
    import asyncio

    import aiohttp

    from stages.teleop import TeleopConfig, TeleopSession
    from stages.teleop.server import self_signed_context

    if shutil.which("openssl") is None:
        pytest.skip("no openssl to make the self-signed certificate")
    session = TeleopSession(kitchen, task="press_button", out=tmp_path / "out",
                            config=TeleopConfig(width=32, height=24, cameras=("head",)), world_seed=5)
    srv = ServerThread(session, rate=50.0, burst=20, ssl_context=self_signed_context(tmp_path / "tls", "127.0.0.1"))
    assert srv.base.startswith("https://")
    session.start()

    async def attack() -> tuple[list, int]:
        async with aiohttp.ClientSession(connector=aiohttp.TCPConnector(ssl=False)) as http:
            async with http.get(srv.base) as r:
                assert r.status == 401
            async with http.ws_connect(srv.base + "ws?token=" + srv.server.token) as ws:
                bad = ["{", "[]", '{"type": "cmd"}', '{"type": "cmd", "seq": 1, "base": [NaN, 0, 0], '
                       '"jog": [0,0,0,0,0,0], "mode": 0, "gripper": 0}',
                       json.dumps({"type": "cmd", "seq": 1, "base": [5, 0, 0], "jog": [0] * 6, "mode": 0,
                                   "gripper": 0}),
                       json.dumps({"type": "ack", "frame": 1, "pad": "x" * 20000})]
                for m in bad:
                    await ws.send_str(m)
                await ws.send_bytes(b"\x00" * 10)
                await asyncio.sleep(0.5)
                for i in range(200):  # a flood: 200 messages at once, the limiter lets ~20 through
                    await ws.send_str(json.dumps({"type": "ack", "frame": i}))
                await asyncio.sleep(0.5)
                ticks = session.status()["tick"]
                got = []
                while len(got) < 3:
                    msg = await ws.receive(timeout=60)
                    if msg.type == aiohttp.WSMsgType.TEXT:
                        got.append(json.loads(msg.data))
                return got, ticks

    try:
        wait_for(lambda: session.status()["tick"] > 0, what="the first tick")
        statuses, ticks = asyncio.run(attack())
        wait_for(lambda: session.status()["tick"] > ticks + 2, what="ticks after the attack")
        stats = srv.server.stats
        assert stats["rejected"] == 7 and 150 <= stats["rate_limited"] <= 185, stats
        reasons = " | ".join(srv.server.rejections)
        for part in ("not JSON", "JSON object", "missing keys", "not a number", "out of range", "exceeds",
                     "binary"):
            assert part in reasons
        assert statuses[-1]["server"]["rejected"] == 7 and session.running
    finally:
        session.stop()
        session.join(60)
        srv.close()


def test_emulated_headset_wrist_drives_the_hand_and_a_pinch_closes_the_gripper(kitchen, tmp_path):
    """IWER (vendored from npm) emulates a Quest 3 with hand tracking in the page: the page's WebXR
    session streams head and 25 hand-joint poses; the wrist moves the end effector to the commanded
    pose (within 1 cm and 5 degrees), a pinch closes the gripper, and the episode is saved as webxr."""
    chromium()  # skips without the OS's Chromium
    sync_api = pytest.importorskip("playwright.sync_api", reason="Playwright (pip) drives the browser")
    from scipy.spatial.transform import Rotation

    from stages.teleop import TeleopConfig, TeleopSession, read_input_log
    from stages.teleop.vendor import vendored
    from stages.teleop.xr import ee_target_to_wrist

    if vendored() is None:
        pytest.skip("IWER is not vendored (python -m stages.teleop.vendor needs npm; .ci/run installs it)")
    cfg = TeleopConfig(width=32, height=24, cameras=("head", "wrist", "third_person"), seed=4)
    session = TeleopSession(kitchen, task="pick_place_bowl", out=tmp_path / "out", config=cfg, world_seed=5)
    srv = ServerThread(session)
    session.start()
    js_pose = "(h) => ({p: [h.position.x, h.position.y, h.position.z], q: [h.quaternion.x, h.quaternion.y, " \
              "h.quaternion.z, h.quaternion.w]})"
    try:
        with sync_api.sync_playwright() as pw:
            browser, page, errors = launch_page(pw)
            page.goto(srv.url + "&emulate=1")
            wait_for(lambda: page.evaluate("() => window.teleopState.frames > 1"), what="the first frames")
            page.click("#btn-start")
            wait_for(lambda: session.status()["recording"] and session.status()["ee_pose"], what="recording")
            ee0 = np.asarray(session.status()["ee_pose"])  # the hand at the reset, base frame
            enter_xr(page, session)  # the emulated immersive session
            # IWER's right hand: its transform -> its wrist joint's pose (what the page reports)
            hand = page.evaluate(f"() => ({js_pose})(window.teleopXrDevice.hands.right)")
            hand_m = np.eye(4)
            hand_m[:3, :3] = Rotation.from_quat(hand["q"]).as_matrix()
            hand_m[:3, 3] = hand["p"]
            wait_for(lambda: page.evaluate("() => window.teleopState.xrSent > 10"), what="fresh XR poses")
            head = np.asarray(session.xr.head)
            offset = np.linalg.inv(hand_m) @ np.asarray(session.xr.hands["right"][0])
            # command: 6 cm left and 8 cm up of the reset hand, its orientation
            goal = np.eye(4)
            goal[:3, :3] = Rotation.from_quat(np.roll(ee0[3:], -1)).as_matrix()
            goal[:3, 3] = ee0[:3] + [0.0, 0.06, 0.08]
            want_hand = ee_target_to_wrist(goal, head) @ np.linalg.inv(offset)
            q = Rotation.from_matrix(want_hand[:3, :3]).as_quat()
            page.evaluate("([p, q]) => { const h = window.teleopXrDevice.hands.right; "
                          "h.position.set(p[0], p[1], p[2]); h.quaternion.set(q[0], q[1], q[2], q[3]); }",
                          [list(want_hand[:3, 3]), list(q)])
            t0 = session.status()["tick"]
            wait_for(lambda: session.status()["tick"] >= t0 + 45, what="1.5 s of reaching")
            before_pinch = session.status()["tick"]
            page.evaluate("() => window.teleopXrDevice.hands.right.updatePinchValue(1)")
            wait_for(lambda: session.status()["tick"] >= before_pinch + 20, what="the pinch")
            pinch = np.asarray(session.xr.hands["right"])
            save_episode(page, session, tmp_path / "out")
            browser.close()
        assert not errors, errors
    finally:
        session.stop()
        session.join(120)
        srv.close()
    assert np.linalg.norm(pinch[4][:3, 3] - pinch[9][:3, 3]) < 0.025  # thumb and index tips together [m]
    ep = [e for e in read_input_log(session.log_path).episodes if e.record][0]
    cmd = np.asarray(ep.ticks[before_pinch - 2].ee).reshape(4, 4)  # the commanded pose, base frame
    assert np.abs(cmd[:3, 3] - goal[:3, 3]).max() < 1e-3  # the page's poses carry the command (rounded 1e-5)
    import pyarrow.parquet as pq

    root = tmp_path / "out" / "dataset"
    t = pq.read_table(sorted((root / "data").glob("*/*.parquet")))
    state = np.stack(t.column("observation.state").to_numpy(zero_copy_only=False))
    action = np.stack(t.column("action").to_numpy(zero_copy_only=False))
    ee = state[before_pinch - 1, 7:14]  # measured end-effector pose (xyz, wxyz), base frame
    pos_err = np.linalg.norm(ee[:3] - cmd[:3, 3])
    rot_err = np.degrees((Rotation.from_quat(np.roll(ee[3:], -1)).inv()
                          * Rotation.from_matrix(cmd[:3, :3])).magnitude())
    print(f"\nteleop webxr: end effector {pos_err * 1000:.2f} mm, {rot_err:.3f} deg from the wrist's command")
    assert pos_err < 0.01 and rot_err < 5.0
    assert np.linalg.norm(state[before_pinch - 1, 7:10] - ee0[:3]) > 0.05  # it did move there
    assert action[before_pinch - 1, 17] == 0.0 and action[-1, 17] == 1.0  # open, then closed by the pinch
    assert (action[:, 18] == 1).sum() > 40  # manipulation mode while XR drove it
    meta = json.loads((root / "meta" / "teleop.json").read_text())["episodes"][0]
    assert meta["input_device"] == "webxr"
