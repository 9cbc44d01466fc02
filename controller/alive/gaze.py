"""Look-at geometry: eye-head coordination for a 3D target, inside swing-twist joint limits.

Frames (rig.py): head frame in mm, +y up, +z forward out of the face, +x the head's OWN left. Angles in
degrees: yaw + = turn to the head's left (towards +x), pitch + = up. A direction for (yaw, pitch) is
``Ry(yaw) Rx(-pitch) z`` = (sin yaw cos pitch, sin pitch, cos yaw cos pitch) — neck pan carries neck tilt,
eye pan carries eye tilt, as in the Face contract.

Limits are elliptic swing limits (Baerlocher & Boulic, muscle-models.md §8) on the swing axis-angle
vector s of the direction (swing from +z; s_x about x, s_y about y):
(s_x / r_pitch)^2 + (s_y / r_yaw)^2 <= 1. A direction outside is pulled radially onto the ellipse.
Twist is not used (pan-tilt eyes and necks have none); roll stays 0.

Coordination (eyes lead, the neck takes the rest): the eyes take the target direction if it lies within
the eyes' *comfortable* range (default 18 deg yaw, 12 deg pitch); beyond it the neck turns by the excess,
within the neck's limits, and the eyes stay at the edge of their range. If the neck saturates, the eyes
use their full joint range. The solution is exact (the eye direction hits the target, including the
parallax of the eyes sitting off the neck pivot), found by fixed-point iteration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.controller.errors import TimelineError

Vec = NDArray[np.float64]


@dataclass(frozen=True)
class GazeConfig:
    """Geometry and limits. ``eye_limit_*`` / ``neck_limit_*`` are also the AU full scale (AU = 1)."""

    eye_center_mm: tuple[float, float, float] = (0.0, 60.0, 75.0)  # cyclopean eye, neutral head
    neck_pivot_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)  # head frame origin = top of the neck
    eye_range_yaw_deg: float = 18.0
    eye_range_pitch_deg: float = 12.0
    eye_limit_yaw_deg: float = 35.0
    eye_limit_pitch_deg: float = 25.0
    neck_limit_yaw_deg: float = 60.0
    neck_limit_pitch_deg: float = 30.0
    neck_limit_roll_deg: float = 25.0
    saccade_s: float = 0.12
    head_move_s: float = 0.6

    def __post_init__(self) -> None:
        for name in (
            "eye_range_yaw_deg", "eye_range_pitch_deg", "eye_limit_yaw_deg", "eye_limit_pitch_deg",
            "neck_limit_yaw_deg", "neck_limit_pitch_deg", "neck_limit_roll_deg", "saccade_s", "head_move_s",
        ):  # fmt: skip
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise TimelineError(f"gaze.{name}: expected a finite positive number, got {value!r}")
            if name.endswith("_deg") and value >= 180:
                raise TimelineError(f"gaze.{name}: a swing limit must be < 180 deg, got {value!r}")
        if self.eye_range_yaw_deg > self.eye_limit_yaw_deg or self.eye_range_pitch_deg > self.eye_limit_pitch_deg:
            raise TimelineError("gaze.eye_range_*: the eyes' comfortable range must lie within their limits")


def direction(yaw_deg: float, pitch_deg: float) -> Vec:
    """Unit direction for (yaw, pitch), (3,) float."""
    y, p = math.radians(yaw_deg), math.radians(pitch_deg)
    return np.array([math.sin(y) * math.cos(p), math.sin(p), math.cos(y) * math.cos(p)], dtype=np.float64)


def angles(d: Vec) -> tuple[float, float]:
    """(yaw_deg, pitch_deg) of a direction (need not be unit)."""
    x, y, z = (float(c) for c in d)
    return math.degrees(math.atan2(x, z)), math.degrees(math.atan2(y, math.hypot(x, z)))


def rotation(yaw_deg: float, pitch_deg: float) -> Vec:
    """Ry(yaw) @ Rx(-pitch), (3, 3) float: pan carrying tilt."""
    y, p = math.radians(yaw_deg), math.radians(-pitch_deg)
    ry = np.array([[math.cos(y), 0, math.sin(y)], [0, 1, 0], [-math.sin(y), 0, math.cos(y)]])
    rx = np.array([[1, 0, 0], [0, math.cos(p), -math.sin(p)], [0, math.sin(p), math.cos(p)]])
    out: Vec = ry @ rx
    return out


def swing_vector(d: Vec) -> tuple[float, float]:
    """Swing axis-angle components (s_x, s_y) in radians taking +z onto ``d``."""
    u = d / np.linalg.norm(d)
    angle = math.acos(max(-1.0, min(1.0, float(u[2]))))
    s = math.hypot(float(u[0]), float(u[1]))
    if s < 1e-12:
        return (0.0, 0.0) if u[2] > 0 else (math.pi, 0.0)
    k = angle / s
    return -float(u[1]) * k, float(u[0]) * k


def from_swing(sx: float, sy: float) -> Vec:
    a = math.hypot(sx, sy)
    if a < 1e-15:
        return np.array([0.0, 0.0, 1.0])
    ux, uy = sx / a, sy / a
    return np.array([math.sin(a) * uy, -math.sin(a) * ux, math.cos(a)])


def swing_ratio(d: Vec, r_yaw_deg: float, r_pitch_deg: float) -> float:
    """Elliptic limit value sqrt((s_x/r_pitch)^2 + (s_y/r_yaw)^2); <= 1 inside the limit."""
    sx, sy = swing_vector(d)
    return math.hypot(sx / math.radians(r_pitch_deg), sy / math.radians(r_yaw_deg))


def clamp_swing(d: Vec, r_yaw_deg: float, r_pitch_deg: float) -> tuple[Vec, bool]:
    """``d`` pulled radially onto the elliptic swing limit if outside; (direction, was_clamped)."""
    q = swing_ratio(d, r_yaw_deg, r_pitch_deg)
    if q <= 1.0:
        return d / np.linalg.norm(d), False
    sx, sy = swing_vector(d)
    return from_swing(sx / q, sy / q), True


def clamp_angles(yaw_deg: float, pitch_deg: float, r_yaw_deg: float, r_pitch_deg: float) -> tuple[float, float]:
    return angles(clamp_swing(direction(yaw_deg, pitch_deg), r_yaw_deg, r_pitch_deg)[0])


@dataclass(frozen=True)
class GazePose:
    """Joint-space gaze: neck and (both) eyes, degrees. ``reachable`` False = the target lies outside the
    combined limits and the eyes point as close as they can."""

    head_yaw_deg: float = 0.0
    head_pitch_deg: float = 0.0
    eye_yaw_deg: float = 0.0
    eye_pitch_deg: float = 0.0
    reachable: bool = True


def eye_position_mm(head_yaw_deg: float, head_pitch_deg: float, cfg: GazeConfig) -> Vec:
    pivot = np.asarray(cfg.neck_pivot_mm, dtype=float)
    offset = np.asarray(cfg.eye_center_mm, dtype=np.float64) - pivot
    out: Vec = pivot + rotation(head_yaw_deg, head_pitch_deg) @ offset
    return out


def eyes_for_head(
    target_mm: Vec, head_yaw_deg: float, head_pitch_deg: float, cfg: GazeConfig
) -> tuple[float, float, bool]:
    """Eye angles (in the head) that look at ``target_mm`` for a given head pose, clamped to the eye
    joint limits: (yaw_deg, pitch_deg, within_limits)."""
    to_target = np.asarray(target_mm, dtype=float) - eye_position_mm(head_yaw_deg, head_pitch_deg, cfg)
    if np.linalg.norm(to_target) < 1e-6:
        raise TimelineError(f"look_at_mm: target {tuple(target_mm)} coincides with the eyes")
    local = rotation(head_yaw_deg, head_pitch_deg).T @ to_target
    clamped, was = clamp_swing(local, cfg.eye_limit_yaw_deg, cfg.eye_limit_pitch_deg)
    yaw, pitch = angles(clamped)
    return yaw, pitch, not was


def solve_look_at(target_mm: Vec | tuple[float, float, float], cfg: GazeConfig = GazeConfig()) -> GazePose:
    """Neck + eye angles that look at ``target_mm`` (head frame at neutral, mm): eyes lead within their
    comfortable range, the neck takes the rest within its limits."""
    target = np.asarray(target_mm, dtype=float)
    if target.shape != (3,) or not np.all(np.isfinite(target)):
        raise TimelineError(f"look_at_mm: expected three finite numbers [x, y, z] in mm, got {target_mm!r}")
    hy = hp = 0.0
    for _ in range(100):
        to_target = target - eye_position_mm(hy, hp, cfg)
        if np.linalg.norm(to_target) < 1e-6:
            raise TimelineError(f"look_at_mm: target {tuple(target)} coincides with the eyes")
        local = rotation(hy, hp).T @ to_target
        q = swing_ratio(local, cfg.eye_range_yaw_deg, cfg.eye_range_pitch_deg)
        if q <= 1.0 and hy == 0.0 and hp == 0.0:
            break  # the eyes alone reach it
        if q < 1e-9:
            break
        sx, sy = swing_vector(local)
        want_y, want_p = angles(local)
        edge_y, edge_p = angles(from_swing(sx / q, sy / q))  # same direction, on the comfortable edge
        ny, np_ = clamp_angles(
            hy + want_y - edge_y, hp + want_p - edge_p, cfg.neck_limit_yaw_deg, cfg.neck_limit_pitch_deg
        )
        if q < 1.0 and ny * hy + np_ * hp <= 0.0:
            hy, hp = 0.0, 0.0  # shrinking the neck past neutral: the eyes alone reach it
            break
        if abs(ny - hy) < 1e-7 and abs(np_ - hp) < 1e-7:
            break  # converged, or the neck is at its limit
        hy, hp = ny, np_
    eye_y, eye_p, ok = eyes_for_head(target, hy, hp, cfg)
    return GazePose(hy, hp, eye_y, eye_p, ok)


#: AU whose joint angle at intensity 1 gives each full scale: (human AU, dog AU, joint name prefix).
_SCALE_AUS: dict[str, tuple[int, int, str]] = {
    "eye_limit_yaw_deg": (61, 12, "eye_pan"),
    "eye_limit_pitch_deg": (63, 13, "eye_tilt"),
    "neck_limit_yaw_deg": (51, 10, "neck_"),
    "neck_limit_pitch_deg": (53, 9, "neck_"),
    "neck_limit_roll_deg": (55, 11, "neck_roll"),
}


def gaze_config_for(face_type: str, head: Any = None, **overrides: Any) -> GazeConfig:
    """A GazeConfig whose AU full scales (= swing limits) come from the face's AU table in ``servoface.sim.au``
    (e.g. human AU61 = eyes 30 deg left, AU51 = neck 45 deg), so AU intensities mean what the muscle model
    will do with them. Falls back to the defaults when the table cannot be read. With a ``head``
    (``servoface.sim.head.Head``: anything with ``joints`` carrying ``name`` and ``pivot_mm``) the eye centre is the
    midpoint of the eye-pan pivots and the neck pivot that of ``neck_pan`` / ``neck_pitch``."""
    values: dict[str, Any] = {}
    try:
        from servoface.sim.au import load_au_table

        table = load_au_table(face_type)
        for key, (human_au, dog_au, joint_prefix) in _SCALE_AUS.items():
            entry = table.entries.get(human_au if face_type == "human" else dog_au)
            if entry is None:
                continue
            angles_deg = [abs(float(a)) for j, a in entry.action.joints if j.startswith(joint_prefix)]
            if angles_deg:
                values[key] = max(angles_deg)
    except Exception:  # noqa: BLE001 - the table is optional here; keep the defaults
        values = {}
    if head is not None:
        pivots = {j.name: tuple(float(c) for c in j.pivot_mm) for j in getattr(head, "joints", ())}
        if "eye_pan_l" in pivots and "eye_pan_r" in pivots:
            left, right = pivots["eye_pan_l"], pivots["eye_pan_r"]
            values["eye_center_mm"] = tuple((a + b) / 2 for a, b in zip(left, right, strict=True))
        neck = pivots.get("neck_pan") or pivots.get("neck_pitch")
        if neck is not None:
            values["neck_pivot_mm"] = neck
    values.update(overrides)
    base = GazeConfig()
    values.setdefault("eye_range_yaw_deg", min(base.eye_range_yaw_deg, values.get("eye_limit_yaw_deg", 1e9)))
    values.setdefault("eye_range_pitch_deg", min(base.eye_range_pitch_deg, values.get("eye_limit_pitch_deg", 1e9)))
    return GazeConfig(**values)
