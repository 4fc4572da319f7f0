"""How far off the bar can the scripted drawer grasp close and still open the drawer? (issue 17, session 29)

Runs the scripted open_drawer expert (one world, no cameras) in one kitchen and seed once per offset, with the
final grasp pose (``stages.demos.articulated.handle_pose`` at ``back == 0``) moved in the tool frame: x along
the bar, y the fingers' closing direction (about vertical), z the approach axis (negative: short of the bar) [m],
and optionally turned by a rotation vector [deg] in the tool frame. Prints and writes OUT (JSON) one row per
offset: success and failure reason.

    python tests/benchmarks/drawer_grasp_tolerance.py --kitchen 101 --seed 1000005 --work WORK_WITH_KITCHENS \\
        --offsets '[[0,0,-0.01],[0,0,0,0,3,0]]' --out tol.json

WORK: a folder whose ``kitchens`` catalog ``agentworld eval --work`` built (or builds there on first use).
Session 29 (kitchen 101, seed 1000005): the grasp holds 1 cm along the bar, 6 mm across, 3 deg about any tool
axis and up to 12 mm short along the approach; 13.5 mm short the drawer stays shut.
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
    from stages.engine import BatchEngine, EngineConfig
    from stages.engine.programs import Listed
    from stages.policy.evaluate import build_kitchen

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--kitchen", type=int, default=101)
    p.add_argument("--seed", type=int, default=1000005)
    p.add_argument("--work", type=Path, required=True)
    p.add_argument("--offsets", required=True, help="JSON list of [dx, dy, dz] or [dx, dy, dz, rx, ry, rz]")
    p.add_argument("--out", type=Path, required=True)
    a = p.parse_args()
    offsets = [np.asarray(o, float) for o in json.loads(a.offsets)]
    if any(o.shape not in ((3,), (6,)) for o in offsets):
        raise SystemExit("drawer_grasp_tolerance: each offset is [dx, dy, dz] or [dx, dy, dz, rx, ry, rz]")
    world = build_kitchen(a.work / "kitchens", a.kitchen)
    orig, rows = art.handle_pose, []
    try:
        for k, off in enumerate(offsets):
            def moved(part, q, pitch, back=0.0, _off=off):
                m = orig(part, q, pitch, back)
                if back == 0.0:  # the grasp itself, not the pre-grasp
                    m = m.copy()
                    m[:3, 3] = m[:3, 3] + m[:3, :3] @ _off[:3]
                    if len(_off) == 6:
                        m[:3, :3] = m[:3, :3] @ Rotation.from_rotvec(np.radians(_off[3:])).as_matrix()
                return m

            art.handle_pose = moved
            engine = BatchEngine(world, panda_root=None, work_dir=a.work / f"tolerance_{a.kitchen}_{a.seed}_{k}",
                                 config=EngineConfig(worlds=1, record_images=False), seed=a.seed)
            res = []
            engine.run(Listed(world, {0: [("open_drawer", a.seed, None)]}), begin=lambda w, t: (lambda f: None),
                       end=lambda w, t, r: res.append(r))
            rows.append({"offset": off.tolist(), "success": bool(res[0].success), "reason": res[0].reason or ""})
            print(f"offset {off.tolist()}: {'opened' if res[0].success else 'failed ' + str(res[0].reason)}", flush=True)
    finally:
        art.handle_pose = orig
    a.out.write_text(json.dumps({"kitchen": a.kitchen, "seed": a.seed, "rows": rows}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
