"""The embodiment spec: one robot described as data (a TOML file), read by simulation, experts,
recorder and dataset schema, so that adding a robot is a spec plus assets, not a code fork.

Format (every length [m], angle [rad] unless the name says ``_deg``; gains in SI units)::

    name = "g1_29dof"                  # [a-z][a-z0-9_]*, the spec's id
    robot_type = "unitree_g1"          # LeRobot robot_type of its datasets
    extends = "other.toml"             # optional: start from that spec (same folder), tables merged

    [description]                      # where the robot's URDF/MJCF comes from
    format = "urdf"                    # urdf | mjcf
    file = "robots/g1_description/urdf/g1_29dof_rev_1_0.urdf"   # relative to the root below
    package = "example-robot-data"     # pip distribution holding it (its data root), and/or
    shared = "robots/unitree_g1__newton_assets"  # a folder of the shared third-party assets
    assembly = "as_is"                 # as_is | mobile_base (arm URDF mounted on the project's base)
    collider = "hull"                  # ingest collider kind (asset_catalog ColliderKind)

    [base]
    kind = "legged_policy"             # holonomic | legged_policy | fixed
    root_link = "pelvis"
    joints = []                        # holonomic: the x, y, yaw joints driven by (vx, vy, v_theta)
    height = 0.78                      # nominal root height above the floor when standing
    policy = "g1_velocity"             # legged_policy: a policy folder of stages/locomotion/policies, or a path

    [[arms]]                           # one per arm, in control order
    name = "left"
    root_link = "torso_link"           # chain root ...
    tip_link = "left_wrist_yaw_link"   # ... to the last arm link; `joints` are the chain's joints
    joints = ["left_shoulder_pitch_joint", ...]
    end_effector = "left_hand"         # a key of [end_effectors], or "" for none
    ee_frame = "left_ee"               # name of the end-effector frame: tip_link * ee_xyz/ee_rpy
    ee_xyz = [0.1, 0.0, 0.0]
    ee_rpy = [0.0, 0.0, 0.0]
    orientation = true                 # false: IK tracks position only (arms with < 6 joints)

    [end_effectors.left_hand]
    kind = "hand"                      # parallel_gripper | hand | none
    mount_link = "left_hand_palm_link"
    joints = [...]                     # finger joints; open/closed: their positions at command 0/1
    open = [...]
    closed = [...]

    [cameras.head]                     # a camera rides on `parent`: its optical frame (looks along
    link = "head_camera"               # -Z, +Y up) is at xyz in the parent link's frame, looking
    parent = "torso_link"              # along `forward` with +Y towards `up` (both in the parent
    xyz = [...]                        # frame); `link` names the camera link a builder adds
    forward = [...]
    up = [0.0, 0.0, 1.0]
    width = 128                        # [px]
    height = 128
    vertical_fov_deg = 70.0
    [cameras.third_person]             # a fixed camera: parent = "world", eye [m] and a target
    parent = "world"                   # x, y as fractions of the scene's size, z [m]
    eye = [0.3, 0.3, 2.3]
    target_scene_fraction = [0.6, 0.6, 0.6]

    [default_pose]                     # joint name -> position; unlisted joints: 0
    left_knee_joint = 0.3

    [[drives]]                         # first entry whose regex fully matches a joint name wins
    joints = ".*_knee_joint"
    mode = "position"                  # position | velocity | none (passive)
    kp = 99.1                          # [N m/rad] or [N/m]
    kd = 6.3                           # [N m s/rad] or [N s/m]
    armature = 0.025                   # [kg m^2] or [kg]; absent: the description's
    effort_limit = 139.0               # [N m] or [N]; absent: the description's
    gravity_compensation = false

Loading: :func:`load_spec` (a path, or the name of a spec shipped in ``stages/embodiment/specs``);
every problem of a file is collected into one :class:`EmbodimentError` naming the file. Checks
against the robot's kinematic model (joints and links exist, chains are chains) are in
``stages.embodiment.kinematics.check_spec``.
"""

from __future__ import annotations

import math
import re
import tomllib
from enum import StrEnum
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

SPECS_DIR = Path(__file__).resolve().parent / "specs"
_NAME_RE = re.compile(r"^[a-z][a-z0-9_]*$")
Vec3 = tuple[float, float, float]


class EmbodimentError(ValueError):
    """An embodiment spec that cannot be used; the one-line message names the file and every problem."""


class BaseKind(StrEnum):
    HOLONOMIC = "holonomic"           # base joints x, y, yaw velocity-driven by (vx, vy, v_theta)
    LEGGED_POLICY = "legged_policy"   # floating base; a locomotion policy turns (vx, vy, v_theta) into legs
    FIXED = "fixed"                   # root fixed to the world


class EndEffectorKind(StrEnum):
    PARALLEL_GRIPPER = "parallel_gripper"
    HAND = "hand"
    NONE = "none"


class DriveMode(StrEnum):
    POSITION = "position"
    VELOCITY = "velocity"
    NONE = "none"


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class DescriptionSpec(_Strict):
    """Where the description comes from (see the module docstring); resolved by
    ``stages.embodiment.sources.resolve_description``."""

    format: str = Field(pattern="^(urdf|mjcf)$")
    file: str
    package: str | None = None
    shared: str | None = None
    assembly: str = Field(default="as_is", pattern="^(as_is|mobile_base)$")
    collider: str = Field(default="hull", pattern="^(auto|hull|coacd|none)$")

    @field_validator("file")
    @classmethod
    def _relative(cls, v: str) -> str:
        if Path(v).is_absolute() or ".." in Path(v).parts:
            raise ValueError(f"description file {v!r} must be relative, without '..'")
        return v

    @field_validator("package", "shared", mode="before")
    @classmethod
    def _empty_is_none(cls, v: str | None) -> str | None:
        return None if v == "" else v    # TOML has no null: "" unsets an inherited value

    @model_validator(mode="after")
    def _somewhere(self) -> DescriptionSpec:
        if self.package is None and self.shared is None:
            raise ValueError("description needs a package or a shared folder")
        return self


class MobileBaseGeometry(_Strict):
    """The project's holonomic base (assembly ``mobile_base``): chassis box (x, y, z) [m];
    clearance: chassis bottom above the floor [m]; mass [kg]; arm_mount: arm root position on the
    chassis top in base_link (x, y) [m]; arm_mounts: per arm name, its root position there (x, y)
    [m] (several arms; stages.simulate.dual_arm); mast_xy [m]; mast_height: mast top above the
    floor [m]."""

    chassis: Vec3
    clearance: float
    mass: float = Field(gt=0)
    arm_mount: tuple[float, float]
    arm_mounts: dict[str, tuple[float, float]] = {}
    mast_xy: tuple[float, float]
    mast_height: float = Field(gt=0)


class BaseSpec(_Strict):
    """kind; root_link: the description's root link; joints: holonomic base joints (x, y, yaw);
    height: nominal root height above the floor [m] (legged); max_force [N] / max_torque [N m]:
    holonomic base joint force limits; velocity_kd: their velocity gain [N s/m];
    policy: the locomotion policy (legged_policy): a folder name in stages/locomotion/policies or
    a path (stages.locomotion.embodiment.policy_folder); empty where none is shipped."""

    kind: BaseKind
    root_link: str
    joints: tuple[str, ...] = ()
    height: float | None = Field(default=None, gt=0)
    max_force: float | None = Field(default=None, gt=0)
    max_torque: float | None = Field(default=None, gt=0)
    velocity_kd: float | None = Field(default=None, gt=0)
    policy: str = ""
    mobile: MobileBaseGeometry | None = None

    @model_validator(mode="after")
    def _joints_match_kind(self) -> BaseSpec:
        if self.kind == BaseKind.HOLONOMIC and len(self.joints) != 3:
            raise ValueError(f"a holonomic base names its 3 joints (x, y, yaw), got {list(self.joints)}")
        if self.kind != BaseKind.HOLONOMIC and self.joints:
            raise ValueError(f"a {self.kind.value} base has no base joints, got {list(self.joints)}")
        return self


class EndEffectorSpec(_Strict):
    """kind; mount_link: the link the end effector hangs from; joints: its actuated joints;
    open / closed: their positions at command 0 / 1 [m or rad]; max_force: per-joint force limit
    [N or N m]; squeeze: how far past ``closed`` the command-1 target lies [m or rad]."""

    kind: EndEffectorKind
    mount_link: str
    joints: tuple[str, ...] = ()
    open: tuple[float, ...] = ()
    closed: tuple[float, ...] = ()
    max_force: float | None = Field(default=None, gt=0)
    squeeze: float = Field(default=0.0, ge=0)

    @model_validator(mode="after")
    def _lengths(self) -> EndEffectorSpec:
        if len(self.open) != len(self.joints) or len(self.closed) != len(self.joints):
            raise ValueError(f"end effector on {self.mount_link}: open/closed need one value per joint "
                             f"({len(self.joints)}), got {len(self.open)}/{len(self.closed)}")
        if self.kind == EndEffectorKind.NONE and self.joints:
            raise ValueError(f"end effector on {self.mount_link}: kind none has no joints")
        return self


class ArmSpec(_Strict):
    """One arm: name; the kinematic chain root_link -> tip_link and its joints (root first);
    end_effector: a key of the spec's end_effectors ("" for none); ee_frame: the end-effector
    frame's name, at ee_xyz [m] / ee_rpy [rad] (URDF convention) in tip_link; orientation: whether
    IK tracks the orientation too (False for arms with fewer than 6 joints)."""

    name: str = Field(pattern=_NAME_RE.pattern)
    root_link: str
    tip_link: str
    joints: tuple[str, ...] = Field(min_length=1)
    end_effector: str = ""
    ee_frame: str
    ee_xyz: Vec3 = (0.0, 0.0, 0.0)
    ee_rpy: Vec3 = (0.0, 0.0, 0.0)
    orientation: bool = True


class CameraMountSpec(_Strict):
    """A camera. On a link (parent != "world"): xyz [m] of its optical frame (looks along -Z, +Y
    up, +X right) in the parent link, looking along ``forward`` with +Y towards ``up`` (both in the
    parent frame); ``link`` names the camera link a robot builder adds. Fixed (parent "world"):
    ``eye`` [m] and ``target_scene_fraction`` (x, y as fractions of the scene's size, z [m]).
    width, height [px]; vertical_fov_deg [deg]."""

    parent: str
    link: str | None = None
    xyz: Vec3 | None = None
    forward: Vec3 | None = None
    up: Vec3 = (0.0, 0.0, 1.0)
    eye: Vec3 | None = None
    target_scene_fraction: Vec3 | None = None
    width: int = Field(default=128, gt=0)
    height: int = Field(default=128, gt=0)
    vertical_fov_deg: float = Field(default=60.0, gt=0, lt=180)

    @property
    def fixed(self) -> bool:
        return self.parent == "world"

    @property
    def vertical_fov(self) -> float:
        """[rad]"""
        return math.radians(self.vertical_fov_deg)

    def intrinsics(self) -> tuple[float, float, float, float]:
        """Pinhole (fx, fy, cx, cy) [px], square pixels, principal point at the image centre
        (pixel-edge origin), as stages.simulate.sensors renders."""
        f = 0.5 * self.height / math.tan(0.5 * self.vertical_fov)
        return f, f, self.width / 2.0, self.height / 2.0

    def look_at(self, scene_size: tuple[float, float]) -> tuple[Vec3, Vec3]:
        """A fixed camera's eye and target [m] in a scene of ``scene_size`` (x, y) [m]."""
        fx, fy, z = self.target_scene_fraction
        return self.eye, (fx * scene_size[0], fy * scene_size[1], z)

    @model_validator(mode="after")
    def _complete(self) -> CameraMountSpec:
        if self.fixed:
            if self.eye is None or self.target_scene_fraction is None:
                raise ValueError("a fixed camera (parent 'world') needs eye and target_scene_fraction")
        elif self.link is None or self.xyz is None or self.forward is None:
            raise ValueError(f"a camera on link {self.parent!r} needs link, xyz and forward")
        return self


class DriveSpec(_Strict):
    """Drive of the joints whose names fully match the regex ``joints``: mode; kp [N m/rad or N/m];
    kd [N m s/rad or N s/m]; armature [kg m^2 or kg] and effort_limit [N m or N] (None: the
    description's); gravity_compensation: the bodies the joints move are gravity-compensated."""

    joints: str
    mode: DriveMode = DriveMode.POSITION
    kp: float = Field(default=0.0, ge=0)
    kd: float = Field(default=0.0, ge=0)
    armature: float | None = Field(default=None, ge=0)
    effort_limit: float | None = Field(default=None, gt=0)
    gravity_compensation: bool = False

    def matches(self, joint: str) -> bool:
        return re.fullmatch(self.joints, joint) is not None


class EmbodimentSpec(_Strict):
    """A robot as data (see the module docstring)."""

    name: str = Field(pattern=_NAME_RE.pattern)
    robot_type: str = Field(pattern=_NAME_RE.pattern)
    description: DescriptionSpec
    base: BaseSpec
    arms: tuple[ArmSpec, ...] = ()
    end_effectors: dict[str, EndEffectorSpec] = {}
    cameras: dict[str, CameraMountSpec] = {}
    default_pose: dict[str, float] = {}
    drives: tuple[DriveSpec, ...] = ()

    @model_validator(mode="after")
    def _consistent(self) -> EmbodimentSpec:
        problems = []
        for what, names in (("arm", [a.name for a in self.arms]), ("arm joint", self.arm_joints),
                            ("end-effector joint", self.end_effector_joints)):
            dup = sorted({n for n in names if names.count(n) > 1})
            if dup:
                problems.append(f"duplicate {what} names {dup}")
        for arm in self.arms:
            if arm.end_effector and arm.end_effector not in self.end_effectors:
                problems.append(f"arm {arm.name!r}: end_effector {arm.end_effector!r} is not in end_effectors")
        for cam in self.cameras:
            if not _NAME_RE.match(cam):
                problems.append(f"camera name {cam!r} must match {_NAME_RE.pattern}")
        for bad in (p.joints for p in self.drives if not _compiles(p.joints)):
            problems.append(f"drives: {bad!r} is not a regular expression")
        if not problems:
            undriven = [j for j in self.actuated_joints if self.drive_for(j) is None]
            if undriven:
                problems.append(f"no drive matches joints {undriven}")
        if problems:
            raise ValueError("; ".join(problems))
        return self

    # -- derived names ----------------------------------------------------------------------
    @property
    def arm_joints(self) -> tuple[str, ...]:
        """Every arm's joints, arms in order."""
        return tuple(j for a in self.arms for j in a.joints)

    @property
    def end_effector_joints(self) -> tuple[str, ...]:
        return tuple(j for a in self.arms if a.end_effector for j in self.end_effectors[a.end_effector].joints)

    @property
    def actuated_joints(self) -> tuple[str, ...]:
        """Joints the controllers command, in control order: base, arms, end effectors (legs and
        waist of a legged base are the policy's and come from the description, not listed here)."""
        return self.base.joints + self.arm_joints + self.end_effector_joints

    @property
    def arm_dof(self) -> int:
        return len(self.arm_joints)

    def arm(self, name: str) -> ArmSpec:
        for a in self.arms:
            if a.name == name:
                return a
        raise KeyError(f"{self.name}: no arm {name!r} (arms: {[a.name for a in self.arms]})")

    def drive_for(self, joint: str) -> DriveSpec | None:
        """The first drive entry whose regex matches ``joint``, or None."""
        return next((d for d in self.drives if d.matches(joint)), None)

    def link_cameras(self) -> dict[str, CameraMountSpec]:
        return {n: c for n, c in self.cameras.items() if not c.fixed}


def _compiles(pattern: str) -> bool:
    try:
        re.compile(pattern)
    except re.error:
        return False
    return True


# --------------------------------------------------------------------------------------------
# loading
# --------------------------------------------------------------------------------------------


def shipped_specs() -> dict[str, Path]:
    """Spec name (file stem) -> path of every spec shipped with the package."""
    return {p.stem: p for p in sorted(SPECS_DIR.glob("*.toml"))}


def spec_path(source: str | Path) -> Path:
    """The TOML file of ``source``: a path, or the name of a shipped spec."""
    path = Path(source)
    if not path.suffix and path.name == str(source):
        shipped = shipped_specs()
        if str(source) not in shipped:
            raise EmbodimentError(f"{SPECS_DIR}: no shipped embodiment spec {source!r}; "
                                  f"there are {sorted(shipped)}")
        path = shipped[str(source)]
    return path


def spec_files(source: str | Path) -> tuple[Path, ...]:
    """The spec's TOML file and every file it ``extends`` (for cache keys)."""
    out, path = [], spec_path(source)
    while path is not None and len(out) < 6:
        out.append(path)
        try:
            parent = tomllib.loads(path.read_text(encoding="utf-8")).get("extends")
        except (OSError, tomllib.TOMLDecodeError):
            break
        path = None if parent is None else path.parent / parent
    return tuple(out)


def load_spec(source: str | Path) -> EmbodimentSpec:
    """Load a spec: a TOML path, or the name of a shipped spec (``"g1_29dof"``). Raises
    EmbodimentError naming the file with every problem of it."""
    path = spec_path(source)
    data = _read(path, depth=0)
    try:
        return EmbodimentSpec.model_validate(data)
    except ValidationError as e:
        problems = [f"{'.'.join(str(x) for x in err['loc']) or 'spec'}: {err['msg']}" for err in e.errors()]
        raise EmbodimentError(f"{path}: invalid embodiment spec: {'; '.join(problems)}") from None


def _read(path: Path, depth: int) -> dict[str, Any]:
    if depth > 4:
        raise EmbodimentError(f"{path}: 'extends' nested too deeply (a cycle?)")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as e:
        raise EmbodimentError(f"{path}: cannot read the embodiment spec ({e.strerror})") from None
    except tomllib.TOMLDecodeError as e:
        raise EmbodimentError(f"{path}: not valid TOML: {e}") from None
    parent = data.pop("extends", None)
    if parent is None:
        return data
    return _merge(_read(path.parent / parent, depth + 1), data)


def _merge(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    """Tables merge key by key; everything else (arrays of tables included) is replaced."""
    out = dict(base)
    for k, v in over.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out
