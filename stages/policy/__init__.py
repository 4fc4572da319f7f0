"""Policies trained on our datasets and evaluated closed-loop in held-out kitchens (issue 17).

Public surface (heavy packages load inside the functions, never on import):

- ``train.TrainConfig`` / ``train.train_policy``: lerobot-train (ACT, Diffusion Policy) on a dataset
  folder as the project writes it; training curve CSV + PNG, wall time (``agentworld train-policy``);
- ``runner.load_policy`` / ``runner.BatchedRunner``: a lerobot checkpoint run for many worlds, with
  per-world action chunking, ACT's temporal ensembling and Diffusion's observation history;
- ``evaluate.EvalConfig`` / ``evaluate.evaluate``: the policy drives the batched engine's worlds in
  held-out kitchens; success per task and family with failure reasons, rollout videos, ``eval.json``
  (``agentworld eval``);
- ``evalmerge.merge_reports`` / ``evalmerge.typical_seconds``: one report from per-kitchen
  ``eval.json`` parts (the device driver's parallel evaluation); the expert's median episode length
  of a task in a dataset (the driver's default episode limit);
- ``cli``: the two commands.
"""
