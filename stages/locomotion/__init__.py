"""Locomotion for legged robots: the Unitree G1 velocity-tracking task, its PPO trainer and policy runtime.

Public surface (heavy packages are imported lazily by the submodules, never by this file):
- ``config``: ``EnvConfig``, ``TrainConfig``, ``PPOConfig`` ... (typed dataclasses)
- ``env.G1VelocityEnv``: N G1 worlds in one Newton model (SolverMuJoCo), torch tensors on the device
- ``train.train`` / ``evaluate.evaluate`` / ``policy.export_policy`` and ``policy.PolicyRuntime``
- ``runtime.LeggedPolicyRuntime``: the policy and the arms' CLIK inside any Newton model of N G1 worlds
  (base interface (vx, vy, v_theta) + mode, end-effector targets); ``runtime.HumanoidWorlds``: N G1
  worlds as in training with the runtime; ``runtime_eval.evaluate_runtime``: tracking, hands, falls
- ``cli``: the ``agentworld loco-train`` / ``loco-eval`` / ``loco-export`` / ``loco-runtime`` subcommands
"""
