"""How far off the bar can the scripted drawer grasp close and still open the drawer? (issue 17, session 29)

Runs the scripted open_drawer expert (one world, no cameras) in one kitchen and seed once per offset, with the
final grasp pose (``stages.demos.articulated.handle_pose`` at ``back == 0``) moved in the tool frame: x along
the bar, y the fingers' closing direction (about vertical), z the approach axis (negative: short of the bar) [m],
and optionally turned by a rotation vector [deg] in the tool frame; ``--stance-yaw`` [rad] also turns the base's
stance from square to the drawer (its pull then runs at that angle to the drawer's axis), and with ``--hand-turns``
the hand turns with it (the grasp and pre-grasp turned by that yaw about the vertical, as a policy that keeps the
hand's orientation in the base frame would hold it). Prints and writes OUT
(JSON) one row per offset: success, failure reason and the fingers' opening after closing [m].

    python tests/benchmarks/drawer_grasp_tolerance.py --kitchen 101 --seed 1000005 --work WORK_WITH_KITCHENS \\
        --offsets '[[0,0,-0.01],[0,0,0,0,3,0]]' --out tol.json

WORK: a folder whose ``kitchens`` catalog ``agentworld eval --work`` built (or builds there on first use).
Session 29 (kitchen 101, seed 1000005): the grasp holds 1 cm along the bar, 6 mm across, 3 deg about any tool
axis and up to 12 mm short along the approach; 13.5 mm short the drawer stays shut. The fingers stop at 0.0117 m
square on the bar, narrower short of it (0.0095 at 12 mm) and wider rolled about the approach axis (0.0132 at 5 deg,
0.0167 at 15, 0.0187 at 20: all opened); a stance turned 0.3 rad still opens it. With the hand turned too the
fingers stop wider as the yaw grows (0.0130 m at 0.2 rad, 0.0141 at 0.35, 0.0153 at 0.5) and at -0.5 rad the
drawer stays shut: the policy's wide stops (0.016-0.019 m) are stances turned ~0.5 rad or more from square.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))


def main() -> int:
    from scipy.spatial.transform import Rotation

    import stages.demos.articulated as art
    from stages.demos.part_checks import _finger_gap
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed
    from stages.policy.evaluate import build_kitchen

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--kitchen", type=int, default=101)
    p.add_argument("--seed", type=int, default=1000005)
    p.add_argument("--work", type=Path, required=True)
    p.add_argument("--offsets", required=True, help="JSON list of [dx, dy, dz] or [dx, dy, dz, rx, ry, rz]")
    p.add_argument("--stance-yaw", type=float, default=0.0, help="[rad] added to the stance candidates' yaw")
    p.add_argument("--hand-turns", action="store_true", help="the hand turns with --stance-yaw")
    p.add_argument("--out", type=Path, required=True)
    a = p.parse_args()
    offsets = [np.asarray(o, float) for o in json.loads(a.offsets)]
    if any(o.shape not in ((3,), (6,)) for o in offsets):
        raise SystemExit("drawer_grasp_tolerance: each offset is [dx, dy, dz] or [dx, dy, dz, rx, ry, rz]")
    world = build_kitchen(a.work / "kitchens", a.kitchen)
    orig, rows = art.handle_pose, []
    orig_check, orig_base, gaps = art._check_grasp, art.choose_base, []

    def check(part, d, *args, **kw):  # the expert's own check after closing: note the fingers' opening there
        gaps.append(_finger_gap(d))
        return orig_check(part, d, *args, **kw)

    def turned(d, part, grid, cands, targets):
        return orig_base(d, part, grid, [(c[0], c[1], c[2] + a.stance_yaw, c[3]) for c in cands], targets)

    art._check_grasp, art.choose_base = check, turned
    hand_turn = Rotation.from_euler("z", a.stance_yaw).as_matrix()  # world vertical
    try:
        for k, off in enumerate(offsets):
            def moved(part, q, pitch, back=0.0, _off=off):
                m = orig(part, q, pitch, 0.0 if a.hand_turns else back).copy()
                if a.hand_turns:  # about the vertical through the grasp point, keeping the pre-grasp behind it
                    m[:3, :3] = hand_turn @ m[:3, :3]
                    m[:3, 3] = m[:3, 3] - back * m[:3, 2]
                if back == 0.0:  # the grasp itself, not the pre-grasp
                    m[:3, 3] = m[:3, 3] + m[:3, :3] @ _off[:3]
                    if len(_off) == 6:
                        m[:3, :3] = m[:3, :3] @ Rotation.from_rotvec(np.radians(_off[3:])).as_matrix()
                return m

            art.handle_pose = moved
            engine = BatchEngine(world, panda_root=None, work_dir=a.work / f"tolerance_{a.kitchen}_{a.seed}_{k}",
                                 config=EngineConfig(worlds=1, record_images=False), seed=a.seed)
            res, gaps[:] = [], []
            engine.run(Listed(world, {0: [("open_drawer", a.seed, None)]}), begin=lambda w, t: (lambda f: None),
                       end=lambda w, t, r: res.append(r))
            gap = round(gaps[0], 4) if gaps else None
            rows.append({"offset": off.tolist(), "success": bool(res[0].success), "reason": res[0].reason or "",
                         "finger_gap": gap})
            print(f"offset {off.tolist()}: {'opened' if res[0].success else 'failed ' + str(res[0].reason)}, "
                  f"fingers {gap} m", flush=True)
    finally:
        art.handle_pose, art._check_grasp, art.choose_base = orig, orig_check, orig_base
    a.out.write_text(json.dumps({"kitchen": a.kitchen, "seed": a.seed, "stance_yaw": a.stance_yaw,
                                 "hand_turns": a.hand_turns, "rows": rows},
                                indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
