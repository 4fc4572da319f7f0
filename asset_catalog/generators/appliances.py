"""Articulated appliances and fixtures: fridge, microwave, oven/stove, room door, alarm clock.

Joint conventions (root frame, +X front): doors open towards +X with positive angles; drawers slide
along +X; push buttons move along their inward normal (0 = out, upper = pressed); knobs turn about
their outward normal. Appliances are hollow: masses are real appliance weights, not density x volume.
"""

from __future__ import annotations

import numpy as np

import asset_catalog.generators._geom as g
from asset_catalog.generators._builder import AssetBuilder
from asset_catalog.generators._parts import (
    APPLIANCE, GAP, METALS, WOODS, bar_handle, hinged_door, knob, panel, pick_color)

SHELL = 1000.0   # relative density of appliance shells (scaled to the target mass)
DOOR_JAMB = 0.04        # room door frame: jamb width [m]
DOOR_GAP = 0.003        # gap between leaf and frame [m]
DOOR_FLOOR_GAP = 0.01   # gap under the leaf [m]


def fridge(b: AssetBuilder) -> float:
    body = b.material("body", pick_color(b, APPLIANCE, 0.02), roughness=0.3, metallic=0.3)
    liner = b.material("liner", (0.95, 0.95, 0.95), roughness=0.4)
    glass = b.material("shelf", (0.8, 0.88, 0.9), roughness=0.1)
    handle = b.material("handle", pick_color(b, METALS), roughness=0.25, metallic=1.0)
    w, d, h = b.param("width", 0.55, 0.9), b.param("depth", 0.6, 0.72), b.param("height", 1.5, 1.9)
    style = b.choice("style", ["single", "top_freezer", "side_by_side"])
    if style == "side_by_side":
        w = max(w, 0.75)
    t, dt, feet = 0.035, b.param("door_thickness", 0.05, 0.07), 0.03
    x_body = d - dt
    xb0, xb1 = -d / 2, -d / 2 + x_body
    panel(b, "base", (xb0, -w / 2, feet), (xb1, -w / 2 + t, h), body, SHELL)
    panel(b, "base", (xb0, w / 2 - t, feet), (xb1, w / 2, h), body, SHELL)
    panel(b, "base", (xb0, -w / 2 + t, feet), (xb0 + t, w / 2 - t, h), body, SHELL)
    panel(b, "base", (xb0 + t - 0.002, -w / 2 + t - 0.002, feet), (xb1, w / 2 - t + 0.002, feet + 0.08), liner,
          SHELL)
    panel(b, "base", (xb0 + t, -w / 2 + t, h - t), (xb1, w / 2 - t, h), body, SHELL)
    b.surface(feet + 0.08, (xb0 + t, -w / 2 + t), (xb1, w / 2 - t), inside=True,
              clear_height=(h - 0.2) / 4 - 0.008)
    for i in range(1, 4):
        z = feet + 0.08 + i * (h - 0.2) / 4
        panel(b, "base", (xb0 + t - 0.002, -w / 2 + t - 0.002, z), (xb1 - 0.03, w / 2 - t + 0.002, z + 0.008), glass,
              SHELL)
        b.surface(z + 0.008, (xb0 + t, -w / 2 + t), (xb1 - 0.03, w / 2 - t), inside=True,
                  clear_height=(h - 0.2) / 4 - 0.008 if i < 3 else h - t - z - 0.008)
    for x in (xb0 + 0.05, xb1 - 0.05):
        for y in (-w / 2 + 0.05, w / 2 - 0.05):
            b.add("base", g.cylinder(0.02, feet + 0.002, (x, y, (feet + 0.002) / 2), n=12), handle,
                  density=SHELL)
    hinge = b.choice("hinge", ["left", "right"])
    hd = b.param("handle_diameter", 0.018, 0.026)
    kw = dict(parent="base", mat=body, handle_mat=handle, density=SHELL * 0.6, x_front=xb1,
              thickness=dt - GAP,
              effort=60.0, handle_diameter=hd, handle_clearance=b.param("handle_clearance", 0.03, 0.045))
    if style == "single":
        hinged_door(b, "door_0", y0=-w / 2, y1=w / 2, z0=feet, z1=h, hinge=hinge, handle_len=0.5,
                    handle_z=h * 0.6, **kw)
    elif style == "top_freezer":
        zf = h - b.param("freezer_height", 0.35, 0.5)
        hinged_door(b, "door_0", y0=-w / 2, y1=w / 2, z0=feet, z1=zf, hinge=hinge, handle_len=0.4,
                    handle_z=zf - 0.3, **kw)
        hinged_door(b, "door_1", y0=-w / 2, y1=w / 2, z0=zf, z1=h, hinge=hinge, handle_len=0.2,
                    handle_z=zf + 0.15, **kw)
    else:
        hinged_door(b, "door_0", y0=-w / 2, y1=0.0, z0=feet, z1=h, hinge="left", handle_len=0.5,
                    handle_z=h * 0.6, handle_inset=0.04, **kw)
        hinged_door(b, "door_1", y0=0.0, y1=w / 2, z0=feet, z1=h, hinge="right", handle_len=0.5,
                    handle_z=h * 0.6, handle_inset=0.04, **kw)
    return b.param("mass", 45.0, 60.0) * (w * h) / 0.9


def microwave(b: AssetBuilder) -> float:
    body = b.material("body", pick_color(b, APPLIANCE, 0.02), roughness=0.35, metallic=0.2)
    inner = b.material("cavity", (0.85, 0.85, 0.82), roughness=0.5)
    glass = b.material("window", (0.05, 0.06, 0.07), roughness=0.05)
    btn = b.material("button", pick_color(b, [(0.3, 0.3, 0.32), (0.85, 0.85, 0.85)]), roughness=0.4)
    handle = b.material("handle", pick_color(b, METALS), roughness=0.3, metallic=1.0)
    w, d, h = b.param("width", 0.45, 0.56), b.param("depth", 0.34, 0.42), b.param("height", 0.26, 0.32)
    pw = b.param("panel_width", 0.1, 0.13)
    t, dt, feet = 0.012, 0.03, 0.01
    xb1 = d / 2 - dt
    x0 = -d / 2
    cy1 = w / 2 - pw
    panel(b, "base", (x0, -w / 2, feet), (xb1, -w / 2 + t, h), body, SHELL)
    panel(b, "base", (x0, -w / 2 + t, feet), (x0 + t, cy1, h), body, SHELL)
    panel(b, "base", (x0, -w / 2 + t, feet), (xb1, cy1, feet + t), inner, SHELL)
    b.surface(feet + t, (x0 + t, -w / 2 + t), (xb1, cy1), inside=True, clear_height=h - feet - 2 * t)
    panel(b, "base", (x0, -w / 2 + t, h - t), (xb1, cy1, h), body, SHELL)
    panel(b, "base", (x0, cy1, feet), (d / 2, w / 2, h), body, SHELL)
    for x in (x0 + 0.04, xb1 - 0.04):
        for y in (-w / 2 + 0.04, w / 2 - 0.04):
            b.add("base", g.cylinder(0.012, feet + 0.001, (x, y, (feet + 0.001) / 2), n=12), btn,
                  density=SHELL)
    b.link("door", parent="base", origin=(d / 2, -w / 2 + GAP, (feet + h) / 2), joint="revolute", axis=(0, 0,
                                                                                                        -1),
           lower=0.0, upper=float(np.pi / 2), effort=10.0, velocity=2.0, damping=0.2, friction=0.05, role="door")
    panel(b, "door", (xb1 + GAP, -w / 2 + GAP, feet + GAP), (d / 2, cy1 - GAP, h - GAP), body, SHELL)
    panel(b, "door", (d / 2 - 0.002, -w / 2 + 0.05, feet + 0.04), (d / 2 + 0.001, cy1 - 0.06, h - 0.04),
          glass, SHELL)
    bar_handle(b, "door", handle, x_surface=d / 2, center_yz=(cy1 - 0.03, (feet + h) / 2), along="z",
               length=min(0.18, h - 0.08), diameter=0.014, clearance=0.025)
    py = (cy1 + w / 2) / 2
    for i in range(3):
        zz = h - 0.07 - i * 0.035
        panel(b, "base", (d / 2, py - 0.03, zz - 0.012), (d / 2 + 0.003, py + 0.03, zz + 0.012), btn, SHELL)
    travel = b.param("button_travel", 0.004, 0.007)
    bz = feet + 0.05
    b.link("button", parent="base", origin=(d / 2, py, bz), joint="prismatic", axis=(-1, 0, 0), lower=0.0,
           upper=travel, effort=10.0, velocity=0.1, damping=0.5, friction=0.05, role="button")
    # the cap (the collider) stands travel + 1 mm proud of the panel, so pressing it fully stays clear
    stem = g.box_between((d / 2 - 0.002, py - 0.02, bz - 0.008), (d / 2 + travel + 0.0015, py + 0.02,
                                                                  bz + 0.008))
    b.add("button", stem, btn, density=SHELL, collision="none")
    b.add("button", g.box_between((d / 2 + travel + 0.001, py - 0.025, bz - 0.0125),
                                  (d / 2 + travel + 0.009, py + 0.025, bz + 0.0125)), btn, density=SHELL)
    return b.param("mass", 10.0, 17.0)


#: oven door hinge (spring, hold) as fractions of the door's gravity torque m g r: the spring
#: (0.4 m g r per rad towards closed) and friction (0.3 m g r) hold the door anywhere below ~30 deg
#: and let it drop gently onto its open stop above that, as a real oven door's hinge springs do
OVEN_DOOR_BALANCE = (0.4, 0.3)
#: the hinge mechanism's added inertia [kg m^2]: a leaf held by friction alone creeps ~0.2 deg/s
#: under MuJoCo's soft friction constraint at 15 deg; 5 kg m^2 slows that six-fold (measured)
OVEN_DOOR_ARMATURE = 5.0


def oven(b: AssetBuilder) -> float:
    body = b.material("body", pick_color(b, APPLIANCE, 0.02), roughness=0.3, metallic=0.4)
    inner = b.material("cavity", (0.1, 0.1, 0.11), roughness=0.6)
    glass = b.material("window", (0.04, 0.04, 0.05), roughness=0.05)
    cook = b.material("cooktop", (0.08, 0.08, 0.09), roughness=0.2)
    burner = b.material("burner", (0.25, 0.25, 0.26), roughness=0.5, metallic=0.5)
    handle = b.material("handle", pick_color(b, METALS), roughness=0.25, metallic=1.0)
    knob_m = b.material("knob", pick_color(b, [(0.15, 0.15, 0.15), (0.8, 0.8, 0.8)]), roughness=0.4)
    w, d, h = b.param("width", 0.58, 0.76), b.param("depth", 0.58, 0.65), b.param("height", 0.85, 0.92)
    t, dt, plinth = 0.025, 0.04, 0.08
    xb1 = d / 2 - dt
    x0 = -d / 2
    zc1 = h - b.param("panel_height", 0.12, 0.16)
    panel(b, "base", (x0, -w / 2, 0), (xb1, -w / 2 + t, zc1), body, SHELL)
    panel(b, "base", (x0, w / 2 - t, 0), (xb1, w / 2, zc1), body, SHELL)
    panel(b, "base", (x0, -w / 2 + t, 0), (x0 + t, w / 2 - t, zc1), inner, SHELL)
    panel(b, "base", (x0 + t, -w / 2 + t, 0), (xb1, w / 2 - t, plinth), body, SHELL)
    panel(b, "base", (x0 + t, -w / 2 + t, zc1 - t), (xb1, w / 2 - t, zc1), inner, SHELL)
    panel(b, "base", (x0 + t, -w / 2 + 0.03, plinth + 0.15), (xb1 - 0.05, w / 2 - 0.03, plinth + 0.16),
          burner, SHELL)
    panel(b, "base", (x0, -w / 2, zc1), (d / 2, w / 2, h - 0.02), body, SHELL)
    panel(b, "base", (x0, -w / 2, h - 0.02), (d / 2, w / 2, h), cook, SHELL)
    b.surface(h, (x0, -w / 2), (d / 2, w / 2))
    for sx in (-1, 1):
        for sy in (-1, 1):
            r = b.param(f"burner_{sx}_{sy}", 0.05, 0.09)
            b.add("base", g.cylinder(r, 0.012, (sx * d / 4 - 0.02, sy * w / 4, h + 0.005), n=32), burner,
                  density=SHELL)
    b.link("door", parent="base", origin=(d / 2, 0.0, plinth + GAP), joint="revolute", axis=(0, 1, 0),
           lower=0.0,
           upper=1.5, effort=40.0, velocity=1.5, damping=8.0, role="door", counterbalance=OVEN_DOOR_BALANCE,
           armature=OVEN_DOOR_ARMATURE)
    zd1 = zc1 - GAP
    panel(b, "door", (xb1 + GAP, -w / 2 + GAP, plinth + GAP), (d / 2, w / 2 - GAP, zd1), body, SHELL)
    panel(b, "door", (d / 2 - 0.002, -w / 2 + 0.08, plinth + 0.12), (d / 2 + 0.001, w / 2 - 0.08,
                                                                     zd1 - 0.12), glass,
          SHELL)
    bar_handle(b, "door", handle, x_surface=d / 2, center_yz=(0.0, zd1 - 0.05), along="y", length=w * 0.7,
               diameter=b.param("handle_diameter", 0.016, 0.024), clearance=0.035)
    n_knobs = int(b.choice("knobs", [4, 5]))
    kz = (zc1 + h - 0.02) / 2
    for i in range(n_knobs):
        ky = -w / 2 + w * (i + 0.5) / n_knobs
        knob(b, f"knob_{i}", parent="base", mat=knob_m, x_surface=d / 2, y=ky, z=kz, radius=0.02, depth=0.025)
    return b.param("mass", 40.0, 70.0)


#: room door hinge: damping [N m s/rad] and friction [N m]; a ~30 kg leaf (~7 kg m^2 about its hinge)
#: let go of at 0.3 rad/s coasts ~0.2 rad and stops (with 2 / 0.5 it swung on for a radian)
ROOM_DOOR_DAMPING = 10.0
ROOM_DOOR_FRICTION = 3.0


def room_door(b: AssetBuilder) -> float | None:
    """A hinged door leaf in its frame. The asset's bounding box is the wall opening it fills:
    width = leaf + 2 x (jamb + gap), height = leaf + floor gap + head; depth (X) = wall thickness."""
    wood = b.material("leaf", pick_color(b, WOODS + [(0.95, 0.95, 0.93)] * 2), roughness=0.5)
    frame = b.material("frame", pick_color(b, WOODS + [(0.95, 0.95, 0.93)]), roughness=0.5)
    metal = b.material("handle", pick_color(b, METALS), roughness=0.25, metallic=1.0)
    lw, lh = b.param("leaf_width", 0.8, 0.9), b.param("leaf_height", 1.98, 2.05)
    lt, wall = b.param("leaf_thickness", 0.035, 0.045), b.param("wall_thickness", 0.1, 0.15)
    jamb, floor_gap, gap = DOOR_JAMB, DOOR_FLOOR_GAP, DOOR_GAP
    ow = lw + 2 * (jamb + gap)
    oh = lh + floor_gap + gap + jamb
    panel(b, "base", (-wall / 2, -ow / 2, 0), (wall / 2, -ow / 2 + jamb, oh), frame, 700.0)
    panel(b, "base", (-wall / 2, ow / 2 - jamb, 0), (wall / 2, ow / 2, oh), frame, 700.0)
    panel(b, "base", (-wall / 2, -ow / 2 + jamb, oh - jamb), (wall / 2, ow / 2 - jamb, oh), frame, 700.0)
    # stop strips behind the leaf (the leaf opens towards +X, away from them)
    for y0, y1 in ((-ow / 2 + jamb - 0.002, -ow / 2 + jamb + 0.012), (ow / 2 - jamb - 0.012, ow / 2 - jamb + 0.002)):
        panel(b, "base", (-wall / 2, y0, 0), (-lt / 2 - gap, y1, oh - jamb + 0.002), frame, 700.0)
    hinge = b.choice("hinge", ["left", "right"])
    hy = -ow / 2 + jamb + gap if hinge == "left" else ow / 2 - jamb - gap
    sgn = 1.0 if hinge == "left" else -1.0
    b.link("leaf", parent="base", origin=(lt / 2, hy, floor_gap), joint="revolute",
           axis=(0, 0, -1) if hinge == "left" else (0, 0, 1), lower=0.0, upper=float(np.pi / 2), effort=50.0,
           velocity=1.5, damping=ROOM_DOOR_DAMPING, friction=ROOM_DOOR_FRICTION, role="door")
    ly0, ly1 = sorted((hy, hy + sgn * lw))
    panel(b, "leaf", (-lt / 2, ly0, floor_gap), (lt / 2, ly1, floor_gap + lh), wood, 450.0)
    hz = b.param("handle_height", 0.95, 1.05)
    yl = hy + sgn * (lw - 0.065)
    lever_len = b.param("lever_length", 0.11, 0.14)
    lr = b.param("lever_radius", 0.008, 0.011)
    standoff = 0.055
    for side in (1, -1):
        xs = side * lt / 2
        b.add("leaf", g.cylinder(0.026, 0.014, (xs + side * 0.005, yl, hz), axis="x", n=24), metal,
              density=7800.0)
        b.add("leaf", g.cylinder(0.009, standoff + 0.001, (xs + side * (standoff / 2 + 0.006), yl, hz),
                                 axis="x", n=16),
              metal, density=7800.0)
        lever = g.cylinder(lr, lever_len, (xs + side * (standoff + 0.006 - lr),
                                           yl - sgn * (lever_len / 2 - 0.009), hz),
                           axis="y", n=16)
        b.add("leaf", lever, metal, density=7800.0)
        b.handle("leaf", (xs + side * (standoff + 0.006 - lr), yl - sgn * lever_len / 2, hz), 2 * lr,
                 standoff + 0.006 - 2 * lr, (0.0, 1.0, 0.0), kind="lever")
    return None


#: the alarm clock's slide switch: travel range [m]; knob (width along the slide, protrusion from the
#: back face, height) [m]; joint damping [N s/m], friction [N] and armature [kg]: a fingertip pushes
#: it with ~0.2 N (a 0.2 kg clock slides on the counter at ~1 N), and it stays where it is left
#: its top button's return spring [N/m] (the ~6 g button sags 0.2 mm under gravity; pressed in fully
#: it pushes back ~1.5 N; without it gravity held the button pressed), damping [N s/m] and armature
#: [kg]. The armature also stiffens the fingertip's contact: MuJoCo's soft contact pushes with a force
#: in proportion to the contact's effective mass, and on a 16 g button the fingertip sank through the
#: cap against the spring (measured: the button did not move, the tip went 8 mm past the cap)
CLOCK_BUTTON_SPRING = 300.0
CLOCK_BUTTON_DAMPING = 10.0
CLOCK_BUTTON_ARMATURE = 0.5
CLOCK_SWITCH_TRAVEL = (0.012, 0.018)
CLOCK_KNOB = (0.008, 0.012, 0.014)
CLOCK_SWITCH_DAMPING = 1.0
CLOCK_SWITCH_FRICTION = 0.1
CLOCK_SWITCH_ARMATURE = 0.3  # (the fingertip's contact on the knob, as the button's)


def alarm_clock(b: AssetBuilder) -> float:
    """A twin-bell (round) or boxy alarm clock: face +X, a push button on top (role ``button``,
    pressed along -Z), an on/off slide switch on the back (role ``switch``, +Y, see CLOCK_*)."""
    body = b.material("body", pick_color(b, [(0.85, 0.2, 0.18), (0.15, 0.4, 0.75), (0.2, 0.2, 0.2),
                                             (0.9, 0.8, 0.2), (0.3, 0.65, 0.35)]), roughness=0.35)
    face = b.material("face", (0.97, 0.97, 0.95), roughness=0.6)
    hands = b.material("hands", (0.05, 0.05, 0.05), roughness=0.5)
    metal = b.material("metal", (0.8, 0.8, 0.82), roughness=0.2, metallic=1.0)
    r = b.param("radius", 0.045, 0.065)
    depth = b.param("depth", 0.035, 0.055)
    zc = r + 0.012
    round_body = b.choice("shape", [True, False])
    if round_body:
        b.add("base", g.cylinder(r, depth, (0, 0, zc), axis="x", n=40), body, density=700.0)
        top = zc + r
    else:
        b.add("base", g.rounded_box((depth, 2 * r, 2 * r), 0.012, (0, 0, zc), n=8), body, density=700.0)
        top = zc + r
    b.add("base", g.cylinder(r * 0.82, 0.004, (depth / 2 + 0.001, 0, zc), axis="x", n=40), face,
          density=700.0)
    b.add("base", g.box((0.002, 0.004, r * 0.6), (depth / 2 + 0.004, 0, zc + r * 0.28)), hands, density=700.0)
    b.add("base", g.box((0.002, r * 0.45, 0.004), (depth / 2 + 0.0045, r * 0.2, zc)), hands, density=700.0)
    for s in (-1, 1):
        b.add("base", g.box((depth * 0.6, 0.012, 0.02), (0, s * r * 0.55, 0.01)), metal, density=2000.0)
        if round_body:
            bell = g.sphere(r * 0.38, (0, s * r * 0.62, top - r * 0.12), n=20)
            b.add("base", bell, metal, density=1500.0)
    travel = b.param("button_travel", 0.003, 0.005)
    b.link("button", parent="base", origin=(0, 0, top), joint="prismatic", axis=(0, 0, -1), lower=0.0,
           upper=travel, effort=5.0, velocity=0.1, damping=CLOCK_BUTTON_DAMPING, friction=0.01, role="button",
           spring=CLOCK_BUTTON_SPRING, armature=CLOCK_BUTTON_ARMATURE)
    b.add("button", g.cylinder(0.008, travel + 0.012, (0, 0, top + 0.006 - travel / 2 + 0.0005), n=16), metal,
          density=1000.0, collision="none")
    b.add("button", g.cylinder(0.013, 0.005, (0, 0, top + 0.009 + 0.0005), n=20), metal, density=1000.0)
    # the alarm's on/off slide switch on the back face (-X), sliding along +Y (0 = off at -Y, upper = on)
    sw = b.param("switch_travel", CLOCK_SWITCH_TRAVEL[0], CLOCK_SWITCH_TRAVEL[1])
    xb, zs = -depth / 2, zc
    kw, kh = CLOCK_KNOB[0], CLOCK_KNOB[2]
    b.add("base", g.box_between((xb - 0.0015, -sw / 2 - kw / 2 - 0.003, zs - 0.003),
                                (xb + 0.001, sw / 2 + kw / 2 + 0.003, zs + 0.003)), hands, density=700.0,
          collision="none")  # the slot (visual)
    b.link("switch", parent="base", origin=(xb, -sw / 2, zs), joint="prismatic", axis=(0, 1, 0), lower=0.0,
           upper=sw, effort=5.0, velocity=0.2, damping=CLOCK_SWITCH_DAMPING, friction=CLOCK_SWITCH_FRICTION,
           role="switch", armature=CLOCK_SWITCH_ARMATURE)
    b.add("switch", g.box_between((xb - 0.004, -sw / 2 - 0.002, zs - 0.002), (xb + 0.003, -sw / 2 + 0.002,
                                                                               zs + 0.002)), metal,
          density=1000.0, collision="none")  # the stem in the slot (visual)
    knob_lo = (xb - 0.0015 - CLOCK_KNOB[1], -sw / 2 - kw / 2, zs - kh / 2)
    knob_hi = (xb - 0.002, -sw / 2 + kw / 2, zs + kh / 2)
    b.add("switch", g.box_between(knob_lo, knob_hi), body, density=1000.0)
    return b.param("mass", 0.18, 0.45)
