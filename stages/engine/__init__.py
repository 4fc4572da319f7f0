"""The batched demonstration engine (runtime library): many task worlds in one simulation, each
running its own episodes (scripted experts today; teleoperation and policies are drivers of the
same engine), recorded frame by frame with one render per frame for all worlds.

Public surface::

    from stages.engine import BatchEngine, EngineConfig, EpisodeResult
"""

from stages.engine.engine import BatchEngine, EngineConfig, EngineStats, EpisodeResult, device_scope
from stages.engine.lockstep import Lockstep, WorldStopped

__all__ = ["BatchEngine", "EngineConfig", "EngineStats", "EpisodeResult", "Lockstep", "WorldStopped",
           "device_scope"]
