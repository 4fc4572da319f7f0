"""Scripted demonstrations of the basic household tasks, recorded as sharded LeRobot datasets (issue 7).

Modules: tasks (task specs and success predicates), kitchen (the task world), packages (catalog
packages placed in it), looks (its materials and lights), sampling (task worlds and instances from a
seed), planner (A* on the occupancy grid + base path follower), driver (what an expert acts through),
experts (one scripted expert per task), parts (articulated doors and drawers, their predicates),
part_grasps / part_planning / articulated (the generic open/close experts: where the hand goes,
where the base stands, the phases), part_world (one asset in a room, for the articulated experts),
record (30 fps recording of state, action and cameras), session (a simulated world running
episodes), job (the ``demos`` job kind: shards per task, merged dataset, success report).
Importing this package loads nothing heavy (no pxr, warp, newton, torch).
"""
