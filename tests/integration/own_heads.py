"""Three heads written the way a builder writes theirs (profile TOML by hand, own meshes, own AU table),
for the bring-up tests: a mechanical 8-servo head without skin, a skin head with only a few anchors (it
cannot smile), and a dog head whose own meshes are in metres (``scale = 1000``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

# ------------------------------------------------------------------------------------------------------
# 1. mechanical: jaw, two brows on levers, two lids, eye pan + tilt (one servo each for both eyes), neck pan

MECH_TOML = """\
schema_version = 1
name = "tinbot"
face_type = "human"
calibration = "calibration.json"
au_direct = "direct.toml"

[[joint]]
name = "neck_pan"
pivot_mm = [0.0, 0.0, 0.0]
axis = [0.0, 1.0, 0.0]
limits_deg = [-50.0, 50.0]

[[joint]]
name = "jaw"
parent = "neck_pan"
pivot_mm = [0.0, 80.0, 0.0]
axis = [1.0, 0.0, 0.0]
limits_deg = [0.0, 22.0]

[[joint]]
name = "brow_l"
parent = "neck_pan"
pivot_mm = [34.0, 150.0, 30.0]
axis = [-1.0, 0.0, 0.0]
limits_deg = [-10.0, 18.0]

[[joint]]
name = "brow_r"
parent = "neck_pan"
pivot_mm = [-34.0, 150.0, 30.0]
axis = [-1.0, 0.0, 0.0]
limits_deg = [-10.0, 18.0]

[[joint]]
name = "upper_lid_l"
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
name = "eye_pan_l"
parent = "neck_pan"
pivot_mm = [32.0, 122.0, 58.0]
axis = [0.0, 1.0, 0.0]
limits_deg = [-30.0, 30.0]

[[joint]]
name = "eye_pan_r"
parent = "neck_pan"
pivot_mm = [-32.0, 122.0, 58.0]
axis = [0.0, 1.0, 0.0]
limits_deg = [-30.0, 30.0]

[[joint]]
name = "eye_tilt_l"
parent = "eye_pan_l"
pivot_mm = [32.0, 122.0, 58.0]
axis = [-1.0, 0.0, 0.0]
limits_deg = [-20.0, 20.0]

[[joint]]
name = "eye_tilt_r"
parent = "eye_pan_r"
pivot_mm = [-32.0, 122.0, 58.0]
axis = [-1.0, 0.0, 0.0]
limits_deg = [-20.0, 20.0]

[[part]]
name = "neck_base"
mesh = "stl/neck_base.stl"

[[part]]
name = "neck"
joint = "neck_pan"
mesh = "stl/neck.stl"

[[part]]
name = "skull"
joint = "neck_pan"
mesh = "stl/skull.stl"
color_rgba = [0.8, 0.75, 0.7, 1.0]

[[part]]
name = "jaw"
joint = "jaw"
mesh = "stl/jaw.stl"

[[part]]
name = "brow_l"
joint = "brow_l"
mesh = "stl/brow_l.stl"
color_rgba = [0.2, 0.15, 0.1, 1.0]

[[part]]
name = "brow_r"
joint = "brow_r"
mesh = "stl/brow_r.stl"
color_rgba = [0.2, 0.15, 0.1, 1.0]

[[part]]
name = "eye_l"
joint = "eye_tilt_l"
mesh = "stl/eye_l.stl"
color_rgba = [0.97, 0.97, 0.95, 1.0]

[[part]]
name = "eye_r"
joint = "eye_tilt_r"
mesh = "stl/eye_r.stl"
color_rgba = [0.97, 0.97, 0.95, 1.0]

[[part]]
name = "lid_l"
joint = "upper_lid_l"
mesh = "stl/lid_l.stl"

[[part]]
name = "lid_r"
joint = "upper_lid_r"
mesh = "stl/lid_r.stl"

[[actuator]]
role = "jaw"
servo = { id = 11, model = "XL430-W250" }
kind = "joint"
joints = ["jaw"]

[[actuator]]
role = "brow_l"
servo = { id = 12, model = "XL330-M288" }
kind = "joint"
joints = ["brow_l"]

[[actuator]]
role = "brow_r"
servo = { id = 13, model = "XL330-M288" }
kind = "joint"
joints = ["brow_r"]

[[actuator]]
role = "lid_l"
servo = { id = 14, model = "XL330-M288" }
kind = "joint"
joints = ["upper_lid_l"]

[[actuator]]
role = "lid_r"
servo = { id = 15, model = "XL330-M288" }
kind = "joint"
joints = ["upper_lid_r"]

[[actuator]]
role = "eye_pan"
servo = { id = 16, model = "XL330-M288" }
kind = "joint"
joints = ["eye_pan_l", "eye_pan_r"]

[[actuator]]
role = "eye_tilt"
servo = { id = 17, model = "XL330-M288" }
kind = "joint"
joints = ["eye_tilt_l", "eye_tilt_r"]

[[actuator]]
role = "neck_pan"
servo = { id = 18, model = "XL430-W250" }
kind = "joint"
joints = ["neck_pan"]
"""

MECH_DIRECT = """\
schema_version = 1
face_type = "human"

[AU1]
targets = { "brow_{side}" = 10.0 }

[AU2]
targets = { "brow_{side}" = 14.0 }

[AU4]
targets = { "brow_{side}" = -9.0 }
"""

# what the mechanical head can show with the built-in human AU table: the joint rows it has (jaw, upper
# lids, eyes, neck pan) plus the brows of its direct table; vergence (AU65/66) needs two eye-pan servos
MECH_CAN_SHOW = {
    "AU1", "AU2", "AU4", "AU5", "AU7", "AU19", "AU22", "AU25", "AU26", "AU27", "AU41", "AU42", "AU43",
    "AU44", "AU45", "AU46", "AU51", "AU52", "AU61", "AU62", "AU63", "AU64",
}  # fmt: skip


def write_mechanical(folder: Path) -> Path:
    from servoface.controller.new_head.mechanical import meshes

    (folder / "stl").mkdir(parents=True, exist_ok=True)
    for name, mesh in meshes().items():
        if name.startswith("pupil"):
            continue
        mesh.export(str(folder / "stl" / f"{name}.stl"))  # type: ignore[attr-defined]
    (folder / "head.toml").write_text(MECH_TOML)
    (folder / "direct.toml").write_text(MECH_DIRECT)
    return folder


# ------------------------------------------------------------------------------------------------------
# 2. skin with a few anchors: brows pulled by two cables, a jaw and a neck; its own small AU table.
#    The zygomatic muscle is modelled (the skin could smile) but no servo pulls the mouth corners.

SKIN_TOML = """\
schema_version = 1
name = "browbot"
face_type = "human"
calibration = "calibration.json"
au_table = "aus.toml"

[landmarks]
mouth_corner_l = [24.0, 72.0, 80.5]
mouth_corner_r = [-24.0, 72.0, 80.5]

[skin]
mesh = "builtin:human_skin"
joint = "neck_pan"
smooth_iterations = 20

[[skin.bind]]
joint = "jaw"
falloff_mm = 0.5
halfspaces = [
    { point_mm = [0.0, 72.0, 0.0], normal = [0.0, -1.0, 0.0] },
    { point_mm = [0.0, 0.0, 35.0], normal = [0.0, 0.0, 1.0], falloff_mm = 50.0 },
    { point_mm = [0.0, 22.0, 0.0], normal = [0.0, 1.0, 0.0], falloff_mm = 35.0 },
]

[[joint]]
name = "neck_pan"
pivot_mm = [0.0, 0.0, 0.0]
axis = [0.0, 1.0, 0.0]
limits_deg = [-45.0, 45.0]

[[joint]]
name = "jaw"
parent = "neck_pan"
pivot_mm = [0.0, 100.0, 5.0]
axis = [1.0, 0.0, 0.0]
limits_deg = [0.0, 20.0]

[[part]]
name = "skull"
joint = "neck_pan"
mesh = "builtin:human_skull"

[[part]]
name = "jaw"
joint = "jaw"
mesh = "builtin:human_jaw"

[[part]]
name = "eyeball_l"
joint = "neck_pan"
mesh = "builtin:human_eyeball_l"
color_rgba = [0.97, 0.97, 0.95, 1.0]

[[part]]
name = "eyeball_r"
joint = "neck_pan"
mesh = "builtin:human_eyeball_r"
color_rgba = [0.97, 0.97, 0.95, 1.0]

[[muscle]]
name = "frontalis_medial_l"
mirror = "frontalis_medial_r"
type = "linear"
attachment_mm = [14.0, 190.0, 67.0]
insertion_mm = [14.0, 148.0, 87.0]
zone_deg = 30.0
rs_mm = 46.0
rf_mm = 62.0
max_contraction = 0.185

[[muscle]]
name = "zygomatic_major_l"
mirror = "zygomatic_major_r"
type = "linear"
attachment_mm = [60.0, 110.0, 62.0]
insertion_mm = [25.0, 72.0, 80.0]
zone_deg = 30.0
rs_mm = 55.0
rf_mm = 70.0
max_contraction = 0.215

[anchors]
brow_l = { near_mm = [14.0, 148.0, 87.0], mirror = "brow_r" }

[[actuator]]
role = "brow_l"
servo = { id = 1, model = "XL330-M288" }
kind = "anchor"
anchor = "brow_l"
line = [0.0, 1.0, 0.0]
range_mm = [-3.0, 8.0]
radius_mm = 14.0

[[actuator]]
role = "brow_r"
servo = { id = 2, model = "XL330-M288" }
kind = "anchor"
anchor = "brow_r"
line = [0.0, 1.0, 0.0]
range_mm = [-3.0, 8.0]
radius_mm = 14.0

[[actuator]]
role = "jaw"
servo = { id = 3, model = "XL430-W250" }
kind = "joint"
joints = ["jaw"]

[[actuator]]
role = "neck_pan"
servo = { id = 4, model = "XL430-W250" }
kind = "joint"
joints = ["neck_pan"]
"""

SKIN_AUS = """\
schema_version = 1
face_type = "human"
intensity = [0.0, 1.0]
contraction = [0.0, 1.0]

[AU1]
source = "my head: inner brow raiser on the two brow cables"
sided = true
muscles = { "frontalis_medial_{side}" = 1.0 }

[AU12]
source = "my head: the zygomatic is modelled, no servo pulls the mouth corner yet"
sided = true
muscles = { "zygomatic_major_{side}" = 1.0 }

[AU26]
source = "my head: jaw drop"
joints = { "jaw" = 14.0 }

[AU51]
source = "my head: turn left"
joints = { "neck_pan" = 40.0 }

[AU52]
source = "my head: turn right"
joints = { "neck_pan" = -40.0 }
"""

SKIN_CAN_SHOW = {"AU1", "AU26", "AU51", "AU52"}


def write_skin(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "head.toml").write_text(SKIN_TOML)
    (folder / "aus.toml").write_text(SKIN_AUS)
    return folder


# ------------------------------------------------------------------------------------------------------
# 3. a dog head from CAD, exported in metres: scale = 1000 on every part

DOG_TOML = """\
schema_version = 1
name = "cadpup"
face_type = "dog"
calibration = "calibration.json"

[[joint]]
name = "neck_yaw"
pivot_mm = [0.0, 0.0, 0.0]
axis = [0.0, 1.0, 0.0]
limits_deg = [-40.0, 40.0]

[[joint]]
name = "jaw"
parent = "neck_yaw"
pivot_mm = [0.0, 68.0, 40.0]
axis = [1.0, 0.0, 0.0]
limits_deg = [0.0, 28.0]

[[joint]]
name = "ear_pan_l"
parent = "neck_yaw"
pivot_mm = [40.0, 170.0, 0.0]
axis = [0.0, 1.0, 0.0]
limits_deg = [-40.0, 30.0]

[[joint]]
name = "ear_pan_r"
parent = "neck_yaw"
pivot_mm = [-40.0, 170.0, 0.0]
axis = [0.0, -1.0, 0.0]
limits_deg = [-40.0, 30.0]

[[part]]
name = "skull"
joint = "neck_yaw"
mesh = "cad/skull.stl"
scale = 1000.0
color_rgba = [0.55, 0.4, 0.25, 1.0]

[[part]]
name = "jaw"
joint = "jaw"
mesh = "cad/jaw.stl"
scale = 1000.0
color_rgba = [0.5, 0.36, 0.22, 1.0]

[[part]]
name = "ear_l"
joint = "ear_pan_l"
mesh = "cad/ear_l.stl"
scale = 1000.0
color_rgba = [0.35, 0.25, 0.15, 1.0]

[[part]]
name = "ear_r"
joint = "ear_pan_r"
mesh = "cad/ear_r.stl"
scale = 1000.0
color_rgba = [0.35, 0.25, 0.15, 1.0]

[[actuator]]
role = "jaw"
servo = { id = 1, model = "XL430-W250" }
kind = "joint"
joints = ["jaw"]

[[actuator]]
role = "ear_l"
servo = { id = 2, model = "XL330-M288" }
kind = "joint"
joints = ["ear_pan_l"]

[[actuator]]
role = "ear_r"
servo = { id = 3, model = "XL330-M288" }
kind = "joint"
joints = ["ear_pan_r"]

[[actuator]]
role = "neck_yaw"
servo = { id = 4, model = "XM430-W350" }
kind = "joint"
joints = ["neck_yaw"]
"""

# the built-in DFACS table on this head: ears (AU5 both ways), jaw open (AU7; its counter closes past
# the stop), the jaw part of AU8 and AU16, head turn (AU10 both ways)
DOG_CAN_SHOW = {"AU5", "AU5-", "AU7", "AU8", "AU8-", "AU10", "AU10-", "AU16"}


def _box_m(lo: tuple[float, float, float], hi: tuple[float, float, float]) -> trimesh.Trimesh:
    lo_a, hi_a = np.array(lo) / 1000.0, np.array(hi) / 1000.0
    box = trimesh.creation.box(extents=hi_a - lo_a)
    box.apply_translation((lo_a + hi_a) / 2)
    return box


def write_dog_in_metres(folder: Path, *, scale: bool = True) -> Path:
    (folder / "cad").mkdir(parents=True, exist_ok=True)
    parts = {
        "skull": trimesh.util.concatenate(
            [_box_m((-50, 60, -60), (50, 160, 60)), _box_m((-25, 72, 60), (25, 110, 140))]
        ),
        "jaw": _box_m((-22, 50, 62), (22, 66, 135)),
        "ear_l": _box_m((37, 164, -12), (43, 205, 12)),
        "ear_r": _box_m((-43, 164, -12), (-37, 205, 12)),
    }
    for name, mesh in parts.items():
        mesh.export(str(folder / "cad" / f"{name}.stl"))
    text = DOG_TOML if scale else DOG_TOML.replace("scale = 1000.0\n", "")
    (folder / "head.toml").write_text(text)
    return folder
