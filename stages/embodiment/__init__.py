"""Embodiments as data: robot specs (TOML), their descriptions resolved and ingested into USD
packages, kinematic models and upper-body CLIK.

- :mod:`stages.embodiment.spec`: the spec format, :func:`load_spec`, the shipped specs;
- :mod:`stages.embodiment.sources`: finding a spec's URDF/MJCF, ingesting it into a USD package;
- :mod:`stages.embodiment.kinematics`: the Pinocchio model of a spec, chains, frames, checks;
- :mod:`stages.embodiment.clik`: closed-loop IK per arm, batched over worlds (numpy);
- :mod:`stages.embodiment.layout`: the dataset's state and action names per embodiment;
- :mod:`stages.embodiment.job`: the ``robots`` job kind (specs -> USD packages).

Importing this package loads neither pinocchio, pxr, warp nor torch.
"""

from stages.embodiment.spec import (ArmSpec, BaseKind, BaseSpec, CameraMountSpec, DescriptionSpec, DriveMode,
                                    DriveSpec, EmbodimentError, EmbodimentSpec, EndEffectorKind, EndEffectorSpec,
                                    load_spec, shipped_specs)

__all__ = ["ArmSpec", "BaseKind", "BaseSpec", "CameraMountSpec", "DescriptionSpec", "DriveMode", "DriveSpec",
           "EmbodimentError", "EmbodimentSpec", "EndEffectorKind", "EndEffectorSpec", "load_spec", "shipped_specs"]
