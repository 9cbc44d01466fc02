"""A small synthetic head for the gate's tests and benchmarks (no profile files, built in milliseconds).

A box skull on a neck yaw joint, a jaw plate hinged under it that collides with the skull when closed
past 0 deg, an ear paddle that hits the skull's side when swung far back, an eyeball with a lid shell, a
flat skin sheet in front (lower rows follow the jaw) with two anchor pullers and a coupling rule. It has
the attribute names of `servoface.sim.head.Head`, so the gate cannot tell it from a loaded profile.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from servoface.sim.rig import AnchorActuator, Joint, JointActuator, RigidPart, ServoRef, Skin


@dataclass(frozen=True)
class DemoRule:
    roles: tuple[str, ...]
    max_sum_share: float
    note: str = ""


@dataclass(frozen=True)
class DemoHead:
    name: str
    face_type: str
    joints: tuple[Joint, ...]
    parts: tuple[RigidPart, ...]
    skin: Skin
    actuators: tuple[Any, ...]
    coupling_rules: tuple[Any, ...] = ()
    muscles: tuple[Any, ...] = ()
    landmarks_mm: dict[str, Any] = field(default_factory=dict)


def _box(extents: tuple[float, float, float], centre: tuple[float, float, float]) -> Any:
    import trimesh

    m = trimesh.creation.box(extents=extents)
    m.apply_translation(centre)
    return m


def _shell(radius_mm: float, centre: tuple[float, float, float]) -> Any:
    """Upper half of a thin spherical cap (the lid), open mesh."""
    import trimesh

    s = trimesh.creation.icosphere(subdivisions=2, radius=radius_mm)
    keep = s.triangles_center[:, 1] > radius_mm * 0.3
    cap = trimesh.Trimesh(s.vertices, s.faces[keep], process=True)
    cap.apply_translation(centre)
    return cap


def _skin_sheet(nx: int = 14, ny: int = 12) -> Skin:
    xs = np.linspace(-40.0, 40.0, nx)
    ys = np.linspace(-50.0, 30.0, ny)
    xx, yy = np.meshgrid(xs, ys)
    v = np.c_[xx.ravel(), yy.ravel(), np.full(xx.size, 62.0)]
    faces = []
    for j in range(ny - 1):
        for i in range(nx - 1):
            a = j * nx + i
            faces += [[a, a + 1, a + nx + 1], [a, a + nx + 1, a + nx]]
    w_jaw = np.clip((-10.0 - v[:, 1]) / 25.0, 0.0, 1.0)  # below y = -10 blends onto the jaw
    weights = np.c_[np.zeros(len(v)), 1.0 - w_jaw, w_jaw]  # base, neck_pan, jaw
    return Skin(v, np.array(faces, dtype=np.int64), ("neck_pan", "jaw"), weights)


def demo_head() -> DemoHead:
    """The synthetic head (see module docstring)."""
    joints = (
        Joint("neck_pan", None, (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), -45.0, 45.0),
        Joint("jaw", "neck_pan", (0.0, -10.0, -20.0), (1.0, 0.0, 0.0), -8.0, 25.0),
        Joint("ear_pan_l", "neck_pan", (42.0, 30.0, 0.0), (0.0, 1.0, 0.0), -40.0, 60.0),
        Joint("eye_pan_l", "neck_pan", (20.0, 15.0, 50.0), (0.0, 1.0, 0.0), -30.0, 30.0),
        Joint("upper_lid_l", "neck_pan", (20.0, 15.0, 50.0), (1.0, 0.0, 0.0), -15.0, 55.0),
    )
    parts = (
        RigidPart("skull", "neck_pan", _box((80.0, 60.0, 100.0), (0.0, 25.0, 0.0))),
        # jaw plate: under the skull, 1 mm gap at 0 deg; opening (+) rotates its front down (+x axis).
        RigidPart("jaw", "jaw", _box((60.0, 10.0, 80.0), (0.0, -11.0, 20.0))),
        RigidPart("ear_l", "ear_pan_l", _box((4.0, 30.0, 40.0), (44.0, 45.0, 22.0))),
        RigidPart("eyeball_l", "eye_pan_l", _eyeball()),
        RigidPart("upper_lid_l", "upper_lid_l", _shell(14.5, (20.0, 15.0, 50.0))),
    )
    actuators: tuple[Any, ...] = (
        JointActuator("neck_pan", ServoRef(1, "XL330-M288"), ("neck_pan",), -45.0, 45.0),
        JointActuator("jaw", ServoRef(2, "XL330-M288"), ("jaw",), -8.0, 25.0),
        JointActuator("ear_pan_l", ServoRef(3, "XL330-M288"), ("ear_pan_l",), -40.0, 60.0),
        JointActuator("eye_pan", ServoRef(4, "XL330-M288"), ("eye_pan_l",), -30.0, 30.0),
        JointActuator("upper_lid_l", ServoRef(5, "XL330-M288"), ("upper_lid_l",), -15.0, 55.0),
        AnchorActuator(
            "lip_corner_l", ServoRef(6, "XL330-M288"), 3 * 14 + 9, (0.6, 0.8, 0.0), -6.0, 12.0, radius_mm=18.0
        ),
        AnchorActuator(
            "lip_depressor_l",
            ServoRef(7, "XL330-M288"),
            3 * 14 + 9,
            (0.0, -1.0, 0.0),
            -6.0,
            12.0,
            radius_mm=18.0,
        ),
    )
    rules = (DemoRule(("lip_corner_l", "lip_depressor_l"), 1.0, "smile and frown pullers of one side"),)
    return DemoHead("demo", "human", joints, parts, _skin_sheet(), actuators, rules)


def _eyeball() -> Any:
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=2, radius=11.0)
    nose = trimesh.creation.box(extents=(3.0, 3.0, 8.0))
    nose.apply_translation((0.0, 0.0, 12.0))  # a pupil bump, so pan matters to the lid
    m = trimesh.util.concatenate([m, nose])
    m.apply_translation((20.0, 15.0, 50.0))
    return m


def demo_calibration(head: DemoHead | None = None) -> Any:
    """A linear calibration of the demo head: 4096/360 tick per deg about 2048, 20 tick per mm."""
    from servoface.calibration.curves import LinearCurve
    from servoface.calibration.head import HeadCalibration
    from servoface.calibration.servo import ServoCalibration

    head = head or demo_head()
    servos = []
    for a in head.actuators:
        if a.kind == "joint":
            unit: Literal["deg", "mm"] = "deg"
            scale, lo, hi = 4096.0 / 360.0, a.lower_deg, a.upper_deg
        else:
            unit = "mm"
            scale, lo, hi = 20.0, a.lower_mm, a.upper_mm
        curve = LinearCurve(2048.0, scale, 1 if a.servo.id % 2 else -1)
        t_lo, t_hi = sorted(float(x) for x in curve.forward(np.array([lo, hi])))
        servos.append(
            ServoCalibration(
                a.role, a.servo.id, a.servo.model, curve, int(np.ceil(t_lo)), int(np.floor(t_hi)), 2048, unit
            )
        )
    return HeadCalibration(head.name, servos)
