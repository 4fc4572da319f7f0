"""Extra ``agentworld`` subcommands contributed by stage modules.

``COMMANDS`` maps a subcommand name (e.g. ``"render-layout"``) to ``("module:function", help)``:
``function(argv: list[str]) -> int`` parses its own arguments and returns the exit status; help is
the one line ``agentworld --help`` shows. The CLI imports a module only when its subcommand runs.
One entry per command; the built-in names (run, ingest, catalog, status) cannot be overridden.
"""

COMMANDS: dict[str, tuple[str, str]] = {
    "eval": ("stages.policy.cli:eval_main",
             "evaluate a lerobot policy checkpoint closed-loop in held-out task kitchens (success, reasons, videos)"),
    "loco-eval": ("stages.locomotion.cli:eval_main",
                  "evaluate a G1 velocity policy: tracking error [m/s, rad/s] and falls over R rollouts"),
    "loco-export": ("stages.locomotion.cli:export_main",
                    "export a G1 velocity checkpoint as TorchScript with its config and reward curve"),
    "loco-house": ("stages.locomotion.cli:house_main",
                   "a G1 walks through a doorway with a threshold and up the stairs of a generated house"),
    "loco-runtime": ("stages.locomotion.cli:runtime_main",
                     "G1 worlds through the humanoid runtime (policy + CLIK hands): tracking, hand error, falls"),
    "loco-train": ("stages.locomotion.cli:train_main",
                   "train the G1 velocity-tracking policy with PPO on N Newton worlds; resumes from checkpoints"),
    "train-policy": ("stages.policy.cli:train_main",
                     "train ACT or Diffusion Policy on a dataset with lerobot-train; curve CSV/PNG, wall time"),
    "teleop": ("stages.teleop.cli:main",
               "teleoperate a task world from a browser (keyboard) and record episodes; --replay a session"),
    "record-table": ("stages.demos.table_record:cli",
                     "record the dexterous hands' and the dual-arm platform's table tasks: shards, success, sheets"),
    "record-table-summary": ("stages.demos.table_summary:cli",
                             "sum record-table runs (e.g. several seeds of a pair) into the per-pair success table"),
    "render-assets": ("stages.render_assets:main",
                      "contact sheet PNG per category of a catalog's assets (Newton SensorCamera, CPU)"),
    "render-dataset": ("stages.dataset.render:cli",
                       "contact sheet PNG of a LeRobot dataset's camera frames (RGB and depth)"),
    "render-layout": ("stages.layout.render:cli",
                      "generate a house; write its top-down plan PNG and a 3D render PNG"),
    "render-scenes": ("stages.scene.render:cli",
                      "contact sheet PNG of a scene job's populated scenes, one camera per room"),
}
