"""Registry of job kinds: ``kind`` in a job TOML -> ``"module:attribute"`` of a ``pipeline.types.JobKind``.

Imported lazily by the runner; each entry's module is imported only when a job uses it.
"""

JOB_KINDS: dict[str, str] = {
    "ingest": "stages.ingest:INGEST_JOB",
    "default_catalog": "stages.catalog:DEFAULT_CATALOG_JOB",
    "layout": "stages.layout.job:LAYOUT_JOB",
    "scene": "stages.scene.job:SCENE_JOB",
    "demos": "stages.demos.job:DEMOS_JOB",
    "humanoid_demos": "stages.demos.humanoid_job:HUMANOID_DEMOS_JOB",
    "robots": "stages.embodiment.job:ROBOTS_JOB",
}
