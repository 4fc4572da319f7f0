"""Putting the pitcher back (issue 16, serve drinks: the last stage, ``place_pitcher``, of
``serve_drinks``; the pick and the pour: :mod:`stages.demos.skill_pour`).

- :func:`place_pitcher`: the pitcher, hanging tilted in the hand after the pour, lowered until its
  lowest base point (:func:`base_contact`) touches the table over that point's home spot, rolled
  flat about it (:func:`roll_about`), released, the hand backed out along its approach axis.

Frame: world, Z up, metres, radians. Pitcher asset frame: origin at its base centre, handle on +Y,
spout on -Y (asset_catalog.generators.objects.pitcher).
"""

from __future__ import annotations

import logging
import math

import numpy as np

from stages.demos.driver import APPROACH_TOL
from stages.demos.skill_pour import _log_pitcher, _tilt_deg

log = logging.getLogger(__name__)

PLACE_STEP = 0.03         # the pitcher is lowered onto the table in steps of at most this [m]
PLACE_HOVER = 0.06        # the hand this far [m] over the grasp's height when it is brought over the home spot
PLACE_TOUCH = 0.004       # its lowest base point this near [m] the table counts as touching
ROLL_STEP = 5.0           # a touching pitcher that still tilts is rolled flat in steps of this [deg]
ROLL_TRIES = 10           # at most this many
BACK_OUT = 0.10           # the released hand backs out this far [m] along its approach axis, then up
ROLL_TILT = 3.0           # until it tilts less than this [deg]


def base_contact(position, orientation, params: dict) -> tuple[np.ndarray, np.ndarray]:
    """The lowest point (3,) [m] of the base ring (radius 0.85 x the pitcher's radius, the
    generator's foot) of a pitcher at ``position`` (3,) [m], ``orientation`` (w, x, y, z), and that
    point in the pitcher frame (3,) [m] (where a tilted pitcher lowered onto a table touches it)."""
    from scipy.spatial.transform import Rotation

    r = 0.85 * float(params["radius"])
    a = np.linspace(0.0, 2 * math.pi, 72, endpoint=False)
    ring = np.column_stack([r * np.cos(a), r * np.sin(a), np.zeros_like(a)])
    w, x, y, z = (float(v) for v in orientation)
    pts = Rotation.from_quat([x, y, z, w]).apply(ring) + np.asarray(position, float)
    k = int(np.argmin(pts[:, 2]))
    return pts[k], ring[k]


def bottom_low(position, orientation, params: dict) -> float:
    """Height [m] of the lowest point of the base ring of a pitcher at ``position`` (3,) [m],
    ``orientation`` (w, x, y, z) (:func:`base_contact`)."""
    return float(base_contact(position, orientation, params)[0][2])


def roll_about(point, up, hand, share: float = 1.0) -> np.ndarray:
    """Where a hand at ``hand`` (3,) [m] goes when the body it holds turns about the horizontal axis
    through ``point`` (3,) [m] by ``share`` of the turn that stands the body's axis ``up`` (3,)
    upright (the hand keeps its rotation: the pitcher turns about the pads' normal in it)."""
    from scipy.spatial.transform import Rotation

    up = np.asarray(up, float) / np.linalg.norm(up)
    axis = np.cross(up, [0.0, 0.0, 1.0])
    s = float(np.linalg.norm(axis))
    if s < 1e-9:
        return np.asarray(hand, float)
    turn = Rotation.from_rotvec(axis / s * math.atan2(s, float(up[2])) * share)
    return np.asarray(point, float) + turn.apply(np.asarray(hand, float) - np.asarray(point, float))


def place_pitcher(inst, d) -> None:
    """The expert of ``place_pitcher`` (the pitcher held, hanging tilted): the hand carried so that the
    pitcher's lowest base point (:func:`base_contact`) stands over that point of the pitcher on its
    home spot, :data:`PLACE_HOVER` above the table; down in steps (up to :data:`PLACE_STEP`, smaller
    as it nears) until that point touches the table; then rolled flat about it (:func:`roll_about`:
    the hand, its rotation kept, moves down and back along the arc, the pitcher turns about the
    pads' normal, in :data:`ROLL_STEP` steps until it tilts less than :data:`ROLL_TILT`); released,
    the hand backed out along its approach axis (the open fingers slide past the strap out of the
    loop) and up, tucked. The moves keep the arm's branch (``restarts=False``).

    Why: it hangs 20-28 deg tilted forward in the hand after the pour (it turns about the pads'
    normal), past its base's tipping angle. Lowered by its origin's height it was pushed edge first
    into the table, squeezed out of the pads and flipped (living room flat_000 seed 1; kitchens:
    ``object_tipped`` 7 of 20). Stood upright in the air (the hand turned up) the arm at a 0.43 m
    coffee table ran to its joint limits (shoulder -101 deg, joint 5 165 deg), CLIK restarted on
    another branch and the joint sweep swung the pitcher out of the hand; pressed straight down on
    its touching edge it jammed (the edge must stay and the hand swing back)."""
    from scipy.spatial.transform import Rotation

    from stages.demos.counter import _pose
    from stages.demos.driver import stow
    from stages.simulate.state import read_state

    w, plan = inst.world, inst.place
    params = w.placed["pitcher"].asset.params
    hx, hy, hz, hyaw = plan.home
    home_rot = Rotation.from_euler("z", hyaw)

    def now():
        st = read_state(d.sim)
        p = st.objects[plan.pitcher]
        low, local = base_contact(p.position, p.orientation, params)
        spot = np.array([hx, hy, w.table_z]) + home_rot.apply(local) * [1, 1, 0]   # that point at home
        x, y, z, qw = p.orientation[1], p.orientation[2], p.orientation[3], p.orientation[0]
        up = Rotation.from_quat([x, y, z, qw]).apply([0.0, 0.0, 1.0])
        ee = np.asarray(st.robot.ee_pose.position, float)
        return ee, st.robot.ee_pose.matrix()[:3, :3], low, spot, up, _tilt_deg(p.orientation)

    ee, rot, low, spot, _, _ = now()
    over = ee + (spot - low) * [1, 1, 0]
    over[2] = max(ee[2], ee[2] + (w.table_z + PLACE_HOVER - low[2]))
    d.move(_pose(over, rot), 2.0, segments=3, carry=True, tol=APPROACH_TOL, restarts=False)
    _log_pitcher(d, plan, "place_pitcher: over home")
    for _ in range(12):   # down until the lowest base point touches, kept over its spot
        ee, rot, low, spot, _, _ = now()
        gap = low[2] - w.table_z
        _log_pitcher(d, plan, f"place_pitcher: base {gap:.4f} m over the table")
        if gap <= PLACE_TOUCH:
            break
        dz = min(PLACE_STEP, max(0.002, gap - 0.5 * PLACE_TOUCH))
        d.move(_pose(ee + (spot - low) * [1, 1, 0] - [0.0, 0.0, dz], rot), 0.6 if dz > 0.01 else 0.3, segments=1,
               settle=0.2, restarts=False)
    for _ in range(ROLL_TRIES):   # rolled flat about the touching point
        ee, rot, low, spot, up, tilt = now()
        log.debug("place_pitcher: base %.4f m over the table, tilt %.1f deg", low[2] - w.table_z, tilt)
        if tilt < ROLL_TILT or low[2] - w.table_z > 2 * PLACE_TOUCH:
            break
        share = min(1.0, ROLL_STEP / tilt)
        d.move(_pose(roll_about(low, up, ee, share) - [0.0, 0.0, 0.002], rot), 0.4, segments=1, settle=0.2,
               restarts=False)
    _log_pitcher(d, plan, "place_pitcher: down")
    d.grip(0.0, 0.6)
    d.settle(0.3)
    _log_pitcher(d, plan, "place_pitcher: released")
    ee, rot, _, _, _, _ = now()
    out = ee - BACK_OUT * rot[:, 2]
    d.move(_pose(out, rot), 0.8, segments=2, tol=APPROACH_TOL)
    d.move(_pose(out + [0.0, 0.0, 0.08], rot), 0.6, segments=1, tol=APPROACH_TOL)
    _log_pitcher(d, plan, "place_pitcher: backed off")
    stow(d)
