"""Where the expert closes its hand on a drawer's bar, over a recorded open_drawer state set.

Per episode of a LeRobot dataset written by a ``demos`` step with ``environment_state`` and
``environment_gripper`` (``jobs/policies_state_armdart.toml``, ``jobs/policies_state_steady.toml``):
- close: the first frame whose action commands the gripper shut (> 0.5);
- ee - handle [m]: the measured end effector (``observation.state``'s ee_x/y/z, base frame) minus
  the handle's grasp centre (``observation.environment_state``'s handle_x/y/z) at the close;
- pull: the first frame from the close on that commands the base back with the hand shut
  (``open_pull_probe.pull_frames``: ``base_vx`` < -0.02 m/s), its gap to the close [frames] and the fingers' opening there (the state's last entry) [m].

Prints the first episodes and the spread: |ee - handle| median / p90 / max, the gap's median and p90.
Session 27: DART noise on the arm up to the grip (``open_armdart``) closes the hand a median 7.5 mm
(max 22 mm) off the bar's centre; the steady grasp (``open_steady``) 0.4 mm (max 0.7 mm).

Run::

    .venv/bin/python tests/benchmarks/grasp_spread.py DATASET [--show 12]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from open_pull_probe import pull_frames  # noqa: E402  (tests/benchmarks, the script's folder)


def spread(root: Path) -> np.ndarray:
    """Rows (episode, close frame, pull gap [frames], ee - handle x, y, z [m], opening at the close,
    opening at the pull [m]) of every episode in dataset ``root``."""
    import pyarrow.parquet as pq

    from stages.dataset.view import feature_names

    sn, an = feature_names(root), feature_names(root, "action")
    en = feature_names(root, "observation.environment_state") or []
    if not en or en[-1] != "gripper_opening" or en[:3] != ["handle_x", "handle_y", "handle_z"]:
        raise SystemExit(f"{root}: needs an open/close set with the gripper entry, has {en}")
    files = sorted((root / "data").rglob("*.parquet"))
    cols = ["episode_index", "observation.state", "observation.environment_state", "action"]
    t = {k: [] for k in cols}
    for f in files:
        tab = pq.read_table(f, columns=cols)
        for k in cols:
            t[k].extend(tab.column(k).to_pylist())
    ep = np.asarray(t["episode_index"])
    S, E, A = (np.asarray(t[k], float) for k in cols[1:])
    ee = [sn.index(f"ee_{c}") for c in "xyz"]
    g, vx = an.index("gripper"), an.index("base_vx")
    rows = []
    for e in np.unique(ep):
        i = np.flatnonzero(ep == e)
        c, pull = pull_frames(A[i], vx, g)
        if c < 0:
            continue
        p = int(pull[0]) if len(pull) else -1
        rows.append((e, c, p - c if p >= 0 else -1, *(S[i[c], ee] - E[i[c], :3]), E[i[c], -1],
                     E[i[p], -1] if p >= 0 else np.nan))
    return np.array(rows, float)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dataset", type=Path)
    ap.add_argument("--show", type=int, default=12, help="episodes to print")
    a = ap.parse_args()
    o = spread(a.dataset)
    np.set_printoptions(precision=4, suppress=True, linewidth=150)
    print("episode close gap ee-handle(x, y, z) opening@close opening@pull")
    print(o[:a.show])
    d = np.linalg.norm(o[:, 3:6], axis=1)
    gap = o[o[:, 2] >= 0, 2]
    print(f"{a.dataset.name}: {len(o)} episodes; |ee - handle| at the close median {np.median(d):.4f} "
          f"p90 {np.percentile(d, 90):.4f} max {d.max():.4f} m; close to pull median {np.median(gap):.0f} "
          f"p90 {np.percentile(gap, 90):.0f} frames")


if __name__ == "__main__":
    main()
