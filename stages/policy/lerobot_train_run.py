"""``python -m stages.policy.lerobot_train_run CURVE.csv [--deadline T] [--frame-cache DIR] [--cameras LIST] -- <args>``.

Runs lerobot's own training entry point (``lerobot.scripts.lerobot_train:main``, what the
``lerobot-train`` command runs) with the given arguments, in this process, offline. One addition: a
logging handler receives lerobot's metrics tracker at every log step (``--log_freq``) and appends a
row to ``CURVE.csv``: step, samples, epochs, loss and the policy's sub-losses, gradient norm,
learning rate, update and data-loading time per step [s], and the wall time since start [s].
(lerobot's console line rounds the step to thousands, "step:2K"; the tracker has the exact values.)
It is a filter of the root logger, which lerobot's ``init_logging`` keeps (it replaces handlers).

``--memory-frames`` (first, before the others): samples are read from the dataset's columns held in
memory (:mod:`stages.policy.memory_frames`: the same items, ~25x faster for a policy of no camera).

``--cameras LIST`` (comma-separated camera names, empty for none): the policy takes only these of the
dataset's RGB cameras (``observation.images.<camera>``) and the data loader decodes only their videos (no depth)
(a policy of no camera takes the state and ``observation.environment_state``).

``--deadline T`` (Unix time [s]): the first step that ends at or after T is a checkpoint step
(lerobot saves it and points ``checkpoints/last`` at it), and training stops before the next update;
``CURVE.csv``'s folder then gets ``stopped.json`` (the step reached); two of lerobot-train's module
functions are wrapped for this (``should_save_checkpoint``, ``update_policy``). ``--frame-cache DIR``:
the data loader reads RGB video frames through :mod:`stages.policy.frame_cache` (each video decoded
once into DIR, then memory-mapped: about 4x fewer CPU seconds per sample).
"""

from __future__ import annotations

import csv
import json
import logging
import os
import sys
import time
from pathlib import Path

# curve columns; sub-losses of a policy (ACT: l1_loss, kld_loss) follow as they appear
CURVE_COLUMNS = ("step", "samples", "epochs", "loss", "grad_norm", "lr", "update_s", "data_s", "wall_s")
_TRACKER_NAMES = {"loss": "loss", "grad_norm": "grad_norm", "lr": "lr", "update_s": "update_s",
                  "data_s": "dataloading_s"}  # curve column -> lerobot's tracker metric


class CurveFilter(logging.Filter):
    """Writes a CSV row per logged metrics tracker (``lerobot.utils.logging_utils.MetricsTracker``);
    lets every record through."""

    def __init__(self, path: Path) -> None:
        super().__init__()
        self.path = Path(path)
        self.t0 = time.perf_counter()
        self.columns: list[str] | None = None

    def filter(self, record: logging.LogRecord) -> bool:
        tracker = record.msg
        if hasattr(tracker, "steps") and hasattr(tracker, "metrics"):
            self._write(tracker)
        return True

    def _write(self, tracker) -> None:
        metrics = tracker.metrics
        row = {"step": int(tracker.steps), "samples": int(tracker.samples), "epochs": f"{tracker.epochs:.4f}",
               "wall_s": f"{time.perf_counter() - self.t0:.2f}"}
        for col, name in _TRACKER_NAMES.items():
            row[col] = f"{float(metrics[name].avg):.6g}" if name in metrics else ""
        known = set(_TRACKER_NAMES.values()) | {"samples_per_s"}
        for name, meter in metrics.items():
            if name not in known:
                row[name] = f"{float(meter.avg):.6g}"
        new = self.columns is None
        if new:
            self.columns = [*CURVE_COLUMNS, *(k for k in row if k not in CURVE_COLUMNS)]
        with self.path.open("a", newline="") as f:
            w = csv.DictWriter(f, fieldnames=self.columns, extrasaction="ignore")
            if new:
                w.writeheader()
            w.writerow(row)


FRAME_CACHE_ENV = "AGENTWORLD_FRAME_CACHE"
MEMORY_ENV = "AGENTWORLD_MEMORY_FRAMES"
CAMERAS_ENV = "AGENTWORLD_TRAIN_CAMERAS"
IMAGES = "observation.images."


def _install_frame_cache() -> None:
    """With ``AGENTWORLD_FRAME_CACHE`` set, read RGB video frames through the frame cache there. Run at
    import too: lerobot's data loader workers are spawned processes that import this (the main)
    module afresh and inherit the environment, not the parent's patched classes."""
    if os.environ.get(FRAME_CACHE_ENV):
        from stages.policy.frame_cache import install

        install(os.environ[FRAME_CACHE_ENV])


def _install_cameras() -> None:
    """With ``AGENTWORLD_TRAIN_CAMERAS`` set (comma-separated, empty for none), the policy's features
    and the data loader's video queries keep only those RGB cameras (run at import, as the frame cache)."""
    if CAMERAS_ENV not in os.environ:
        return
    keep = {IMAGES + c for c in os.environ[CAMERAS_ENV].split(",") if c}
    from lerobot.datasets.dataset_reader import DatasetReader
    from lerobot.policies import factory

    if getattr(DatasetReader._query_videos, "agentworld_cameras", False):
        return
    features_of, query = factory.dataset_to_policy_features, DatasetReader._query_videos

    def dataset_to_policy_features(features):
        return {k: v for k, v in features_of(features).items() if not k.startswith(IMAGES) or k in keep}

    def _query_videos(self, query_timestamps, ep_idx):
        wanted = {k: v for k, v in query_timestamps.items() if k in keep}  # depth: no policy input
        return query(self, wanted, ep_idx) if wanted else {}

    _query_videos.agentworld_cameras = True
    factory.dataset_to_policy_features = dataset_to_policy_features
    DatasetReader._query_videos = _query_videos


def _install_memory_frames() -> None:
    """With ``AGENTWORLD_MEMORY_FRAMES=1``, samples are read from columns in memory
    (:mod:`stages.policy.memory_frames`; run at import, as the frame cache)."""
    if os.environ.get(MEMORY_ENV) == "1":
        from stages.policy.memory_frames import install

        install()


_install_frame_cache()
_install_cameras()
_install_memory_frames()


class _Deadline(Exception):
    """Raised before the update after the deadline's checkpoint step (ends the training loop)."""


def install_deadline(lerobot_train, deadline: float, stopped: Path) -> None:
    """Make the first step ending at or after ``deadline`` (Unix time [s]) a checkpoint step and stop
    before the next update, writing ``stopped`` ({"step", "deadline"}); see the module docstring."""
    state: dict = {"step": None}
    save, update = lerobot_train.should_save_checkpoint, lerobot_train.update_policy

    def should_save_checkpoint(step, save_freq, total_steps):
        if state["step"] is None and step < total_steps and time.time() >= deadline:
            state["step"] = step
            return True
        return save(step, save_freq, total_steps)

    def update_policy(*args, **kwargs):
        if state["step"] is not None:
            stopped.write_text(json.dumps({"step": state["step"], "deadline": deadline}) + "\n")
            raise _Deadline
        return update(*args, **kwargs)

    lerobot_train.should_save_checkpoint = should_save_checkpoint
    lerobot_train.update_policy = update_policy


def main(argv: list[str]) -> int:
    deadline = frames = cameras = None
    while len(argv) >= 3 and argv[1] == "--memory-frames":
        os.environ[MEMORY_ENV] = "1"  # here, and in the data loader's spawned workers
        _install_memory_frames()
        argv = [argv[0], *argv[2:]]
    while len(argv) >= 4 and argv[1] in ("--deadline", "--frame-cache", "--cameras"):
        if argv[1] == "--deadline":
            deadline = float(argv[2])
        elif argv[1] == "--cameras":
            cameras = argv[2]
        else:
            frames = Path(argv[2])
        argv = [argv[0], *argv[3:]]
    if len(argv) < 2 or argv[1] != "--":
        print("usage: python -m stages.policy.lerobot_train_run CURVE.csv [--memory-frames] [--deadline UNIX_TIME] "
              "[--frame-cache DIR] [--cameras LIST] -- "
              "<lerobot-train arguments>", file=sys.stderr)
        return 2
    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    os.environ.setdefault("HF_DATASETS_DISABLE_PROGRESS_BARS", "1")
    from lerobot.scripts import lerobot_train

    curve = Path(argv[0])
    curve.unlink(missing_ok=True)
    (curve.parent / "stopped.json").unlink(missing_ok=True)
    logging.getLogger().addFilter(CurveFilter(curve))
    if deadline is not None:
        install_deadline(lerobot_train, deadline, curve.parent / "stopped.json")
    if frames is not None:  # here, and in the data loader's spawned workers (they import this module)
        os.environ[FRAME_CACHE_ENV] = str(frames)
        _install_frame_cache()
    if cameras is not None:  # after the frame cache: the camera filter wraps its query
        os.environ[CAMERAS_ENV] = cameras
        _install_cameras()
    sys.argv = ["lerobot-train", *argv[2:]]
    try:
        lerobot_train.main()
    except _Deadline:
        logging.info("stopped at the deadline after step %s", json.loads((curve.parent / "stopped.json").read_text()))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
