"""Scene population: semantic placement, PBR materials, lighting and composition into USD scenes.

Public surface (pxr/newton are imported inside the functions, never at import time):

    rules.load_rules(path=DEFAULT_RULES) -> PlacementRules          # rules/*.toml, data not code
    library.Library.from_index(catalog_sqlite) -> Library           # ingested assets by category
    solver.Populator(plan, layout_usd, library, rules, rng).populate_room(room) -> RoomReport
        # re-arranges the room (up to rules.defaults.room_attempts) when a required entry fails;
        # RoomReport.arrangements_rejected lists why
    verify.verify(populator) -> CheckReport                          # exact collider + robot path checks
    collide.penetration_depth(a, b) -> float                         # convex pieces, exact SAT
    build.build_scene(plan_json, layout_usd, library, rules, rng, out_dir, final_dir, BuildOptions())
        -> SceneSummary                                              # one attempt; SceneRejected(reason)
    rest.analytic_rest(populator, needs_package_check) -> RestProof  # rest proven by statics (COM in contact)
    support.tips_over(inst, support_inst) -> str | None              # COM over the feet on the surface?
    validation.validate_scene(scene_usd, packages, CheckCache) -> SceneValidation
        # packages once per content hash (checkcache), per scene only what composition adds
    settle_batch.settle_batch(scenes, device="cuda:0") -> BatchSettle   # a few scenes, one MuJoCo-Warp model
    settle_pool.SettlePool(devices, procs_per_device).run(scenes, chunk) -> Iterator[ChunkResult]
        # many scenes: chunks settled + validated by worker processes per device, as they finish
    settle.settle_check(scene_usd, seconds=2.0, tolerance=0.01, early_exit=StillExit(), instances=None)
        # Newton add_usd + MuJoCo; stops early only once every body is still (see StillExit) (None: full 2 s)
    render.contact_sheet(scene_usds, out_png) -> Path                # `agentworld render-scenes`
    job.SCENE_JOB                                                    # job kind "scene"

Scene folder: scene.usda (root) + lighting.usda, materials.usdc, placement.usda sublayers,
textures/*.png, scene.json (instances, checks, chosen lights, timings).
"""
