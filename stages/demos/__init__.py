"""Scripted demonstrations of the basic household tasks, recorded as sharded LeRobot datasets (issue 7).

Modules: tasks (task specs and success predicates), sampling (task worlds and instances from a
seed), planner (A* on the occupancy grid + base path follower), experts (one scripted expert per
task), record (30 fps recording of state, action and cameras), session (a simulated world running
episodes), job (the ``demos`` job kind: shards per task, merged dataset, success report).
Importing this package loads nothing heavy (no pxr, warp, newton, torch).
"""
