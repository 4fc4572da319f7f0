"""Record the table tasks of the dexterous hands and the dual-arm platform
(:mod:`stages.demos.table_tasks`) as LeRobot shards, with success counts, failure reasons and a
contact sheet per embodiment-task pair.

Command (``agentworld record-table``)::

    agentworld record-table OUT [--pairs allegro/pick_place_mug,aloha/lift_tray,...] [--episodes 30]
        [--seed 0] [--no-images] [--width 128 --height 96] [--fps 30] [--catalog WORK_DIR]

writes, per pair ``<emb>/<task>``:

- ``OUT/shards/<emb>-<task>``: a LeRobot v3.0 dataset (:func:`stages.dataset.open_shard`) of the
  successful episodes (failed ones are counted, not written), in the embodiment's layout
  (:func:`dataset_spec`); it loads with ``LeRobotDataset`` (:func:`stages.dataset.load_dataset`);
- ``OUT/sheets/<emb>-<task>.png``: its contact sheet (:func:`stages.dataset.render.render_contact_sheet`);
- ``OUT/report.json``: attempts, successes, failure reasons, wall and simulated seconds per episode
  for every pair, and each episode's sample and measurements;
- ``OUT/summary.json`` and, printed at the end, one line per pair: successes / episodes, failure
  reasons, whether the pair meets the issue's 80 % bar (:mod:`stages.demos.table_summary`; runs
  of one pair with other seeds, e.g. on several hosts, sum with ``agentworld record-table-summary
  OUT1 OUT2 ...``).

The hand tasks' mug, can and counter are the default catalog's ``mug_04``, ``can_00`` and
``kitchen_counter_00``: built by a two-step job in ``OUT/catalog_job`` (default catalog, ingest of
the packages the pairs need; cached after the first run) unless ``--catalog`` names a work dir that
holds them (``assets/<id>``).

Why not the batched engine (:mod:`stages.engine`): its worlds are kitchens (``KitchenWorld``: the
robot is the mobile Panda written by ``stages.simulate.robot``, free objects mug / bowl / pusher, the
microwave button watched) and its episodes are the kitchen tasks' experts. A dexterous hand rides
on it only as teleoperation's ``EngineConfig.gripper``; the dual-arm platform not at all. The table
tasks run here in one :class:`~stages.simulate.world.Sim` per pair, episode after episode (MuJoCo C
on the CPU), and record the same frames the engine would.
"""

from __future__ import annotations

import argparse
import json
import logging
import time
from collections import Counter
from pathlib import Path

import numpy as np

from stages.demos.record import EpisodeTimeout, base_pose, pose7
from stages.demos.table_summary import summarize_runs, summary_table, write_json
from stages.demos.table_tasks import PACKAGES, PAIRS, TableRig, build_rig, instruction, run_expert

log = logging.getLogger(__name__)

MAX_SECONDS = 40.0  # [s] simulated time limit of an episode


def dataset_spec(rig: TableRig, *, images: bool = True, width: int = 128, height: int = 96, fps: int = 30):
    """The :class:`stages.dataset.DatasetSpec` of a pair: a hand records its joints (``hand_joints``);
    the dual-arm platform both arms (``arms``). Cameras: the robot's link cameras (the Panda's wrist
    and head; the platform's two wrist cameras) and a fixed third-person camera."""
    from stages.dataset import CameraSpec, DatasetSpec

    cams = (*rig.desc.cameras, "third_person") if images else ()
    cameras = tuple(CameraSpec(c, height=height, width=width) for c in cams)
    if rig.embodiment == "aloha":
        return DatasetSpec(arm_dof=len(rig.desc.arm_joints), fps=fps, robot_type="agentworld_dual_arm",
                           cameras=cameras, arms=tuple(rig.desc.arms))
    return DatasetSpec(arm_dof=len(rig.desc.arm_joints), fps=fps, robot_type=f"agentworld_mobile_panda_{rig.embodiment}",
                       cameras=cameras, hand_joints=tuple(rig.desc.gripper.hand.joints))


def camera_rig(rig: TableRig, spec):
    """The CameraRig of ``spec``'s cameras (None without cameras): the third-person camera looks at
    the table from across it, to the robot's left (the drawer tasks: from the robot's left, before
    the counter)."""
    from stages.simulate.sensors import CameraRig, CameraSpec, look_at

    if not spec.cameras:
        return None
    cams = []
    for c in spec.cameras:
        if c.name == "third_person":
            eye, target = ((0.1, 1.3, 1.6), (0.55, 0.0, 0.9)) if rig.task == "open_double_door" else \
                ((1.6, 0.9, 1.4), (0.4, 0.0, 0.6)) if rig.embodiment == "aloha" else \
                ((0.15, 1.1, 1.45), (0.5, 0.0, 0.7)) if rig.task.endswith("drawer") else \
                ((1.45, 0.6, 1.2), (0.72, 0.0, 0.62))
            cams.append(CameraSpec(name=c.name, width=c.width, height=c.height, vertical_fov=1.0,
                                   pose=look_at(eye, target)))
        else:
            m = rig.desc.cameras[c.name]
            cams.append(CameraSpec(name=c.name, width=c.width, height=c.height, vertical_fov=m.vertical_fov,
                                   link=m.link))
    return CameraRig(rig.sim, cams, segmentation=False)


class TableRecorder:
    """Pre-step callback of ``rig.sim`` capturing frames of ``spec`` at its fps into ``sink`` while
    active (:meth:`start` / :meth:`stop`); ``cams``: the :func:`camera_rig`. Raises
    :class:`~stages.demos.record.EpisodeTimeout` past ``max_seconds`` of an episode."""

    def __init__(self, rig: TableRig, spec, cams=None) -> None:
        self.rig, self.spec, self.cams = rig, spec, cams
        self.active, self.sink, self.frames = False, None, 0
        self._t0 = 0.0
        self._next = 0
        self.max_seconds = MAX_SECONDS
        self.render_seconds = 0.0
        rig.sim.pre_step.append(self)

    def start(self, sink, max_seconds: float = MAX_SECONDS) -> None:
        self.sink, self.max_seconds = sink, max_seconds
        self.active, self.frames, self._next, self._t0 = True, 0, 0, self.rig.sim.time

    def stop(self) -> None:
        self.active, self.sink = False, None

    def __call__(self, sim) -> None:
        if not self.active:
            return
        t = sim.time - self._t0
        if t > self.max_seconds:
            self.active = False
            raise EpisodeTimeout(f"episode ran past {self.max_seconds:.1f} s")
        if t + 1e-9 < self._next / self.spec.fps:
            return
        self._next += 1
        self.sink(self.frame())
        self.frames += 1

    def frame(self):
        """The current :class:`stages.dataset.Frame` (state, commands in force, images)."""
        from stages.dataset import Frame, depth_m_to_mm

        rig, sim, ctl = self.rig, self.rig.sim, self.rig.ctl
        jq = sim.state_0.joint_q.numpy()
        q = np.array([jq[sim.world_coord(n)] for n in rig.desc.arm_joints])
        target = ctl.arm_targets()
        extra = {}
        if rig.embodiment == "aloha":
            ee, ee_t = self._arm_poses(q), self._arm_poses(target)
            gripper = np.array([ctl.commands[a] for a in rig.desc.arms])
        else:
            q0 = rig.ik.neutral()
            ee = pose7(rig.ik.fk(rig.ik.with_arm(q0, q)))
            ee_t = pose7(rig.ik.fk(rig.ik.with_arm(q0, target)))
            gripper = float(np.clip(ctl.commands.get(None, 0.0), 0.0, 1.0))
            fingers = rig.desc.gripper.finger_joints
            extra = {"hand_joint_pos": np.array([jq[sim.world_coord(n)] for n in fingers]),
                     "hand_joint_target": ctl.finger_targets()}
        rgb, depth = {}, {}
        if self.cams is not None:
            t0 = time.perf_counter()
            for name, fr in self.cams.render().items():
                rgb[name], depth[name] = fr.rgb[0], depth_m_to_mm(fr.depth[0])
            self.render_seconds += time.perf_counter() - t0
        return Frame(arm_joint_pos=q, ee_pose=ee, base_pose=base_pose(sim), arm_joint_target=target,
                     ee_target=ee_t, base_velocity=np.zeros(3), gripper=gripper, mode=1, rgb=rgb,
                     depth_mm=depth, **extra)

    def _arm_poses(self, arm_q: np.ndarray) -> np.ndarray:
        """Both TCP poses (14,) in the base frame for the arms' joints ``arm_q`` (12,)."""
        ik = self.rig.ik
        q = ik.clik.default_q()
        i = 0
        for name, a in self.rig.desc.arms.items():
            q[ik.clik.arms[name].q_idx] = arm_q[i:i + len(a.joints)]
            i += len(a.joints)
        return np.concatenate([pose7(ik.ee_pose(q, a)) for a in self.rig.desc.arms])


def record_pair(pair: str, out: Path, *, episodes: int, seed: int = 0, assets: dict | None = None,
                images: bool = True, width: int = 128, height: int = 96, fps: int = 30,
                shared_assets: Path | None = None) -> dict:
    """Run ``episodes`` episodes of ``pair`` and write its shard ``out/shards/<emb>-<task>``; returns
    the pair's report (attempts, successes, failures by reason, timings, episodes)."""
    from stages.dataset import EpisodeInfo, open_shard

    slug = pair.replace("/", "-")
    t_build = time.perf_counter()
    rig = build_rig(pair, Path(out) / "work" / slug, assets=assets, shared_assets=shared_assets, seed=seed)
    spec = dataset_spec(rig, images=images, width=width, height=height, fps=fps)
    rec = TableRecorder(rig, spec, camera_rig(rig, spec))
    build_s = time.perf_counter() - t_build
    results = []
    with open_shard(Path(out) / "shards", slug, spec) as shard:
        for k in range(episodes):
            ep_seed = seed * 100_003 + k
            sample = rig.reset(np.random.default_rng([seed, k, PAIRS.index(pair)]))
            shard.begin_episode(EpisodeInfo(task=instruction(rig, sample), task_kind=rig.task,
                                            scene_id=f"table_{slug}", seed=ep_seed, asset_ids=rig.asset_ids))
            t0, r0 = time.perf_counter(), rec.render_seconds
            rec.start(shard.add_frame)
            try:
                res = run_expert(rig, sample)
                ok, reason, detail = res.success, res.reason, res.detail
            except EpisodeTimeout as e:
                ok, reason, detail = False, "timeout", {"error": str(e)}
            finally:
                rec.stop()
            shard.end_episode(ok, reason)
            ep = {"episode": k, "seed": ep_seed, "success": ok, "reason": reason, "sample": sample,
                  "frames": rec.frames, "sim_seconds": round(rig.sim.time, 2),
                  "wall_seconds": round(time.perf_counter() - t0, 2),
                  "render_seconds": round(rec.render_seconds - r0, 2), "detail": detail}
            results.append(ep)
            log.info("%s episode %d: %s %s (%.1f s sim, %.1f s wall)", pair, k, "success" if ok else "FAILED",
                     reason, ep["sim_seconds"], ep["wall_seconds"])
    return summarize(pair, results, build_seconds=build_s)


def summarize(pair: str, results: list[dict], *, build_seconds: float = 0.0) -> dict:
    """A pair's report from its episodes' results."""
    n = len(results)
    wins = sum(r["success"] for r in results)
    mean = (lambda k: round(float(np.mean([r[k] for r in results])), 2)) if n else (lambda k: None)
    return {"pair": pair, "attempts": n, "successes": wins, "success_rate": round(wins / n, 3) if n else None,
            "failures": dict(Counter(r["reason"] for r in results if not r["success"])),
            "wall_seconds_per_episode": mean("wall_seconds"), "sim_seconds_per_episode": mean("sim_seconds"),
            "render_seconds_per_episode": mean("render_seconds"), "frames_per_episode": mean("frames"),
            "build_seconds": round(build_seconds, 2), "episodes": results}


def catalog_assets(work_dir: Path, catalog: Path | None = None, ids=None) -> dict:
    """The hand tasks' packages ``ids`` (default: every one of ``PACKAGES``) as
    :class:`stages.demos.packages.CatalogAsset`, from the work dir ``catalog`` or built by a two-step
    job in ``work_dir / "catalog_job"``."""
    from pipeline import build_job, run_job
    from stages.demos.packages import CatalogAsset

    ids = sorted(set(ids or PACKAGES.values()))
    out = Path(catalog) if catalog else Path(work_dir).resolve() / "catalog_job"
    if catalog is None:
        job = {"job": {"name": "table_catalog", "seed": 0, "out": str(out), "executor": "inline", "workers": 1},
               "step": [{"name": "catalog", "kind": "default_catalog",
                         "config": {"variants": 5, "categories": sorted({i.rsplit("_", 1)[0] for i in ids})}},
                        {"name": "assets", "kind": "ingest", "config": {"catalog_step": "catalog", "only": ids}}]}
        summary = run_job(build_job(job, source="<record-table>", base_dir=out.parent), progress=False)
        failed = {s.name: s.failed for s in summary.steps if s.failed}
        if failed:
            raise RuntimeError(f"record-table: building the packages {ids} failed in {out} ({failed}); see {out}/logs")
    gen = out / "catalog" / "default" / "generated.json"
    if not gen.is_file():
        raise FileNotFoundError(f"{gen}: no default catalog record in the work dir {out}")
    info = json.loads(gen.read_text())
    missing = [i for i in ids if i not in info or not (out / "assets" / i / f"{i}.usda").is_file()]
    if missing:
        raise FileNotFoundError(f"{out}: the work dir holds no ingested package {missing}")
    return {i: CatalogAsset(asset_id=i, category=info[i]["category"], usd=out / "assets" / i / f"{i}.usda",
                            info=info[i]) for i in ids}


def record_all(out: Path, pairs=PAIRS, *, episodes: int = 30, seed: int = 0, images: bool = True,
               sheets: bool = True, catalog: Path | None = None, **kwargs) -> dict:
    """Record every pair of ``pairs`` (see the module docstring); writes and returns the report."""
    from stages.dataset.render import render_contact_sheet

    out = Path(out)
    bad = [p for p in pairs if p not in PAIRS]
    if bad:
        raise ValueError(f"record-table: unknown pairs {bad}; known {list(PAIRS)}")
    ids = {PACKAGES[p.split("/")[1]] for p in pairs if p.split("/")[1] in PACKAGES}
    assets = catalog_assets(out, catalog, ids) if ids else None
    report = {"episodes_per_pair": episodes, "seed": seed, "images": images, "pairs": {}}
    for pair in pairs:
        rep = record_pair(pair, out, episodes=episodes, seed=seed, assets=assets, images=images, **kwargs)
        slug = pair.replace("/", "-")
        if sheets and images and rep["successes"]:
            rep["contact_sheet"] = str(render_contact_sheet(out / "shards" / slug, out / "sheets" / f"{slug}.png"))
        report["pairs"][pair] = rep
        _write_json(out / "report.json", report)
        write_json(out / "summary.json", summarize_runs({str(out): report}))
    return report


def _write_json(path: Path, data: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(data, indent=1, default=_jsonable))
    tmp.replace(path)


def _jsonable(v):
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, np.ndarray | set | frozenset | tuple):
        return list(v.tolist() if isinstance(v, np.ndarray) else v)
    raise TypeError(f"not JSON-able: {type(v)}")


def cli(argv: list[str]) -> int:
    """``agentworld record-table``: see the module docstring."""
    p = argparse.ArgumentParser(prog="agentworld record-table", description=__doc__.splitlines()[0])
    p.add_argument("out", type=Path)
    p.add_argument("--pairs", default=",".join(PAIRS), help=f"comma-separated, of {','.join(PAIRS)}")
    p.add_argument("--episodes", type=int, default=30)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--no-images", action="store_true", help="state and action only (success-rate runs)")
    p.add_argument("--width", type=int, default=128)
    p.add_argument("--height", type=int, default=96)
    p.add_argument("--fps", type=int, default=30)
    p.add_argument("--catalog", type=Path, default=None, help="a work dir holding assets/<id> of the pairs' packages")
    a = p.parse_args(argv)
    if a.episodes < 1 or a.fps < 1 or min(a.width, a.height) < 8:
        print("error: --episodes and --fps must be >= 1, --width/--height >= 8")
        return 2
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    try:
        report = record_all(a.out, tuple(x.strip() for x in a.pairs.split(",") if x.strip()), episodes=a.episodes,
                            seed=a.seed, images=not a.no_images, catalog=a.catalog, width=a.width,
                            height=a.height, fps=a.fps)
    except (ValueError, FileNotFoundError, RuntimeError) as e:
        print(f"error: {e}")
        return 2
    print(summary_table(summarize_runs({str(a.out): report})))
    return 0


if __name__ == "__main__":
    import sys

    sys.exit(cli(sys.argv[1:]))
