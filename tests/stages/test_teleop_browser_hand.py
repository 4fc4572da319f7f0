"""An emulated headset's hand drives an Allegro or a Shadow hand (issue 15): the teleop page in the
OS's Chromium (Playwright) with IWER emulating a Quest 3 with hand tracking streams the 25 XRHand
joints; the session (``hand="allegro"`` / ``"shadow"``) retargets them with dex-retargeting each
tick, and the simulated hand on the Panda follows. IWER's hand poses: "default" (relaxed, open),
its pinch (thumb and index tips together) and "point" (middle, ring and little fingers curled)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from teleop_testutil import ServerThread, chromium, enter_xr, launch_page, save_episode, wait_for

pytest.importorskip("dex_retargeting", reason="dex-retargeting (pip) retargets the hands")

# each hand's flexion joints (its joint order): Allegro index 0-3, middle 4-7, ring 8-11 (abduction,
# three flexions); Shadow FF 0-3, MF 4-7, RF 8-11, LF 12-15 (J3 abduction, J2, J1, J0 flexions)
FLEX = {"allegro": {"index": [1, 2, 3], "middle": [5, 6, 7], "ring": [9, 10, 11]},
        "shadow": {"index": [1, 2, 3], "middle": [5, 6, 7], "ring": [9, 10, 11], "little": [13, 14, 15]}}


def _joints(hand: str) -> tuple[str, ...]:
    from stages.simulate.hands import ALLEGRO_JOINTS, SHADOW_JOINTS

    return {"allegro": ALLEGRO_JOINTS, "shadow": SHADOW_JOINTS}[hand]


def test_emulated_hand_fingers_drive_the_allegro_hand(teleop_world, tmp_path, shared_assets):
    _drive_hand(teleop_world, tmp_path, "allegro")


def test_emulated_hand_fingers_drive_the_shadow_hand(teleop_world, tmp_path, shared_assets):
    _drive_hand(teleop_world, tmp_path, "shadow")


def _drive_hand(teleop_world, tmp_path, hand: str) -> None:
    chromium()  # skips without the OS's Chromium
    sync_api = pytest.importorskip("playwright.sync_api", reason="Playwright (pip) drives the browser")
    import pyarrow.parquet as pq

    from stages.teleop import TeleopConfig, TeleopSession, read_input_log
    from stages.teleop.vendor import vendored

    if vendored() is None:
        pytest.skip("IWER is not vendored (python -m stages.teleop.vendor needs npm; .ci/run installs it)")
    names = _joints(hand)
    n = len(names)  # Allegro 16, Shadow 22
    HAND = slice(17, 17 + n)  # state after arm (7), ee pose (7), base (3); action likewise
    cfg = TeleopConfig(width=32, height=24, cameras=("head",), seed=4, hand=hand)
    session = TeleopSession(teleop_world, task="pick_place_bowl", out=tmp_path / "out", config=cfg, world_seed=5)
    srv = ServerThread(session)
    session.start()
    ends = {}
    try:
        with sync_api.sync_playwright() as pw:
            browser, page, errors = launch_page(pw)
            page.goto(srv.url + "&emulate=1")
            wait_for(lambda: page.evaluate("() => window.teleopState.frames > 1"), what="the first frames")
            page.click("#btn-start")
            wait_for(lambda: session.status()["recording"], what="recording")
            enter_xr(page, session, what="XR hand joints at the server")
            for phase, js in (("open", "h.poseId = 'default'; h.updatePinchValue(0);"),
                              ("pinch", "h.updatePinchValue(1);"),
                              ("point", "h.poseId = 'point'; h.updatePinchValue(0);")):
                page.evaluate(f"() => {{ const h = window.teleopXrDevice.hands.right; {js} }}")
                t0 = session.status()["tick"]
                wait_for(lambda t0=t0: session.status()["tick"] >= t0 + 24, what=f"24 ticks of the {phase} hand")
                ends[phase] = session.status()["tick"]
            save_episode(page, session, tmp_path / "out")
            browser.close()
        assert not errors, errors
    finally:
        session.stop()
        session.join(120)
        srv.close()
    assert session.status()["hand_rejected"] == 0
    ep = [e for e in read_input_log(session.log_path).episodes if e.record][0]
    assert sum(t.hand is not None for t in ep.ticks) > 60 and all(len(t.hand) == n for t in ep.ticks if t.hand)
    root = tmp_path / "out" / "dataset"
    info = json.loads((root / "meta" / "info.json").read_text())["features"]
    assert info["action"]["names"][HAND] == [f"{j}_target" for j in names]
    assert info["observation.state"]["names"][HAND] == list(names)
    t = pq.read_table(sorted((root / "data").glob("*/*.parquet")))
    state = np.stack(t.column("observation.state").to_numpy(zero_copy_only=False))
    action = np.stack(t.column("action").to_numpy(zero_copy_only=False))
    target = {p: action[k - 1, HAND] for p, k in ends.items()}  # at each phase's end
    joint = {p: state[k - 1, HAND] for p, k in ends.items()}
    flex = {p: {f: round(float(target[p][i].sum()), 3) for f, i in FLEX[hand].items()} for p in ends}
    print(f"\nteleop {hand} hand: flexion targets [rad] {flex}; joint - target at the phase ends [rad] "
          f"{ {p: round(float(np.abs(joint[p] - target[p]).max()), 3) for p in ends} }")
    assert flex["pinch"]["index"] > flex["open"]["index"] + 0.5  # the pinch flexes the index
    assert flex["point"]["middle"] > flex["open"]["middle"] + 0.8  # the curled fingers flex
    assert flex["point"]["ring"] > flex["open"]["ring"] + 0.8
    assert abs(flex["point"]["index"] - flex["open"]["index"]) < 0.5  # the pointing index stays as it was
    if hand == "shadow":
        assert flex["point"]["little"] > flex["open"]["little"] + 0.8
    for p in ends:  # the simulated hand follows its targets
        assert np.abs(joint[p] - target[p]).max() < 0.15, (p, joint[p], target[p])
    meta = json.loads((root / "meta" / "teleop.json").read_text())["episodes"][0]
    assert meta["input_device"] == "webxr"
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    ds = LeRobotDataset("agentworld/teleop", root=root)  # the same LeRobot schema, n hand targets
    assert ds.num_frames == meta["frames"] and tuple(ds[ends["pinch"] - 1]["action"].shape) == (7 + 7 + 3 + n + 1,)
    np.testing.assert_allclose(ds[ends["pinch"] - 1]["action"][HAND].numpy(), target["pinch"], atol=1e-6)
