"""Where the hand goes on an articulated part (:mod:`stages.demos.parts`): gripper frames on a
handle bar, on the front face (pushing with the closed hand) and on a bottom-hinged door's free
edge, all turning with the part; the grasp pitch for a handle's height; the approach and arc
waypoints of one stage (:func:`gesture`) and the grips a plan tries (:func:`grips`).

World frame, metres, radians; 4x4 poses with the tool's approach axis along its z.
"""

from __future__ import annotations

import math

import numpy as np

from stages.demos.parts import ArticulatedPart, axis_angle

PUSH_INBOARD = 0.07  # pushing contact on the front face, this far from the bar towards the hinge [m]
LEVER_EXTRA = 0.1   # a lever's rose lies inboard of its grip centre: push further in [m]
PUSH_STANDOFF = 0.015  # tool centre off the face when touching it with the closed hand [m]
# closing a vertically hinged door, the fist may also press the front face turned this much [rad]
# about the vertical towards the hinge (from beside the free edge): the base then stands before the
# fridge instead of beyond its hinge, where a small kitchen has no floor (issue 16, store_food)
PUSH_YAWS = (math.radians(40.0), math.radians(65.0))
OVEN_GRIP_OFFSET = 0.12  # a bottom-hinged door's bar (70 % of the width) may be gripped off-centre [m]
GRASP_BACK = 0.12   # pre-grasp distance along the approach axis [m]
# pinching the free edge of a bottom-hinged (oven) door: catalog ovens have the bar's centre 5 cm
# from the edge and a leaf about 4 cm thick; the tool centre sits 1.5 cm in from the edge
EDGE_FROM_BAR = 0.05   # bar centre to the leaf's free edge [m]
EDGE_PINCH_IN = 0.015  # tool centre this far in from the edge [m]
LEAF_HALF_THICKNESS = 0.019  # [m]
EDGE_ALONG = (0.22, 0.12, 0.0)  # pinch offsets along the edge from its middle, towards the base [m]
# opening a vertically hinged leaf further by pushing its inner face with the closed hand (from before
# the opening, where a kitchen is too narrow to carry the handle round: issue 16, store_food):
# catalog fridge doors are 5.7 cm thick behind the bar's base; the fist presses 0.2 m in from the free edge
LEAF_THICKNESS = 0.057  # [m]
INNER_INBOARD = 0.2     # [m]


def heading(v) -> float:
    return math.atan2(float(v[1]), float(v[0]))


def _rz(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _ry(pitch: float) -> np.ndarray:
    c, s = math.cos(pitch), math.sin(pitch)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


# tool frames with the approach (tool z) along +X: fingers closing vertically (horizontal bars) or
# horizontally (vertical bars)
_FINGERS_VERTICAL = np.stack([[0, 1, 0], [0, 0, 1], [1, 0, 0]], axis=1).astype(float)
_FINGERS_HORIZONTAL = np.stack([[0, 0, -1], [0, 1, 0], [1, 0, 0]], axis=1).astype(float)


def grasp_rotation(part: ArticulatedPart, pitch: float, push: bool = False, yaw: float = 0.0,
                   inner: bool = False) -> np.ndarray:
    """(3, 3) gripper rotation grasping the handle at closed: approach against the front normal,
    pitched ``pitch`` [rad] down, fingers closing across the bar (``push``: along it, so that the
    hand's width runs parallel to the bar); ``yaw`` [rad]: the approach turned that much about the
    vertical towards the hinge (a push from beside the free edge); ``inner``: along the front
    normal (a push on the leaf's inner face, opening it)."""
    vertical_bar = abs(float(np.asarray(part.bar_axis)[2])) > 0.7
    base = _FINGERS_HORIZONTAL if vertical_bar != push else _FINGERS_VERTICAL
    face = np.asarray(part.front) if inner else -np.asarray(part.front)
    return _rz(heading(face) + toward_hinge(part) * yaw) @ _ry(pitch) @ base


def handle_pose(part: ArticulatedPart, q: float, pitch: float, back: float = 0.0) -> np.ndarray:
    """4x4 world pose of the gripper on the handle at joint value ``q`` (turning with the part),
    ``back`` [m] behind it along the approach axis."""
    rot = part.rotation_at(q) @ grasp_rotation(part, pitch)
    m = np.eye(4)
    m[:3, :3] = rot
    m[:3, 3] = part.handle_at(q) - back * rot[:, 2]
    return m


def lateral(part: ArticulatedPart) -> np.ndarray:
    """Doors: unit vector from the hinge axis towards the handle, perpendicular to the axis and
    the front (horizontal for vertical hinges, up for the oven's bottom hinge). Drawers: the
    horizontal bar axis."""
    n = np.asarray(part.front, float)
    if part.kind == "revolute":
        a = np.asarray(part.axis, float)
        v = np.asarray(part.handle) - np.asarray(part.origin)
        v = v - np.dot(v, a) * a
    else:
        v = np.asarray(part.bar_axis, float).copy()
        v[2] = 0.0
    v = v - np.dot(v, n) * n
    return v / max(np.linalg.norm(v), 1e-9)


def toward_hinge(part: ArticulatedPart) -> float:
    """+1 when turning the base counter-clockwise from facing the part turns it towards the hinge
    side (away from the handle), else -1."""
    face, lat = -np.asarray(part.front, float), lateral(part)
    return 1.0 if face[0] * (-lat[1]) - face[1] * (-lat[0]) > 0 else -1.0


def drawer_pitch(z: float) -> float:
    """Gripper pitch [rad] for a handle at height ``z`` [m]: level at shoulder height, pointing
    further down for low handles."""
    return math.radians(float(np.clip(20.0 + (0.75 - z) * 40.0, 0.0, 50.0)))


def door_pitch(z: float) -> float:
    """Gripper pitch [rad] for a vertical bar at height ``z`` [m] (down for low handles, up for
    high ones)."""
    return math.radians(float(np.clip(35.0 - (z - 0.3) * 45.0, -25.0, 40.0)))


def _tool_at(part: ArticulatedPart, p_closed, q: float, pitch: float, out: float = 0.0,
             push: bool = False, yaw: float = 0.0, inner: bool = False) -> np.ndarray:
    """4x4 world gripper pose at the link point ``p_closed`` (3,) carried to joint value q, ``out``
    [m] off the front face along its normal, turning with the part (``yaw``, ``inner``: see
    :func:`grasp_rotation`)."""
    rot = part.rotation_at(q) @ grasp_rotation(part, pitch, push, yaw, inner)
    m = np.eye(4)
    m[:3, :3] = rot
    m[:3, 3] = part.point_at(p_closed, q) + out * part.front_at(q)
    return m


def _lerp_pose(a: np.ndarray, b: np.ndarray, t: float) -> np.ndarray:
    """Pose between 4x4 ``a`` and ``b`` with the same rotation as ``b`` (positions interpolated)."""
    m = b.copy()
    m[:3, 3] = a[:3, 3] + t * (b[:3, 3] - a[:3, 3])
    return m


def _edge_gap(part: ArticulatedPart) -> float:
    """Distance [m] from the handle's grip centre to the leaf's free edge (catalog generators:
    bars 3-5 cm in, a lever's centre about 13 cm in)."""
    return 0.14 if part.handle_kind == "lever" else 0.06


def edge_point(part: ArticulatedPart, along: float = 0.0) -> np.ndarray:
    """The tool centre (3,) [m] pinching a bottom-hinged door's free edge, at closed: mid-thickness,
    EDGE_PINCH_IN in from the edge, above the bar's centre (``along`` [m] off it along the bar)."""
    h = np.asarray(part.handle, float) + along * np.asarray(part.bar_axis, float)
    n = np.asarray(part.front, float)
    face = h - (part.clearance + part.grip_width / 2) * n
    return face + (EDGE_FROM_BAR - EDGE_PINCH_IN) * lateral(part) - LEAF_HALF_THICKNESS * n


def edge_rotation(part: ArticulatedPart, tilt: float, flip: bool = False) -> np.ndarray:
    """(3, 3) gripper rotation pinching the free edge at closed: approach (tool z) from the edge
    towards the hinge, turned ``tilt`` [rad] about the hinge axis, fingers closing across the
    leaf's thickness (``flip``: the hand turned half a turn about its approach axis)."""
    z = -lateral(part)
    y = np.asarray(part.front, float)
    x = np.cross(y, z)
    r = np.stack([x, y, z], axis=1)
    if flip:
        r = r @ np.diag([-1.0, -1.0, 1.0])
    return axis_angle(np.asarray(part.axis, float), tilt) @ r


def _edge_tool(part: ArticulatedPart, q: float, tilt: float, along: float, back: float = 0.0) -> np.ndarray:
    """4x4 world gripper pose pinching the edge at joint value q (``back`` [m] out along the
    approach axis); tilt > pi / 2 encodes the flipped hand (tilt - pi)."""
    flip = tilt > math.pi / 2
    rot = part.rotation_at(q) @ edge_rotation(part, tilt - math.pi if flip else tilt, flip)
    m = np.eye(4)
    m[:3, :3] = rot
    m[:3, 3] = part.point_at(edge_point(part, along), q) - back * rot[:, 2]
    return m


def gesture(part: ArticulatedPart, q0: float, qs: list[float], pitch: float, mode: str = "grasp",
             along: float = 0.0):
    """(approach, arc): world gripper poses leading onto the part at q0 (for an opened door first
    round the leaf's free edge) and then carrying it along ``qs``. Grasp: on the handle bar,
    ``along`` [m] off its centre along the bar. Inner (``mode="inner"``, closed hand): on the inner
    face :data:`INNER_INBOARD` from the free edge, pushing it open. Push (``mode="push"``, closed hand): on the front
    face 7 cm inboard of the bar, pressing along the arc; for a vertical hinge ``along`` is instead
    the fist's yaw [rad] towards the hinge (:data:`PUSH_YAWS`, :func:`grasp_rotation`). Edge
    (``mode="edge"``, bottom-hinged doors): pinching the leaf's free edge, ``pitch`` being the tilt
    about the hinge axis (see :func:`_edge_tool`)."""
    if mode == "edge":
        contact = _edge_tool(part, q0, pitch, along)
        pre = _edge_tool(part, q0, pitch, along, GRASP_BACK)
        approach = [pre, *(_lerp_pose(pre, contact, a) for a in (1 / 3, 2 / 3)), contact]
        return approach, [_edge_tool(part, q, pitch, along) for q in qs]
    yaw = along if mode == "push" and _vertical_hinge(part) else 0.0
    h = np.asarray(part.handle, float) + (along - yaw) * np.asarray(part.bar_axis, float)
    front0 = np.asarray(part.front, float)
    if mode == "inner":  # the closed hand on the inner face, INNER_INBOARD from the free edge, pushing it open
        face = h - (part.clearance + part.grip_width / 2 + LEAF_THICKNESS) * front0 \
            - (INNER_INBOARD - _edge_gap(part)) * lateral(part)
        contact = _tool_at(part, face, q0, pitch, -PUSH_STANDOFF, push=True, inner=True)
        pre = _tool_at(part, face, q0, pitch, -PUSH_STANDOFF - GRASP_BACK, push=True, inner=True)
        approach = [pre, *(_lerp_pose(pre, contact, a) for a in (1 / 3, 2 / 3)), contact]
        return approach, [_tool_at(part, face, q, pitch, push=True, inner=True) for q in qs]
    if mode == "push":
        inboard = PUSH_INBOARD + (LEVER_EXTRA if part.handle_kind == "lever" else 0.0)
        face = h - (part.clearance + part.grip_width / 2) * front0 - inboard * lateral(part)
        contact = _tool_at(part, face, q0, pitch, PUSH_STANDOFF, push=True, yaw=yaw)
        arc = [_tool_at(part, face, q, pitch, push=True, yaw=yaw) for q in qs]
        pre = _tool_at(part, face, q0, pitch, PUSH_STANDOFF + GRASP_BACK, push=True, yaw=yaw)
        around = inboard + _edge_gap(part) + 0.12
    else:
        contact, arc = _tool_at(part, h, q0, pitch), [_tool_at(part, h, q, pitch) for q in qs]
        pre = _tool_at(part, h, q0, pitch, GRASP_BACK)
        around = _edge_gap(part) + 0.12
    approach = [pre, *(_lerp_pose(pre, contact, a) for a in (1 / 3, 2 / 3)), contact]
    if part.kind == "revolute" and q0 - part.closed > 0.15 * part.travel:
        edge = pre.copy()
        edge[:3, 3] += around * (part.rotation_at(q0) @ lateral(part))
        approach.insert(0, edge)
    return approach, arc


def _vertical_hinge(part: ArticulatedPart) -> bool:
    return part.kind == "revolute" and abs(float(np.asarray(part.axis)[2])) > 0.7


def grips(part: ArticulatedPart, base, p0: float, vertical: bool, edge: bool = False,
          push: bool = False) -> list[tuple[float, float]]:
    """(pitch, along) grips to try: the pitch for the handle's height and +-15 deg; a bottom-hinged
    door's long bar is also gripped OVEN_GRIP_OFFSET towards the base. ``edge``: tilts 0 and
    +-20 deg, each also with the hand flipped (tilt + pi), at the bar's centre and offset.
    ``push`` on a vertically hinged door: also the fist turned by :data:`PUSH_YAWS` (``along``
    carries the yaw, see :func:`gesture`)."""
    side = float(np.dot(np.asarray(base[:2]) - np.asarray(part.handle[:2]), np.asarray(part.bar_axis)[:2]))
    if edge:  # from beside the lying leaf: pinch its edge near the corner on the base's side
        tilts = tuple(t + f for f in (0.0, math.pi) for t in (0.0, math.radians(-20), math.radians(20)))
        return [(t, math.copysign(a, side)) for a in EDGE_ALONG for t in tilts]
    pitches = (p0, p0 - math.radians(15), p0 + math.radians(15))
    out = [(p, 0.0) for p in pitches]
    if push and vertical and _vertical_hinge(part):
        out += [(p, y) for y in PUSH_YAWS for p in pitches]
    if not vertical:
        out += [(p, math.copysign(OVEN_GRIP_OFFSET, side)) for p in pitches]
    return out
