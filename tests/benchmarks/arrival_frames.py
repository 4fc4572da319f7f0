"""How a dataset's base arrives at its task (issue 17, session 25): pick_place_bowl, push_object, open/close.

Per episode: the driving frames (a nonzero base velocity action) whose first key point in the base frame
(``observation.environment_state``'s first two entries: ``object_x, object_y`` or ``handle_x, handle_y``)
already lies within ``--radius`` of where it is
when the base stops for good, and the frames from that stop to the arm's first move (its end-effector target
moving by more than 5 mm). A state policy has no phase input: the more driving frames look like the stop,
the more it learns to keep driving there. Prints the median, 90th percentile and mean of each; writes JSON.

    python tests/benchmarks/arrival_frames.py out/pol_grip/datasets/pick_grip out/pol_grip/datasets/pick_dart \\
        --out arrival.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

BASE_V = ("base_vx", "base_vy", "base_vtheta")


def last_drive(action: np.ndarray, base: list[int]) -> int:
    """The index of an episode's last frame whose base velocity action (columns ``base``) is nonzero:
    the base's final stop."""
    return int(np.where(np.abs(action[:, base]).sum(1) > 1e-3)[0][-1])


def arrival(dataset: Path, radius: float) -> dict:
    from stages.dataset.view import feature_names

    an = feature_names(dataset, "action")
    en = feature_names(dataset, "observation.environment_state")
    base = [an.index(n) for n in BASE_V]
    ee = [an.index(n) for n in ("ee_x_target", "ee_y_target", "ee_z_target")]
    obj = [0, 1]  # the first key point's x, y
    assert en[0].endswith("_x") and en[1].endswith("_y"), en
    near, wait = [], []
    for p in sorted((dataset / "data").glob("*/*.parquet")):
        df = pd.read_parquet(p)
        for _, g in df.groupby("episode_index"):
            a = np.stack(g["action"].values)
            e = np.stack(g["observation.environment_state"].values)
            last = last_drive(a, base)
            d = np.linalg.norm(e[:last + 1, obj] - e[last + 1, obj], axis=1)
            near.append(int((d < radius).sum()))
            moved = np.linalg.norm(a[last + 1:, ee] - a[last, ee], axis=1) > 0.005
            wait.append(int(np.argmax(moved)))

    def stat(x: list[int]) -> dict:
        v = np.asarray(x, float)
        return {"median": float(np.median(v)), "p90": float(np.percentile(v, 90)), "mean": round(float(v.mean()), 2)}

    return {"episodes": len(near), "driving_frames_near_stop": stat(near), "frames_stop_to_arm": stat(wait)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("datasets", type=Path, nargs="+")
    p.add_argument("--radius", type=float, default=0.03, help="[m]")
    p.add_argument("--out", type=Path, default=None)
    a = p.parse_args()
    res = {}
    for d in a.datasets:
        res[d.name] = r = arrival(d, a.radius)
        print(f"{d.name}: {r['episodes']} episodes; driving frames within {a.radius} m of the stop: "
              f"{r['driving_frames_near_stop']}; frames from the stop to the arm's move: {r['frames_stop_to_arm']}")
    if a.out:
        a.out.write_text(json.dumps({"radius_m": a.radius, "datasets": res}, indent=1))


if __name__ == "__main__":
    main()
