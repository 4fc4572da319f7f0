"""Open-loop probe of a state policy on its training frames (issue 17, session 25).

For frames of a training dataset (or state view) of pick_place_bowl, each from a fresh chunk (no temporal
ensembling history), prints the policy's first action beside the recorded one: end-effector target
(x, y, z [m], base frame), base velocity (vx, vy [m/s], vtheta [rad/s]) and gripper. Frames: every 60th,
and around the base's final stop (5 before, the stop, 3, 10 and 30 after). A policy that fits its data
matches at every frame; one that fails only in closed loop then meets states its data holds few of. Summary
line per run: over all episodes probed, the mean |base velocity| the policy predicts in the 3 frames after
the stop (the data: 0).

    python tests/benchmarks/policy_probe.py CHECKPOINT VIEW [--episodes 0,5] [--summary-episodes 50]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from arrival_frames import BASE_V, last_drive  # noqa: E402  (tests/benchmarks, the script's folder)


def probe_args(doc: str) -> argparse.Namespace:
    """The probes' command line: CHECKPOINT VIEW [--episodes 0,5] [--summary-episodes 50]."""
    p = argparse.ArgumentParser(description=doc.splitlines()[0])
    p.add_argument("checkpoint", type=Path)
    p.add_argument("view", type=Path)
    p.add_argument("--episodes", default="0,5")
    p.add_argument("--summary-episodes", type=int, default=50)
    return p.parse_args()


def probe_setup(checkpoint: Path, view: Path):
    """(action names, the view's frames as one DataFrame, first_action(state, env_state) -> action): the policy's
    first action from a fresh chunk (no ensembling history) on the CPU."""
    from stages.dataset.view import feature_names
    from stages.policy.runner import BatchedRunner, load_policy

    runner = BatchedRunner(load_policy(checkpoint, "cpu"))
    df = pd.concat(pd.read_parquet(f) for f in sorted((view / "data").glob("*/*.parquet")))

    def first_action(s: np.ndarray, e: np.ndarray) -> np.ndarray:
        runner.reset(0, 0)
        return runner.act({0: {"observation.state": s.astype(np.float32),
                               "observation.environment_state": e.astype(np.float32)}})[0]

    return feature_names(view, "action"), df, first_action


def main() -> None:
    a = probe_args(__doc__)
    an, df, first_action = probe_setup(a.checkpoint, a.view)
    ee = [an.index(n) for n in ("ee_x_target", "ee_y_target", "ee_z_target")]
    base = [an.index(n) for n in BASE_V]
    grip = an.index("gripper")

    def episode(idx: int):
        g = df[df.episode_index == idx]
        s, e = np.stack(g["observation.state"].values), np.stack(g["observation.environment_state"].values)
        act = np.stack(g["action"].values)
        stop = last_drive(act, base)
        return s, e, act, stop

    for idx in (int(x) for x in a.episodes.split(",")):
        s, e, act, stop = episode(idx)
        for k in [*range(0, len(s), 60), stop - 5, stop, stop + 3, stop + 10, stop + 30]:
            y = first_action(s[k], e[k])
            print(f"ep {idx} frame {k:4d}: ee {np.round(y[ee], 3)} (data {np.round(act[k, ee], 3)})  base "
                  f"{np.round(y[base], 2)} (data {np.round(act[k, base], 2)})  gripper {y[grip]:.2f} "
                  f"(data {act[k, grip]:.2f})")
    after = []
    for idx in sorted(df.episode_index.unique())[:a.summary_episodes]:
        s, e, _, stop = episode(int(idx))
        after += [float(np.abs(first_action(s[k], e[k])[base[:2]]).sum()) for k in range(stop + 1, stop + 4)]
    print(f"{a.checkpoint}: mean |vx|+|vy| predicted in the 3 frames after the stop over "
          f"{min(a.summary_episodes, df.episode_index.nunique())} episodes: {np.mean(after):.3f} m/s (data 0)")


if __name__ == "__main__":
    main()
