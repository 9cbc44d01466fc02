"""The ``mechanical`` starting point of `servoface new`: an 8-servo head of rigid parts, no skin.

Jaw, two brows on levers, two upper lids, eye pan and eye tilt (each one servo for both eyes) and neck
pan. The meshes are simple solids written as STL files (mm, head frame), so the folder shows where your
own CAD exports go; the direct table drives the brows (no muscle model reaches a rigid brow).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

EYE_L = (32.0, 122.0, 58.0)
EYE_RADIUS_MM = 13.0
LID_RADIUS_MM = 14.0  # the upper lid's inner radius: 1 mm clear of the eye (and of the pupil, 0.5 mm proud)
UPPER_LID_EDGE_DEG = 22.0  # the open lid's edge, above the pupil (beta, up from straight ahead)
LOWER_LID_TOP_DEG = -36.0  # the fixed lower lid's edge; a blink (+70 deg) brings the upper lid's to -48


def _box(lo: tuple[float, float, float], hi: tuple[float, float, float]) -> object:
    import trimesh

    lo_a, hi_a = np.array(lo), np.array(hi)
    box = trimesh.creation.box(extents=hi_a - lo_a)
    box.apply_translation((lo_a + hi_a) / 2)
    return box


def _sphere(centre: tuple[float, float, float], radius: float, subdivisions: int = 3) -> object:
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    s.apply_translation(centre)
    return s


def _lid_shell(
    centre: tuple[float, float, float], radius: float, beta_deg: tuple[float, float], thick_mm: float = 1.0
) -> object:
    """A smooth spherical lid shell around the eye, closed (watertight) and ``thick_mm`` thick.

    beta = the angle about the eye's x axis from straight ahead (+z) towards up (+y), so the lid's edge is
    a great circle through the eye's left and right poles and turning the lid about x only shifts beta.
    Dense rows and columns: the edges are smooth arcs, not the steps of a cut icosphere."""
    import trimesh
    from servoface.sim.heads import mesh_tools as mt

    rows = max(8, int(round((beta_deg[1] - beta_deg[0]) / 3.0)))
    outer = mt.sphere_patch(np.zeros(3), radius + thick_mm, beta_deg, (-88.0, 88.0), rows, 48)
    inner = mt.sphere_patch(np.zeros(3), radius, beta_deg, (-88.0, 88.0), rows, 48)
    v, f = mt.shell_from_grids(outer, inner)
    mesh = trimesh.Trimesh(v + np.asarray(centre), f, process=False)
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def _lid(centre: tuple[float, float, float]) -> object:
    """The upper lid: a shell just outside the eye from above the pupil, over the top, to behind the eye.

    It closes by turning about the eye's x axis (+70 deg for a blink) and then covers the whole front of the
    eye down to ``LOWER_LID_TOP_DEG``, where the fixed lower lid takes over (a rigid lid turning 70 deg
    alone cannot cover a whole hemisphere)."""
    return _lid_shell(centre, LID_RADIUS_MM, (UPPER_LID_EDGE_DEG, UPPER_LID_EDGE_DEG + 178.0))


def _lower_lid(centre: tuple[float, float, float]) -> object:
    """The fixed lower lid: a shell just outside the upper lid, under the front of the eye."""
    return _lid_shell(centre, LID_RADIUS_MM + 1.5, (-100.0, LOWER_LID_TOP_DEG))


def _cylinder(radius: float, y0: float, y1: float, z: float = 0.0) -> object:
    import trimesh

    c = trimesh.creation.cylinder(radius=radius, height=y1 - y0, sections=24)
    upright = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
    c.apply_transform(upright)  # the cylinder's axis from z to y
    c.apply_translation((0.0, (y0 + y1) / 2, z))
    return c


def _mirror(x: tuple[float, float, float]) -> tuple[float, float, float]:
    return (-x[0], x[1], x[2])


def meshes() -> dict[str, object]:
    """name -> trimesh.Trimesh of every part of the mechanical head (mm, head frame, at rest)."""
    import trimesh

    eye_r = _mirror(EYE_L)
    skull = trimesh.util.concatenate(
        [
            _box((-62.0, 78.0, -70.0), (62.0, 190.0, 38.0)),  # the face plate's front is z = 38
            _box((-9.0, 92.0, 38.0), (9.0, 114.0, 56.0)),  # nose
        ]
    )
    out: dict[str, object] = {
        "neck_base": _cylinder(26.0, -70.0, -4.0),
        "neck": _cylinder(22.0, 0.0, 76.0, -32.0),
        "skull": skull,
        "jaw": _box((-40.0, 38.0, 18.0), (40.0, 70.0, 62.0)),
        "eye_l": _sphere(EYE_L, EYE_RADIUS_MM),
        "eye_r": _sphere(eye_r, EYE_RADIUS_MM),
        # the pupil stands only 0.5 mm proud of the eye, so a closed lid hides it
        "pupil_l": _sphere((EYE_L[0], EYE_L[1], EYE_L[2] + EYE_RADIUS_MM - 3.5), 4.0, 3),
        "pupil_r": _sphere((eye_r[0], eye_r[1], eye_r[2] + EYE_RADIUS_MM - 3.5), 4.0, 3),
        "lid_l": _lid(EYE_L),
        "lid_r": _lid(eye_r),
        "lower_lid_l": _lower_lid(EYE_L),
        "lower_lid_r": _lower_lid(eye_r),
        "brow_l": _box((18.0, 147.0, 52.0), (50.0, 153.0, 60.0)),
        "brow_r": _box((-50.0, 147.0, 52.0), (-18.0, 153.0, 60.0)),
    }
    return out


def write_meshes(folder: Path) -> list[Path]:
    """Write every part as ``folder/<name>.stl``; returns the paths."""
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name, mesh in meshes().items():
        path = folder / f"{name}.stl"
        mesh.export(str(path))  # type: ignore[attr-defined]
        written.append(path)
    return written


HEAD_TOML = """\
# servoface head profile: a purely mechanical head (rigid parts on joints, no skin), 8 servos.
# Written by `servoface new --from mechanical`. Edit it to match your head: replace the meshes in meshes/
# by your own STL/OBJ/GLB exports (mm; for metres set scale = 1000), move the pivots and axes to your
# hinges, set the servo ids and models you assigned (`servoface scan` lists them).
# Frame: mm, +y up, +z out of the face, +x to the head's own LEFT; origin = top of the neck.
# Angles: degrees, positive by the right-hand rule about the joint axis. Schema: sim/heads/README.md.
# Next: `servoface calibrate --head {folder} --csv {folder}/calibration_template.csv` (edit the ticks to what
# you measured), or interactively on the head: `servoface calibrate --head {folder} --port /dev/ttyUSB0`.

schema_version = 1
name = "{name}"
face_type = "human"              # FACS AUs and the human expression library
description = "Mechanical head: jaw, brows on levers, upper lids, eye pan/tilt, neck pan."
calibration = "calibration.json" # written by `servoface calibrate`
au_direct = "direct.toml"        # AU -> actuator targets for what the muscle table cannot reach (brows)

[landmarks]
eye_centre_l = [32.0, 122.0, 58.0]
eye_centre_r = [-32.0, 122.0, 58.0]

# --- joints ---------------------------------------------------------------------------------------------
[[joint]]
name = "neck_pan"                # yaw, + = the head turns to its left
pivot_mm = [0.0, 0.0, 0.0]
axis = [0.0, 1.0, 0.0]
limits_deg = [-60.0, 60.0]

[[joint]]
name = "jaw"                     # + = open
parent = "neck_pan"
pivot_mm = [0.0, 80.0, 0.0]
axis = [1.0, 0.0, 0.0]
limits_deg = [0.0, 25.0]

[[joint]]
name = "brow_l"                  # a lever behind the brow bar: + = brow up
parent = "neck_pan"
pivot_mm = [34.0, 150.0, 30.0]
axis = [-1.0, 0.0, 0.0]
limits_deg = [-10.0, 20.0]

[[joint]]
name = "brow_r"
parent = "neck_pan"
pivot_mm = [-34.0, 150.0, 30.0]
axis = [-1.0, 0.0, 0.0]
limits_deg = [-10.0, 20.0]

[[joint]]
name = "upper_lid_l"             # about the eye centre: + = closing, - = wide open
parent = "neck_pan"
pivot_mm = [32.0, 122.0, 58.0]
axis = [1.0, 0.0, 0.0]
limits_deg = [-15.0, 70.0]

[[joint]]
name = "upper_lid_r"
parent = "neck_pan"
pivot_mm = [-32.0, 122.0, 58.0]
axis = [1.0, 0.0, 0.0]
limits_deg = [-15.0, 70.0]

[[joint]]
name = "eye_pan_l"               # + = the eye turns to the head's left
parent = "neck_pan"
pivot_mm = [32.0, 122.0, 58.0]
axis = [0.0, 1.0, 0.0]
limits_deg = [-35.0, 35.0]

[[joint]]
name = "eye_pan_r"
parent = "neck_pan"
pivot_mm = [-32.0, 122.0, 58.0]
axis = [0.0, 1.0, 0.0]
limits_deg = [-35.0, 35.0]

[[joint]]
name = "eye_tilt_l"              # + = up
parent = "eye_pan_l"
pivot_mm = [32.0, 122.0, 58.0]
axis = [-1.0, 0.0, 0.0]
limits_deg = [-25.0, 25.0]

[[joint]]
name = "eye_tilt_r"
parent = "eye_pan_r"
pivot_mm = [-32.0, 122.0, 58.0]
axis = [-1.0, 0.0, 0.0]
limits_deg = [-25.0, 25.0]

# --- rigid parts (collides = false: drawn only, the twin gate ignores it) --------------------------------
[[part]]
name = "neck_base"
mesh = "meshes/neck_base.stl"
color_rgba = [0.30, 0.31, 0.34, 1.0]

[[part]]
name = "neck"
joint = "neck_pan"
mesh = "meshes/neck.stl"
color_rgba = [0.30, 0.31, 0.34, 1.0]

[[part]]
name = "skull"
joint = "neck_pan"
mesh = "meshes/skull.stl"
color_rgba = [0.78, 0.74, 0.68, 1.0]

[[part]]
name = "jaw"
joint = "jaw"
mesh = "meshes/jaw.stl"
color_rgba = [0.70, 0.66, 0.60, 1.0]

[[part]]
name = "brow_l"
joint = "brow_l"
mesh = "meshes/brow_l.stl"
color_rgba = [0.20, 0.16, 0.14, 1.0]

[[part]]
name = "brow_r"
joint = "brow_r"
mesh = "meshes/brow_r.stl"
color_rgba = [0.20, 0.16, 0.14, 1.0]

[[part]]
name = "eye_l"
joint = "eye_tilt_l"
mesh = "meshes/eye_l.stl"
color_rgba = [0.97, 0.97, 0.95, 1.0]

[[part]]
name = "eye_r"
joint = "eye_tilt_r"
mesh = "meshes/eye_r.stl"
color_rgba = [0.97, 0.97, 0.95, 1.0]

[[part]]
name = "pupil_l"
joint = "eye_tilt_l"
mesh = "meshes/pupil_l.stl"
color_rgba = [0.05, 0.05, 0.05, 1.0]
collides = false

[[part]]
name = "pupil_r"
joint = "eye_tilt_r"
mesh = "meshes/pupil_r.stl"
color_rgba = [0.05, 0.05, 0.05, 1.0]
collides = false

[[part]]
name = "lid_l"
joint = "upper_lid_l"
mesh = "meshes/lid_l.stl"
color_rgba = [0.62, 0.52, 0.46, 1.0]

[[part]]
name = "lid_r"
joint = "upper_lid_r"
mesh = "meshes/lid_r.stl"
color_rgba = [0.62, 0.52, 0.46, 1.0]

[[part]]
name = "lower_lid_l"             # fixed: the closing upper lid tucks under it (no joint of its own)
joint = "neck_pan"
mesh = "meshes/lower_lid_l.stl"
color_rgba = [0.62, 0.52, 0.46, 1.0]

[[part]]
name = "lower_lid_r"
joint = "neck_pan"
mesh = "meshes/lower_lid_r.stl"
color_rgba = [0.62, 0.52, 0.46, 1.0]

# --- actuators: one servo each (ids and models as you assigned them) -------------------------------------
[[actuator]]
role = "jaw"
servo = {{ id = 1, model = "XL430-W250" }}
kind = "joint"
joints = ["jaw"]

[[actuator]]
role = "brow_l"
servo = {{ id = 2, model = "XL330-M288" }}
kind = "joint"
joints = ["brow_l"]

[[actuator]]
role = "brow_r"
servo = {{ id = 3, model = "XL330-M288" }}
kind = "joint"
joints = ["brow_r"]

[[actuator]]
role = "lid_l"
servo = {{ id = 4, model = "XL330-M288" }}
kind = "joint"
joints = ["upper_lid_l"]

[[actuator]]
role = "lid_r"
servo = {{ id = 5, model = "XL330-M288" }}
kind = "joint"
joints = ["upper_lid_r"]

[[actuator]]
role = "eye_pan"                 # one servo turns both eyes (a linkage): no vergence
servo = {{ id = 6, model = "XL330-M288" }}
kind = "joint"
joints = ["eye_pan_l", "eye_pan_r"]

[[actuator]]
role = "eye_tilt"
servo = {{ id = 7, model = "XL330-M288" }}
kind = "joint"
joints = ["eye_tilt_l", "eye_tilt_r"]

[[actuator]]
role = "neck_pan"
servo = {{ id = 8, model = "XL430-W250" }}
kind = "joint"
joints = ["neck_pan"]
"""

DIRECT_TOML = """\
# Direct AU -> actuator targets (deg from each actuator's neutral at full intensity) for the rigid brows:
# the human AU table moves brows with skin muscles, which this head has not. An AU listed here is driven
# from this table only; every other AU (jaw, lids, eyes, neck) goes through the AU table's joint rows.
# Format: servoface.sim.au.direct. `servoface check` shows what each AU does on this head.

schema_version = 1
face_type = "human"

[AU1]  # Inner Brow Raiser
targets = { "brow_{side}" = 12.0 }

[AU2]  # Outer Brow Raiser
targets = { "brow_{side}" = 16.0 }

[AU4]  # Brow Lowerer
targets = { "brow_{side}" = -10.0 }
"""
