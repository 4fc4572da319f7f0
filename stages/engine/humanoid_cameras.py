"""The cameras of an embodiment spec on a humanoid simulation (``stages.engine.humanoid``): each
camera rides its parent link (the head camera on the G1's torso, the wrist cameras on the wrist
links) at the spec's mount (``xyz``, ``forward``, ``up`` in the parent frame; optical frame looks
along -Z with +Y up, as ``stages.simulate.sensors`` renders); a fixed ("world") camera looks from
``eye`` at the scene fraction ``target_scene_fraction`` of the task world.

:func:`mounted_rig` gives a :class:`~stages.simulate.sensors.CameraRig` that renders them in every
world (the scene's UsdLux lights mapped as the engine maps them).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from stages.simulate.sensors import CameraRig, CameraSpec


@dataclass
class _SimView:
    """What CameraRig reads of a simulation: the model, the scene's lights, world count, state."""

    worlds: Any
    scene: Any
    world_count: int

    @property
    def model(self) -> Any:
        return self.worlds.model

    @property
    def state_0(self) -> Any:
        return self.worlds.state


@dataclass
class MountedCameraRig(CameraRig):
    """A CameraRig whose link cameras ride bodies given by index: ``mounts`` camera name ->
    (body index in world 0, bodies per world, (4, 4) camera pose in the body frame)."""

    mounts: dict = field(default_factory=dict)

    def camera_to_world(self, cam: CameraSpec) -> np.ndarray:
        from scipy.spatial.transform import Rotation

        nw = self.sim.world_count
        if cam.name not in self.mounts:
            return np.repeat(np.asarray(cam.pose, float)[None], nw, axis=0)
        body, per_world, offset = self.mounts[cam.name]
        t = self.sim.state_0.body_q.numpy()[body + np.arange(nw) * per_world]
        m = np.tile(np.eye(4), (nw, 1, 1))
        m[:, :3, :3] = Rotation.from_quat(t[:, 3:7]).as_matrix()
        m[:, :3, 3] = t[:, :3]
        return m @ offset


def mount_pose(xyz, forward, up) -> np.ndarray:
    """(4, 4) optical-frame pose in the parent frame of a camera at ``xyz`` [m] looking along ``forward``."""
    from stages.simulate.robot import look_rotation

    m = np.eye(4)
    m[:3, :3] = look_rotation(np.asarray(forward, float), np.asarray(up, float))
    m[:3, 3] = xyz
    return m


def mounted_rig(worlds: Any, spec: Any, scene: Any, names: tuple[str, ...], width: int, height: int, *,
                bodies_per_world: int, room: tuple[float, float] = (5.0, 5.4)) -> MountedCameraRig:
    """A rig of the spec's cameras ``names`` at ``width`` x ``height`` [px] over ``worlds``
    (``HumanoidWorlds``); ``scene``: the task world's ``LoadedScene`` (lights); ``room``: (x, y)
    size [m] for fixed cameras' scene fractions. Raises KeyError naming an unknown camera or link."""
    from stages.simulate.sensors import look_at

    model = worlds.model
    labels = [lbl.rsplit("/", 1)[-1] for lbl in model.body_label[:bodies_per_world]]
    cams, mounts = [], {}
    for name in names:
        if name not in spec.cameras:
            raise KeyError(f"{spec.name}: no camera {name!r} (cameras: {sorted(spec.cameras)})")
        c = spec.cameras[name]
        if c.fixed:
            frac = np.asarray(c.target_scene_fraction, float)
            target = (frac[0] * room[0], frac[1] * room[1], frac[2])
            cams.append(CameraSpec(name=name, width=width, height=height, vertical_fov=c.vertical_fov,
                                   pose=look_at(c.eye, target)))
            continue
        if c.parent not in labels:
            raise KeyError(f"{spec.name}: camera {name!r} rides {c.parent!r}, not a body of the simulated "
                           "robot")
        mounts[name] = (labels.index(c.parent), bodies_per_world, mount_pose(c.xyz, c.forward, c.up))
        cams.append(CameraSpec(name=name, width=width, height=height, vertical_fov=c.vertical_fov,
                               link=c.parent))
    return MountedCameraRig(sim=_SimView(worlds, scene, model.world_count), cameras=cams, segmentation=False,
                            mounts=mounts)
