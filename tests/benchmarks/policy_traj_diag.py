"""Trajectory diagnostics of a pick_place_bowl or open_drawer policy in closed loop (issue 17, sessions 24, 26).

Runs ``agentworld eval``'s evaluator with an observer that keeps what the policy saw at every frame
(``observation.state``: the end effector in the base frame; ``observation.environment_state``: the
mug and the bowl in the base frame) and prints per episode: the start distance of the mug from the
base, the closest end-effector approach to the mug's origin and its offset (x, y, z [m]), the mug's
largest lift and its final distance from the bowl. The scripted expert closes the gripper 0.080 m
above the mug's origin (2.5 cm below the rim); a grasp from 0.10-0.11 m lifts the mug ~3.5 cm and drops it.
Both tasks also print where the policy first commands the gripper shut (action ``gripper`` > 0.5): the end
effector's offset from the mug or the drawer's handle then (x, y, z [m], base frame).

open_drawer (``--task open_drawer``; environment state: the handle's grasp centre and the opening [m]): the
closest approach to the handle and its offset, the frame of the first close command, the pull (the first frame
after it commanding the base back; with the gripper entry the fingers' opening then and 15 frames on), the base
travel commanded from the close on (the ``base_vx`` commands integrated [m]; the expert backs away holding the
bar), the largest and the final opening [m].

    python tests/benchmarks/policy_traj_diag.py CHECKPOINT --scenes 101 --seeds 1000000-1000009 --out /tmp/diag \\
        [--task open_drawer] [--arm-command ee] [--ensemble-coeff -0.1] [--action-steps 10]

Writes OUT/eval.json and OUT/traj.json (per episode: the record, the per-frame observations and actions).
open_drawer with ``--training-dataset`` (its environment state with the gripper entry) also prints the expert's
reference from that dataset: the measured end effector's offset from the handle at the close command [mm] and the
fingers' opening 8 frames on [m], as percentiles over its episodes (session 29: the expert closes within ~0.6 mm,
opening 0.0117 m; policies that slip at the pull close 9-16 mm off, opening 0.016-0.019 m), and each episode's
line then ends with the fingers' opening 8 frames after the close command and the hand's rotation then from the
expert's median hand orientation at that frame (rotation vector in the hand frame [deg]; session 29: the failing
grasps turn 0.19-0.36 deg about y, the expert's p95 is 0.23).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))


def _ints(text: str) -> tuple[int, ...]:
    a, _, b = text.partition("-")
    return tuple(range(int(a), int(b or a) + 1))


EE_QUAT = ("ee_qw", "ee_qx", "ee_qy", "ee_qz")  # the hand's orientation in observation.state, (w, x, y, z)


def _close_frame(t: dict) -> int | None:
    """The first frame whose action commands the gripper shut (``gripper`` > 0.5); None: none does."""
    if not t.get("actions"):
        return None
    g = np.array([a[t["action_names"].index("gripper")] for a in t["actions"]])
    return int(np.argmax(g > 0.5)) if (g > 0.5).any() else None


def _close(t: dict, ee: np.ndarray, obj: np.ndarray) -> str:
    """The first frame whose action commands the gripper shut, and the end effector's offset then."""
    c = _close_frame(t)
    if c is None:
        return "close=never"
    k = min(c, len(ee) - 1)
    return f"close@{k} offset={np.round(ee[k] - obj[k], 3)}"


def _pull(t: dict, e: np.ndarray, fps: float) -> str:
    """open_drawer after the first close command: the first frame commanding the base back (``base_vx`` < -0.02
    m/s), the gripper's opening [m] then and 15 frames on (the environment state's last entry, with the gripper
    entry: ~0.012 on the drawer's bar, below it closed on nothing) and the base travel commanded from the close on [m]."""
    if not t.get("actions"):
        return "pull=?"
    vx = np.array(t["actions"])[:, t["action_names"].index("base_vx")]
    c = _close_frame(t)
    if c is None:
        return "pull=never"
    back = np.flatnonzero(vx[c:] < -0.02)
    travel = f"travel_after_close={vx[c:].sum() / fps:+.2f} m"
    if not len(back):
        return f"pull=never {travel}"
    k = c + int(back[0])
    grip = (f" grip@pull={e[min(k, len(e) - 1), -1]:.3f} grip@pull+15={e[min(k + 15, len(e) - 1), -1]:.3f}"
            if e.shape[1] > 4 else "")
    return f"pull@{k}{grip} {travel}"


def _quat_rot(q):
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat([q[1], q[2], q[3], q[0]])  # (w, x, y, z) -> scipy's (x, y, z, w)


def _grasp(t: dict, s: np.ndarray, e: np.ndarray, ref) -> str:
    """The opening [m] 8 frames after the first close command and the hand's rotation then from ``ref`` (the
    expert's median orientation; rotation vector in the hand frame [deg])."""
    c = _close_frame(t)
    if c is None:
        return ""
    k = min(c + 8, len(s) - 1)
    q = s[k, [t["state_names"].index(n) for n in EE_QUAT]]
    rv = np.degrees((ref.inv() * _quat_rot(q)).as_rotvec())
    return f" open@close+8={e[k, -1]:.4f} rot@close+8={np.round(rv, 2).tolist()} deg"


def expert_grasp(dataset: Path):
    """The expert's drawer grasp in ``dataset`` (a LeRobot v3 set with ``ee_*`` state entries and the environment
    state's handle, opening, ..., gripper_opening): percentiles (5, 50, 95) over episodes of the measured end
    effector's offset from the handle at the first close command [mm] and of the opening 8 frames on [m], as a line;
    and the expert's median hand orientation 8 frames on (a scipy Rotation). Returns ``(line, rotation)``."""
    import pandas as pd

    from stages.dataset.view import feature_names

    snames, anames = feature_names(dataset), feature_names(dataset, "action")
    ix, qi = [snames.index(c) for c in ("ee_x", "ee_y", "ee_z")], [snames.index(c) for c in EE_QUAT]
    gi = anames.index("gripper")
    df = pd.concat([pd.read_parquet(f) for f in sorted((dataset / "data").rglob("*.parquet"))])
    off, opening, quats = [], [], []
    for _, g in df.groupby("episode_index"):
        a, st = np.stack(g["action"].to_numpy()), np.stack(g["observation.state"].to_numpy())
        e = np.stack(g["observation.environment_state"].to_numpy())
        if not (a[:, gi] > 0.5).any():
            continue
        c = int(np.argmax(a[:, gi] > 0.5))
        off.append((st[c, ix] - e[c, :3]) * 1000)
        opening.append(e[min(c + 8, len(e) - 1), -1])
        quats.append(st[min(c + 8, len(st) - 1), qi])
    q, med = (5, 50, 95), np.median(quats, axis=0)
    return (f"expert ({len(off)} episodes of {dataset.name}): offset at close [mm] x/y/z p5,p50,p95 = "
            f"{np.round(np.percentile(off, q, axis=0).T, 1).tolist()}; opening at close+8 [m] = "
            f"{np.round(np.percentile(opening, q), 4).tolist()}"), _quat_rot(med / np.linalg.norm(med))


def summary(trajs: list[dict], task: str = "pick_place_bowl", fps: float = 30.0, ref=None) -> list[str]:
    """One line per episode (see the module docstring); ``ref``: the expert's hand orientation (expert_grasp)."""
    lines = []
    for t in trajs:
        r, log = t["rec"], t["log"]
        s = np.array([x[1] for x in log])
        e = np.array([x[2] for x in log])
        names = t["state_names"]
        ee = s[:, [names.index(c) for c in ("ee_x", "ee_y", "ee_z")]]
        obj = e[:, 0:3]
        d = np.linalg.norm(ee - obj, axis=1)
        k = int(np.argmin(d))
        head = (f"{r['seed']} {'ok ' if r['success'] else 'BAD'} {r['reason'][:24]:24s} frames={len(log)} "
                f"start={np.linalg.norm(obj[0, :2]):.2f} m closest={d.min():.3f} m offset={np.round(ee[k] - obj[k], 3)} ")
        if task == "open_drawer":
            lines.append(head + f"{_close(t, ee, obj)} {_pull(t, e, fps)} max_open={e[:, 3].max():.3f} m "
                                f"final_open={e[-1, 3]:.3f} m" + (_grasp(t, s, e, ref) if ref is not None else ""))
        else:
            tgt = e[:, 3:6]
            lines.append(head + f"{_close(t, ee, obj)} lift={(obj[:, 2] - obj[0, 2]).max():.3f} m "
                                f"final_to_bowl={np.linalg.norm(obj[-1] - tgt[-1]):.3f} m")
    return lines


def main() -> int:
    from stages.policy.evaluate import EvalConfig, evaluate
    from stages.policy.runner import load_policy

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("checkpoint", type=Path)
    p.add_argument("--task", default="pick_place_bowl", choices=("pick_place_bowl", "open_drawer"))
    p.add_argument("--scenes", default="101")
    p.add_argument("--seeds", default="1000000-1000009")
    p.add_argument("--worlds", type=int, default=10)
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--work", type=Path, default=None)
    p.add_argument("--arm-command", default="joints")
    p.add_argument("--ensemble-coeff", type=float, default=None)
    p.add_argument("--action-steps", type=int, default=None)
    p.add_argument("--training-dataset", type=Path, default=None)
    a = p.parse_args()
    names = load_policy(a.checkpoint).state_names
    log: dict[int, list] = {}
    acts: dict[int, list] = {}
    trajs: list[dict] = []
    from stages.engine import EngineConfig

    action_names = EngineConfig().dataset_spec().action_names()

    def observe(w, frame, obs):
        log.setdefault(w, []).append((frame, obs["observation.state"].tolist(),
                                      obs["observation.environment_state"].tolist()))

    def act(w, frame, action):
        acts.setdefault(w, []).append([float(x) for x in action])

    def done(rec):
        trajs.append({"rec": {k: getattr(rec, k) for k in ("task", "scene", "seed", "success", "reason", "frames")},
                      "state_names": list(names) if names else None, "log": log.pop(rec.world, []),
                      "action_names": list(action_names), "actions": acts.pop(rec.world, [])})

    cfg = EvalConfig(checkpoint=a.checkpoint, tasks=(a.task,), scenes=_ints(a.scenes), seeds=_ints(a.seeds),
                     worlds=a.worlds, device="cpu", videos=0, arm_command=a.arm_command,
                     ensemble_coeff=a.ensemble_coeff, action_steps=a.action_steps, training_dataset=a.training_dataset)
    evaluate(cfg, a.out, work_dir=a.work, observers=[observe], episode_listeners=[done], action_listeners=[act])
    if names is None:  # a checkpoint without agentworld_policy.json takes the recorder's whole state
        for t in trajs:
            t["state_names"] = EngineConfig().dataset_spec().state_names()
    (a.out / "traj.json").write_text(json.dumps(trajs))
    line, ref = (expert_grasp(a.training_dataset) if a.task == "open_drawer" and a.training_dataset is not None
                 else (None, None))
    print("\n".join(summary(trajs, a.task, cfg.fps, ref)))
    if line:
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
