"""Physics checks of written asset packages with Newton: does the asset behave in simulation?

- ``rest_check``: the asset, dropped from a small height onto a ground plane, comes to rest on it:
  its lowest collider point ends within a few millimeters of the plane, never sinks through it, is
  not launched, and its velocities decay to about zero.
- ``joint_limit_check``: each revolute/prismatic joint, driven (position drive) past its lower and
  then its upper limit, reaches that limit within a tolerance and never leaves its range. The base
  is fixed for this check.

Solver: ``SolverMuJoCo`` (implicit-fast integrator, elliptic cone, as below). One 4 ms step is
stable for stiff contacts there (Featherstone / semi-implicit would need substeps). The settings
used are recorded in each report (``solver``).

- ``joint_limit_check`` (base fixed, no ground) uses MuJoCo's C engine on CPU (``use_mujoco_cpu``)
  and mujoco-warp on CUDA, with MuJoCo's own collision.
- ``rest_check`` uses the same by default (``contacts="mujoco"``); ``contacts="newton"`` steps
  mujoco-warp (on any device) with Newton's collision pipeline instead (~5-10x slower on CPU). Its
  manifold (multicontact.py) is the deepest point plus support points in directions tilted by
  2 degrees; on a ridge-shaped bottom (os_toothbrush: faces 5-15 degrees apart, center of mass
  0.4-2 mm beside the support line) it holds points up to 0.5 mm above the plane and alternates
  between the two sides of the ridge every ~4 steps, so the body rocks about its long axis in a
  32 ms cycle (up to 3.7 rad/s, 1.7 degrees) with any contact stiffness; it is not the default.

Contact stiffness (``RIGID_CONTACT_SOLREF`` / ``RIGID_CONTACT_SOLIMP``, set on every shape for the
check, recorded in ``solver``). The check is about the asset (colliders, mass, pose), so contacts
are made close to rigid: solref time constant 0.01 s (2.5 steps, critically damped) and impedance
0.99-0.999 instead of Newton's/MuJoCo's defaults (0.02 s; 0.9-0.95). With the soft defaults:

- a body rests 0.2-0.5 mm deep in the plane, deeper than the unevenness of a scanned "flat" face
  (a die has 12 hull vertices within 0.5 mm of its lowest one). MuJoCo's plane-mesh collision
  (``mjc_PlaneConvex``) keeps at most 3 contacts: the deepest vertex and 2 graph neighbours. With
  many vertices in the plane that triangle changes with every tiny tilt (ycb_dice: 96 contact-set
  switches per second, os_mouse 142) and the body micro-rocks at 0.2-0.6 rad/s forever. Impedance
  0.99 alone stops the mouse; both settings make the depth 0.005 mm, the set stays fixed (0
  switches) and both rest at < 0.001 rad/s.
- a 20 cm tube toppling from its crimped end (os_toothpaste) hits with the soft 0.02 s contact and
  sinks 12.6 mm for an instant (3.9 mm with 0.01 s); at rest it lies 0.2 mm deep (0.005 mm).

Rolling across hull faces dissipates less with stiff contacts: a sphere hull authored on its pole
vertex (the default catalog's oranges: an unstable equilibrium, 8 faces at 13-14 degrees around
it) balances 0.7-0.9 s until float noise has grown (rate sqrt(g / h_com) = 16 1/s), rolls onto a
face and rests after 1.9-2.4 s (0.6-1.3 s with the soft defaults), hence the 3 s default run.

The final-speed bound covers every body: a light part that gravity holds on a joint limit can
bounce on that limit (the default catalog's alarm clock buttons, 5.8 g on a prismatic limit
whose authored ke/kd become MuJoCo solreflimit 0.023 s / damping ratio 0.15: an exact 32 ms cycle
at up to 0.03 m/s with either contact setting, so its final speed depends on the cycle's phase).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict

log = logging.getLogger(__name__)


class SolverSettings(BaseModel):
    """What ran the check: solver name, device, time step [s], iterations, integrator, cone;
    contact_solref (time constant [s], damping ratio) and contact_solimp (MuJoCo impedance: d0,
    dwidth, width [m], midpoint, power) set on every shape for the check, None: as authored/Newton's
    defaults (solref 0.02 s, 1; solimp 0.9, 0.95, 0.001, 0.5, 2)."""

    model_config = ConfigDict(frozen=True)

    solver: str = "SolverMuJoCo"
    device: str = "cpu"
    dt: float = 1.0 / 250.0
    iterations: int = 50
    ls_iterations: int = 20
    integrator: str = "implicitfast"
    cone: str = "elliptic"
    backend: str = "mujoco-c"
    contacts: str = "mujoco"
    contact_solref: tuple[float, float] | None = None
    contact_solimp: tuple[float, float, float, float, float] | None = None


class RestReport(BaseModel):
    """Outcome of ``rest_check``. Heights [m] are of the lowest collider point above the plane
    (z = 0); speeds: linear [m/s] at the center of mass, angular [rad/s]; maxima over bodies;
    released_base: the asset's fixed base (joint to the world, or static colliders) was released
    so that it could drop like a free object."""

    model_config = ConfigDict(frozen=True)

    usd_path: Path
    passed: bool
    reasons: tuple[str, ...]
    drop_height: float
    seconds: float
    final_height: float
    min_height: float
    settled_min_height: float
    max_rise: float
    final_linear_speed: float
    final_angular_speed: float
    body_count: int
    shape_count: int
    released_base: bool
    solver: SolverSettings


class JointLimitResult(BaseModel):
    """One joint: limits and reached positions [rad] or [m]; excursion: the largest distance
    outside [lower, upper] seen while driven; drive_stiffness: the check's drive gain [N m/rad] or
    [N/m]; passed if both limits reached within tolerance."""

    model_config = ConfigDict(frozen=True)

    joint: str
    kind: str
    lower: float
    upper: float
    reached_lower: float
    reached_upper: float
    max_excursion: float
    tolerance: float
    drive_stiffness: float
    passed: bool


class JointLimitReport(BaseModel):
    model_config = ConfigDict(frozen=True)

    usd_path: Path
    passed: bool
    reasons: tuple[str, ...]
    joints: tuple[JointLimitResult, ...]
    seconds_per_limit: float
    solver: SolverSettings


# ---------------------------------------------------------------------------------------------
# shared helpers


def _solver(model, settings: SolverSettings):
    import newton

    return newton.solvers.SolverMuJoCo(
        model, use_mujoco_cpu=settings.backend == "mujoco-c", iterations=settings.iterations,
        ls_iterations=settings.ls_iterations, integrator=settings.integrator, cone=settings.cone,
        use_mujoco_contacts=settings.contacts == "mujoco")


def _settings(device: str) -> SolverSettings:
    import warp as wp

    dev = wp.get_device(device)
    return SolverSettings(device=str(dev), backend="mujoco-c" if dev.is_cpu else "mujoco-warp")


# Contact parameters of ``rest_check`` (see the module docstring, "Contact stiffness"): MuJoCo solref
# (time constant [s] = 2.5 time steps, damping ratio: critical) and solimp (impedance 0.99 at zero
# penetration rising to 0.999 at 1 mm; midpoint, power as MuJoCo's default).
RIGID_CONTACT_SOLREF = (0.01, 1.0)
RIGID_CONTACT_SOLIMP = (0.99, 0.999, 0.001, 0.5, 2.0)


def _contact_settings(device: str, contacts: str, solref=RIGID_CONTACT_SOLREF,
                      solimp=RIGID_CONTACT_SOLIMP) -> SolverSettings:
    """Settings of ``rest_check``: MuJoCo's contacts ("mujoco", as ``_settings``) or mujoco-warp with
    Newton's collision pipeline ("newton", full contact manifolds; see the module docstring), with
    the contact solref/solimp to set on every shape (None: leave as loaded)."""
    import warp as wp

    if contacts == "mujoco":
        base = _settings(device)
    elif contacts == "newton":
        base = SolverSettings(device=str(wp.get_device(device)), backend="mujoco-warp", contacts="newton")
    else:
        raise ValueError(f"contacts must be 'mujoco' or 'newton', not {contacts!r}")
    return base.model_copy(update={"contact_solref": None if solref is None else tuple(map(float, solref)),
                                   "contact_solimp": None if solimp is None else tuple(map(float, solimp))})


def _set_contact_parameters(model, settings: SolverSettings) -> None:
    """Write ``settings``' contact solref/solimp into every shape of the finalized ``model`` (before
    the solver is made). solref goes through Newton's shape material: SolverMuJoCo maps ke, kd to
    timeconst = 2 / kd, dampratio = kd / 2 * sqrt(1 / ke); solimp through ``model.mujoco.geom_solimp``."""
    n = model.shape_count
    if settings.contact_solref is not None:
        timeconst, dampratio = settings.contact_solref
        kd = 2.0 / timeconst
        ke = (kd * dampratio / 2.0) ** 2 if dampratio > 0 else 0.0
        model.shape_material_ke.assign(np.full(n, ke, dtype=np.float32))
        model.shape_material_kd.assign(np.full(n, kd, dtype=np.float32))
    if settings.contact_solimp is not None:
        solimp = np.asarray(settings.contact_solimp, dtype=np.float32)
        model.mujoco.geom_solimp.assign(np.tile(solimp, (n, 1)))


def _collider_points_in_bodies(builder) -> list[tuple[int, np.ndarray]]:
    """(body index, (K, 3) points [m] in the body frame) of every colliding mesh/convex shape."""
    import newton

    out = []
    collide = int(newton.ShapeFlags.COLLIDE_SHAPES)
    for s in range(builder.shape_count):
        if not builder.shape_flags[s] & collide:
            continue
        src = builder.shape_source[s]
        verts = getattr(src, "vertices", None)
        if verts is None:
            continue
        tf = np.asarray(builder.shape_transform[s], dtype=np.float64)
        scale = np.asarray(builder.shape_scale[s], dtype=np.float64)
        pts = _transform_points(tf, np.asarray(verts, dtype=np.float64) * scale)
        out.append((int(builder.shape_body[s]), pts))
    return out


def _quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate points v (K, 3) by the unit quaternion q = (x, y, z, w) (warp's order)."""
    u, w = q[:3], q[3]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def _transform_points(tf: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Apply a warp transform (px, py, pz, qx, qy, qz, qw) to points (K, 3)."""
    return _quat_rotate(tf[3:7], pts) + tf[:3]


def _lowest_point(body_q: np.ndarray, shapes: list[tuple[int, np.ndarray]]) -> float:
    zs = []
    for body, pts in shapes:
        world = pts if body < 0 else _transform_points(body_q[body], pts)
        zs.append(world[:, 2].min())
    return float(min(zs)) if zs else math.nan


def _load(source, *, floating: bool | None, z_offset: float = 0.0, mujoco_attributes: bool = False,
          self_collisions: bool = True):
    """A ModelBuilder with the asset (a path or an open Usd.Stage), raised by ``z_offset`` [m];
    ``mujoco_attributes``: register SolverMuJoCo's custom attributes first (``model.mujoco.*``);
    ``self_collisions``: collisions between the asset's own links."""
    import newton
    import warp as wp

    import usd_schemas  # noqa: F401  (registers the schema plugins before USD's schema registry is built)

    builder = newton.ModelBuilder()
    if mujoco_attributes:
        newton.solvers.SolverMuJoCo.register_custom_attributes(builder)
    builder.add_usd(source if not isinstance(source, Path) else str(source),
                    xform=wp.transform((0.0, 0.0, z_offset), wp.quat_identity()), floating=floating,
                    load_visual_shapes=False, enable_self_collisions=self_collisions)
    return builder


def _released_stage(usd_path: Path):
    """The asset as a free object: opened with a session layer that disables joints to the world
    (a fixed base) and, for a static asset (colliders but no rigid body), makes each top-level
    Xform holding colliders a rigid body (mass from the bound physics material's density).
    Returns (stage, released: bool)."""
    from pxr import Usd, UsdPhysics

    import usd_schemas  # noqa: F401

    stage = Usd.Stage.Open(str(usd_path))
    released = False
    with Usd.EditContext(stage, stage.GetSessionLayer()):
        prims = list(stage.Traverse())
        bodies = {p.GetPath() for p in prims if p.HasAPI(UsdPhysics.RigidBodyAPI)}
        for p in prims:
            if p.IsA(UsdPhysics.Joint):
                j = UsdPhysics.Joint(p)
                ends = [*j.GetBody0Rel().GetTargets()[:1], *j.GetBody1Rel().GetTargets()[:1]]
                if len(ends) < 2 or not all(e in bodies for e in ends):
                    j.CreateJointEnabledAttr(False)
                    released = True
        if not bodies:
            root = stage.GetDefaultPrim()
            for child in root.GetChildren() if root else ():
                if any(d.HasAPI(UsdPhysics.CollisionAPI) for d in Usd.PrimRange(child)):
                    UsdPhysics.RigidBodyAPI.Apply(child)
                    released = True
    return stage, released


# ---------------------------------------------------------------------------------------------
# rest check


@dataclass(frozen=True)
class RestTolerances:
    """rest_height: final lowest point within +-rest_height of the plane [m]; sink: over the last
    quarter of the run the lowest point never goes below -sink [m]; impact_sink: bound on the
    transient penetration at impact (MuJoCo's contacts are soft) [m]; launch: the lowest point may
    never rise more than launch [m] above where it started; speeds: final linear [m/s] / angular
    [rad/s] speed bounds."""

    rest_height: float = 0.003
    sink: float = 0.003
    impact_sink: float = 0.01
    launch: float = 0.02
    linear_speed: float = 0.02
    angular_speed: float = 0.2


def rest_check(usd_path: Path, *, device: str = "cpu", seconds: float = 3.0, drop_height: float = 0.02,
               tolerances: RestTolerances = RestTolerances(), contacts: str = "mujoco",
               contact_solref: tuple[float, float] | None = RIGID_CONTACT_SOLREF,
               contact_solimp: tuple[float, ...] | None = RIGID_CONTACT_SOLIMP) -> RestReport:
    """Drop the asset from ``drop_height`` [m] (lowest collider point above the plane, asset in its
    authored orientation) onto a ground plane and simulate ``seconds`` [s] on ``device``;
    ``contacts``: "mujoco" (MuJoCo's collision) or "newton" (Newton's pipeline, see module docstring);
    ``contact_solref`` (time constant [s], damping ratio) / ``contact_solimp`` (MuJoCo solimp) set on
    every shape, None: as loaded (Newton's defaults unless the asset authors them). A fixed base is
    released for the drop (only in memory), so that fixed assets are checked too."""
    import newton
    import warp as wp

    usd_path = Path(usd_path)
    settings = _contact_settings(device, contacts, contact_solref, contact_solimp)
    stage, released = _released_stage(usd_path)
    probe = _load(stage, floating=None)
    shapes0 = _collider_points_in_bodies(probe)
    if not shapes0:
        return _rest_fail(usd_path, "no collider shapes", drop_height, seconds, settings, probe)
    start_low = _lowest_point(np.asarray([_body_q0(probe, b) for b in range(probe.body_count)]), shapes0)
    builder = _load(stage, floating=None, z_offset=drop_height - start_low, mujoco_attributes=True)
    builder.add_ground_plane()
    shapes = _collider_points_in_bodies(builder)
    with wp.ScopedDevice(device):
        model = builder.finalize(device=device)
        _set_contact_parameters(model, settings)
        solver = _solver(model, settings)
        pipeline = newton.CollisionPipeline(model) if settings.contacts == "newton" else None
        found = pipeline.contacts() if pipeline is not None else None
        s0, s1, control = model.state(), model.state(), model.control()
        newton.eval_fk(model, model.joint_q, model.joint_qd, s0)
        steps = max(1, round(seconds / settings.dt))
        heights = []
        for _ in range(steps):
            s0.clear_forces()
            if pipeline is not None:
                pipeline.collide(s0, found)
            solver.step(s0, s1, control, found, settings.dt)
            s0, s1 = s1, s0
            heights.append(_lowest_point(s0.body_q.numpy().astype(np.float64), shapes))
        qd = s0.body_qd.numpy().astype(np.float64)
    lin = float(np.linalg.norm(qd[:, :3], axis=1).max()) if len(qd) else 0.0
    ang = float(np.linalg.norm(qd[:, 3:], axis=1).max()) if len(qd) else 0.0
    h = np.asarray(heights)
    final, low, rise = float(h[-1]), float(h.min()), float(h.max() - drop_height)
    settled = float(h[len(h) * 3 // 4:].min())
    t = tolerances
    reasons = []
    if not np.isfinite(h).all():
        reasons.append("simulation produced NaN")
    if abs(final) > t.rest_height:
        reasons.append(f"final lowest point {final * 1000:.1f} mm from the plane (tolerance {t.rest_height * 1000:.1f} mm)")
    if settled < -t.sink:
        reasons.append(f"sinks {-settled * 1000:.1f} mm below the plane at rest (tolerance {t.sink * 1000:.1f} mm)")
    if low < -t.impact_sink:
        reasons.append(f"sank {-low * 1000:.1f} mm below the plane on impact (tolerance {t.impact_sink * 1000:.1f} mm)")
    if rise > t.launch:
        reasons.append(f"launched {rise * 1000:.1f} mm above the drop height (tolerance {t.launch * 1000:.1f} mm)")
    if lin > t.linear_speed or ang > t.angular_speed:
        reasons.append(f"not at rest after {seconds} s: {lin:.3f} m/s, {ang:.3f} rad/s")
    report = RestReport(usd_path=usd_path, passed=not reasons, reasons=tuple(reasons), drop_height=drop_height,
                        seconds=seconds, final_height=final, min_height=low, settled_min_height=settled, max_rise=rise, final_linear_speed=lin,
                        final_angular_speed=ang, body_count=model.body_count, shape_count=model.shape_count,
                        released_base=released, solver=settings)
    log.debug("rest check %s: %s", usd_path, report)
    return report


def _body_q0(builder, b: int) -> np.ndarray:
    return np.asarray(builder.body_q[b], dtype=np.float64)


def _rest_fail(usd_path, reason, drop_height, seconds, settings, builder) -> RestReport:
    nan = math.nan
    return RestReport(usd_path=usd_path, passed=False, reasons=(reason,), drop_height=drop_height, seconds=seconds,
                      final_height=nan, min_height=nan, settled_min_height=nan, max_rise=nan, final_linear_speed=nan,
                      final_angular_speed=nan, body_count=builder.body_count, shape_count=builder.shape_count,
                      released_base=False, solver=settings)


# ---------------------------------------------------------------------------------------------
# joint limit check


@dataclass(frozen=True)
class _JointLoad:
    """What the check's drive must move and hold for one joint: inertia [kg m^2] or mass [kg] of
    the child subtree about the axis, and its worst static load: joint friction plus the largest
    gravity torque [N m] (revolute) or force [N] (prismatic) over the joint's travel."""

    inertia: float
    static_load: float


def _joint_load(builder, joint: int, gravity: float = 9.81, any_axis: bool = False) -> _JointLoad:
    import newton

    children: dict[int, list[int]] = {}
    for j in range(builder.joint_count):
        children.setdefault(builder.joint_parent[j], []).append(builder.joint_child[j])
    bodies, stack = [], [builder.joint_child[joint]]
    while stack:
        b = stack.pop()
        bodies.append(b)
        stack.extend(children.get(b, []))
    masses = np.array([float(builder.body_mass[b]) for b in bodies])
    mass = float(masses.sum())
    dof = builder.joint_qd_start[joint]
    friction = float(builder.joint_friction[dof])
    # axis and anchor in world, from the parent pose and joint frame at the initial configuration
    parent = builder.joint_parent[joint]
    x_wp = np.asarray(builder.body_q[parent], dtype=np.float64) if parent >= 0 else np.array([0, 0, 0, 0, 0, 0, 1.0])
    x_pj = np.asarray(builder.joint_X_p[joint], dtype=np.float64)
    anchor = _transform_points(x_wp, x_pj[None, :3])[0]
    axis = _quat_rotate(_quat_mul(x_wp[3:7], x_pj[3:7]), np.asarray(builder.joint_axis[dof], dtype=np.float64)[None])[0]
    if builder.joint_type[joint] == newton.JointType.PRISMATIC:
        return _JointLoad(inertia=max(mass, 1e-3), static_load=friction + mass * gravity * abs(axis[2]))
    inertia, moment, reach_moment = 0.0, np.zeros(3), 0.0
    parent_joint = {builder.joint_child[j]: j for j in range(builder.joint_count)}
    reach: dict[int, float] = {}     # body -> bound on its joint anchor's distance from ``anchor``
    for b, m in zip(bodies, masses):
        bq = np.asarray(builder.body_q[b], dtype=np.float64)
        com = _transform_points(bq, np.asarray(builder.body_com[b], dtype=np.float64)[None])[0]
        r = com - anchor
        r_perp = r - axis * np.dot(r, axis)
        moment += m * r_perp
        ib = np.asarray(builder.body_inertia[b], dtype=np.float64).reshape(3, 3)
        a_body = _quat_rotate(bq[3:7] * np.array([-1, -1, -1, 1.0]), axis[None])[0]
        inertia += float(a_body @ ib @ a_body) + m * float(r_perp @ r_perp)
        if any_axis:    # distances along the chain of anchors do not change with the joints
            own = _anchor(builder, parent_joint[b])
            up = builder.joint_parent[parent_joint[b]]
            reach[b] = 0.0 if up not in reach else reach[up] + float(np.linalg.norm(own - _anchor(builder, parent_joint[up])))
            reach_moment += m * (reach[b] + float(np.linalg.norm(com - own)))
    # gravity torque about the axis is |moment x g . axis| <= |moment| g |axis x z|, whatever the angle;
    # any_axis (other joints move too, changing the axis and the subtree's shape): the bound over all
    # configurations, sum of mass x (distance along the anchors to its centre of mass)
    lever = reach_moment if any_axis else float(np.linalg.norm(moment)) * float(
        np.linalg.norm(np.cross(axis, (0.0, 0.0, 1.0))))
    return _JointLoad(inertia=max(inertia, 1e-5), static_load=friction + gravity * lever)


def _anchor(builder, joint: int) -> np.ndarray:
    """World position (3,) of ``joint``'s frame at the initial configuration."""
    parent = builder.joint_parent[joint]
    x_wp = np.asarray(builder.body_q[parent], dtype=np.float64) if parent >= 0 else np.array([0, 0, 0, 0, 0, 0, 1.0])
    return _transform_points(x_wp, np.asarray(builder.joint_X_p[joint], dtype=np.float64)[None, :3])[0]


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz])


def joint_limit_check(usd_path: Path, *, device: str = "cpu", seconds_per_limit: float = 1.5,
                      angular_tolerance: float = math.radians(3.0), linear_tolerance: float = 0.01,
                      natural_frequency: float = 10.0, angular_speed: float = 1.5,
                      linear_speed: float = 0.3, self_collisions: bool = True,
                      joints: Sequence[str] | None = None) -> JointLimitReport:
    """Drive every revolute/prismatic joint first to its lower, then to its upper limit,
    ``seconds_per_limit`` [s] each, with the base fixed, and check where it ends.

    The drive is a position drive per joint. Its stiffness is the larger of (subtree inertia + the
    joint's armature) x ``natural_frequency``^2 and what holds 2x the joint's static load (joint friction plus the
    worst gravity torque/force on the subtree) at half the tolerance; damping is critical; armature
    is added where the stiffness would make the joint too fast for the time step. The target moves
    at ``angular_speed`` [rad/s] / ``linear_speed`` [m/s] (faster if needed to arrive within 60 %
    of the time) and stops half a tolerance past the limit, so that the limit stops the joint.

    A joint passes if it ends within the tolerance ([rad] / [m]) of each limit and never goes
    further than the tolerance outside its range. Joints without both limits are reported failed.
    ``self_collisions=False``: the asset's links pass through each other (a robot, whose joints all
    at their limits at once put limbs into each other; robots are simulated that way here).
    ``joints``: drive only these joints (names), holding every other one where it starts (a robot
    checked limb by limb); the report lists the driven joints. Several joints of one chain move
    together then, so each one's static load is bounded over every configuration (the subtree's
    mass times its reach along the joint anchors), not only over its own travel.
    """
    import newton
    import warp as wp

    usd_path = Path(usd_path)
    settings = _settings(device)
    builder = _load(usd_path, floating=False, self_collisions=self_collisions, mujoco_attributes=True)  # mjc:solreflimit
    movable = [j for j in range(builder.joint_count)
               if builder.joint_type[j] in (newton.JointType.REVOLUTE, newton.JointType.PRISMATIC)]
    if not movable:
        return JointLimitReport(usd_path=usd_path, passed=False, reasons=("no revolute or prismatic joint",),
                                joints=(), seconds_per_limit=seconds_per_limit, solver=settings)
    dofs = {j: builder.joint_qd_start[j] for j in movable}
    coords = {j: builder.joint_q_start[j] for j in movable}
    tolerance = {j: angular_tolerance if builder.joint_type[j] == newton.JointType.REVOLUTE else linear_tolerance
                 for j in movable}
    max_omega = 0.5 / settings.dt
    gains = {}
    for j in movable:
        d = dofs[j]
        load = _joint_load(builder, j, any_axis=joints is not None)
        moved = load.inertia + float(builder.joint_armature[d])     # the source's armature moves too
        ke = max(moved * natural_frequency**2, 4.0 * load.static_load / tolerance[j])
        inertia = max(moved, ke / max_omega**2)
        builder.joint_armature[d] = inertia - load.inertia
        builder.joint_target_ke[d] = ke
        builder.joint_target_kd[d] = 2.0 * math.sqrt(ke * inertia)
        builder.joint_target_mode[d] = int(newton.JointTargetMode.POSITION)
        builder.joint_effort_limit[d] = 1e9
        gains[j] = ke
    lims = {j: (float(builder.joint_limit_lower[dofs[j]]), float(builder.joint_limit_upper[dofs[j]])) for j in movable}
    driven = movable
    if joints is not None:
        by_name = {builder.joint_label[j].rsplit("/", 1)[-1]: j for j in movable}
        unknown = sorted(set(joints) - set(by_name))
        if unknown:
            return JointLimitReport(usd_path=usd_path, passed=False, joints=(), solver=settings,
                                    reasons=(f"no revolute or prismatic joints {unknown}",),
                                    seconds_per_limit=seconds_per_limit)
        driven = [by_name[n] for n in joints]
    reached: dict[int, list[float]] = {j: [] for j in movable}
    excursion = {j: 0.0 for j in movable}
    with wp.ScopedDevice(device):
        model = builder.finalize(device=device)
        solver = _solver(model, settings)
        s0, s1, control = model.state(), model.state(), model.control()
        newton.eval_fk(model, model.joint_q, model.joint_qd, s0)
        steps = max(1, round(seconds_per_limit / settings.dt))
        for side in (0, 1):
            q_start = s0.joint_q.numpy().copy()
            goal, speed = {}, {}
            for j in movable:
                lo, hi = lims[j]
                goal[j] = lo - 0.5 * tolerance[j] if side == 0 else hi + 0.5 * tolerance[j]
                if j not in driven:
                    goal[j] = q_start[coords[j]]
                revolute = builder.joint_type[j] == newton.JointType.REVOLUTE
                dist = abs(goal[j] - q_start[coords[j]])
                speed[j] = max(angular_speed if revolute else linear_speed, dist / (0.6 * seconds_per_limit))
            target = control.joint_target_q.numpy()
            for step in range(steps):
                t = (step + 1) * settings.dt
                for j in movable:
                    q0 = q_start[coords[j]]
                    target[coords[j]] = q0 + np.clip(goal[j] - q0, -speed[j] * t, speed[j] * t)
                control.joint_target_q.assign(target)
                s0.clear_forces()
                solver.step(s0, s1, control, None, settings.dt)
                s0, s1 = s1, s0
                q = s0.joint_q.numpy()
                for j in movable:
                    lo, hi = lims[j]
                    x = float(q[coords[j]])
                    excursion[j] = max(excursion[j], lo - x, x - hi)
            q = s0.joint_q.numpy()
            for j in movable:
                reached[j].append(float(q[coords[j]]))
    return _limit_report(usd_path, builder, driven, lims, reached, excursion, tolerance, gains,
                         seconds_per_limit, settings)


def _limit_report(usd_path, builder, movable, lims, reached, excursion, tolerance, gains, seconds, settings):
    import newton

    results, reasons = [], []
    for j in movable:
        revolute = builder.joint_type[j] == newton.JointType.REVOLUTE
        tol = tolerance[j]
        lo, hi = lims[j]
        r_lo, r_hi = reached[j]
        name = builder.joint_label[j]
        bounded = np.isfinite(lo) and np.isfinite(hi) and abs(lo) < 1e6 and abs(hi) < 1e6
        ok = bool(bounded and abs(r_lo - lo) <= tol and abs(r_hi - hi) <= tol and excursion[j] <= tol)
        if not bounded:
            reasons.append(f"{name}: joint has no finite limits")
        elif not ok:
            reasons.append(f"{name}: limits [{lo:.4f}, {hi:.4f}] reached [{r_lo:.4f}, {r_hi:.4f}], "
                           f"excursion {excursion[j]:.4f} (tolerance {tol:.4f})")
        results.append(JointLimitResult(joint=name, kind="revolute" if revolute else "prismatic", lower=lo, upper=hi,
                                        reached_lower=r_lo, reached_upper=r_hi, max_excursion=float(excursion[j]),
                                        tolerance=tol, drive_stiffness=float(gains[j]), passed=ok))
    return JointLimitReport(usd_path=usd_path, passed=not reasons, reasons=tuple(reasons), joints=tuple(results),
                            seconds_per_limit=seconds, solver=settings)
