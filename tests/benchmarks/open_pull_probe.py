"""Open-loop probe of an open_drawer state policy at the pull (issue 17, session 26).

open_drawer's expert closes the hand on the bar, then backs the base away holding it (arm fixed in the base frame,
only the opening grows). In closed loop the session-26 policy reaches the bar but often does not pull, or stops
part way (README). This probe asks whether it fits that phase on its own training frames: for each episode of a
training dataset (or state view) it finds the close (the first frame whose ``gripper`` command exceeds 0.5) and
the pull (the frames after it whose ``base_vx`` command is below -0.02 m/s), and compares the policy's first
action from a fresh chunk (no ensembling history) with the recorded one: ``base_vx`` [m/s] and ``gripper``.

    python tests/benchmarks/open_pull_probe.py CHECKPOINT VIEW [--episodes 0,5] [--summary-episodes 50]

Prints per probed episode the frames close, pull start -3, pull start, +10, +30, pull end, end +3, and a summary
line: over the pull frames of the first episodes, the mean predicted and recorded ``base_vx`` and the share of
pull frames where the policy commands less than half the recorded pull speed.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from policy_probe import probe_args, probe_setup  # noqa: E402  (tests/benchmarks, the script's folder)

PULL_VX = -0.02  # [m/s] a frame pulls when its base_vx command is below this


def pull_frames(act: np.ndarray, vx: int, grip: int) -> tuple[int, np.ndarray]:
    """(close frame, indices of the pull's frames) of one episode's actions (T, A)."""
    closed = np.flatnonzero(act[:, grip] > 0.5)
    if not len(closed):
        return -1, np.zeros(0, int)
    c = int(closed[0])
    after = np.arange(c, len(act))
    return c, after[(act[after, vx] < PULL_VX) & (act[after, grip] > 0.5)]


def main() -> None:
    a = probe_args(__doc__)
    an, df, first_action = probe_setup(a.checkpoint, a.view)
    vx, grip = an.index("base_vx"), an.index("gripper")

    def episode(idx: int):
        g = df[df.episode_index == idx]
        return (np.stack(g["observation.state"].values), np.stack(g["observation.environment_state"].values),
                np.stack(g["action"].values))

    for idx in (int(x) for x in a.episodes.split(",")):
        s, e, act = episode(idx)
        c, pull = pull_frames(act, vx, grip)
        if not len(pull):
            print(f"ep {idx}: no pull")
            continue
        p0, p1 = int(pull[0]), int(pull[-1])
        for name, k in (("close", c), ("pull-3", p0 - 3), ("pull", p0), ("pull+10", p0 + 10), ("pull+30", p0 + 30),
                        ("pull end", p1), ("end+3", p1 + 3)):
            k = min(max(k, 0), len(s) - 1)
            y = first_action(s[k], e[k])
            print(f"ep {idx} {name:8s} frame {k:4d}: base_vx {y[vx]:+.3f} (data {act[k, vx]:+.3f})  gripper "
                  f"{y[grip]:.2f} (data {act[k, grip]:.2f})  opening {e[k, 3]:.3f} m")
    pred, data = [], []
    for idx in sorted(df.episode_index.unique())[:a.summary_episodes]:
        s, e, act = episode(int(idx))
        _, pull = pull_frames(act, vx, grip)
        for k in pull[::5]:
            pred.append(first_action(s[k], e[k])[vx])
            data.append(act[k, vx])
    pred, data = np.array(pred), np.array(data)
    print(f"{a.checkpoint}: over {len(data)} pull frames (every 5th) of {min(a.summary_episodes, df.episode_index.nunique())} "
          f"episodes: base_vx predicted {pred.mean():+.3f}, recorded {data.mean():+.3f} m/s; "
          f"predicted below half the recorded pull in {np.mean(pred > 0.5 * data):.0%}")


if __name__ == "__main__":
    main()
