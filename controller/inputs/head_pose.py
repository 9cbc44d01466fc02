"""Head pose from a tracker -> head AUs (human AU51-56).

Convention (the head frame of rig.py, seen from the subject): ``yaw_deg`` + = the subject turns to their
OWN left, ``pitch_deg`` + = head up, ``roll_deg`` + = the top of the head tilts to their own left. A 3x3
rotation or 4x4 transform (MediaPipe's facial transformation matrix: canonical face -> camera; the
canonical face has +x to the subject's left, +y up, +z out of the face, so a frontal face is the identity)
is decomposed as ``R = Ry(yaw) Rx(-pitch) Rz(-roll)``.

The AU full scales are the joint swings the human AU table gives (``gaze_config_for``: AU51 = 45 deg of
neck yaw, AU53 = 25 deg of pitch, AU55 = 20 deg of roll); a bigger angle saturates at 1.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from functools import cache
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.controller.alive.gaze import GazeConfig, gaze_config_for
from servoface.controller.alive.gaze_layer import angles_to_aus
from servoface.controller.inputs.errors import InputError

_HEAD_AUS = ("AU51", "AU52", "AU53", "AU54", "AU55", "AU56")
_MAX_ABS_DEG = 180.0


@cache
def _human_config() -> GazeConfig:
    return gaze_config_for("human")


def matrix_to_ypr_deg(matrix: Any, *, field: str = "head.matrix") -> tuple[float, float, float]:
    """(yaw, pitch, roll) in degrees from a 3x3 rotation or 4x4 transform (nested lists, row-major, or a
    flat list of 9 / 16 numbers). Raises InputError if it is not a proper rotation."""
    try:
        m = np.asarray(matrix, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise InputError(f"{field}: expected a 3x3 or 4x4 matrix of numbers, got {matrix!r}") from err
    if m.shape in ((9,), (16,)):
        m = m.reshape(3, 3) if m.size == 9 else m.reshape(4, 4)
    if m.shape not in ((3, 3), (4, 4)) or not np.all(np.isfinite(m)):
        raise InputError(f"{field}: expected a finite 3x3 or 4x4 matrix, got shape {m.shape}")
    r = m[:3, :3]
    if np.abs(r @ r.T - np.eye(3)).max() > 1e-3 or abs(float(np.linalg.det(r)) - 1.0) > 1e-3:
        raise InputError(f"{field}: the 3x3 part is not a rotation (orthonormal, det +1)")
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, float(r[1, 2])))))
    yaw = math.degrees(math.atan2(float(r[0, 2]), float(r[2, 2])))
    roll = -math.degrees(math.atan2(float(r[1, 0]), float(r[1, 1])))
    return yaw, pitch, roll


def ypr_matrix(yaw_deg: float, pitch_deg: float, roll_deg: float) -> NDArray[np.float64]:
    """The rotation ``Ry(yaw) Rx(-pitch) Rz(-roll)`` (3x3) of this convention (tests, senders)."""
    a, b, c = math.radians(yaw_deg), math.radians(-pitch_deg), math.radians(-roll_deg)
    ry = np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])
    rx = np.array([[1, 0, 0], [0, math.cos(b), -math.sin(b)], [0, math.sin(b), math.cos(b)]])
    rz = np.array([[math.cos(c), -math.sin(c), 0], [math.sin(c), math.cos(c), 0], [0, 0, 1]])
    return ry @ rx @ rz  # type: ignore[no-any-return]


def head_pose_aus(
    yaw_deg: float, pitch_deg: float, roll_deg: float, config: GazeConfig | None = None
) -> dict[str, float]:
    """Head AUs 51-56 (0..1) for a head pose in degrees (see the module convention)."""
    cfg = config or _human_config()
    aus = angles_to_aus("human", cfg, head_yaw_deg=yaw_deg, head_pitch_deg=pitch_deg, head_roll_deg=roll_deg)
    return {k: aus[k] + 0.0 for k in _HEAD_AUS}  # + 0.0: no negative zeros


def eye_angles_aus(yaw_deg: float, pitch_deg: float, config: GazeConfig | None = None) -> dict[str, float]:
    """Eye AUs 61-64 (0..1) for a gaze direction in degrees (yaw + = the subject's own left, pitch + = up);
    full scale = the human AU table's eye swing (AU61 = 30 deg, AU63 = 20 deg)."""
    cfg = config or _human_config()
    aus = angles_to_aus("human", cfg, eye_yaw_deg=yaw_deg, eye_pitch_deg=pitch_deg)
    return {k: aus[k] + 0.0 for k in ("AU61", "AU62", "AU63", "AU64")}


def parse_head(head: Any, *, field: str = "head") -> tuple[float, float, float]:
    """(yaw, pitch, roll) degrees from ``{"yaw_deg", "pitch_deg", "roll_deg"}`` (missing = 0) or
    ``{"matrix": [[...]]}``. Unknown keys, non-finite or |angle| > 180 deg raise InputError."""
    if not isinstance(head, Mapping):
        raise InputError(
            f'{field}: expected {{"yaw_deg", "pitch_deg", "roll_deg"}} or {{"matrix"}}, got {type(head).__name__}'
        )
    unknown = set(head) - {"yaw_deg", "pitch_deg", "roll_deg", "matrix"}
    if unknown:
        raise InputError(f"{field}: unknown key(s) {sorted(unknown)}; expected yaw_deg, pitch_deg, roll_deg or matrix")
    if "matrix" in head:
        if len(head) > 1:
            raise InputError(f"{field}: give either matrix or yaw_deg/pitch_deg/roll_deg, not both")
        return matrix_to_ypr_deg(head["matrix"], field=f"{field}.matrix")
    out = []
    for key in ("yaw_deg", "pitch_deg", "roll_deg"):
        value = head.get(key, 0.0)
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
            or abs(value) > _MAX_ABS_DEG
        ):
            raise InputError(f"{field}.{key}: expected a finite angle in degrees within ±180, got {value!r}")
        out.append(float(value))
    return out[0], out[1], out[2]


def openface_pose_deg(rx_rad: float, ry_rad: float, rz_rad: float) -> tuple[float, float, float]:
    """(yaw, pitch, roll) in this module's convention from OpenFace's ``pose_Rx, pose_Ry, pose_Rz``.

    OpenFace wiki ("Output Format"): radians about the camera's X, Y, Z axes (x right, y down, z away from
    the camera), ``R = Rx * Ry * Rz``, "pitch (Rx), yaw (Ry), roll (Rz)", relative to the camera. So a head
    tipped up reads Rx < 0 and a head turned to the subject's own right reads Ry > 0 (as OpenFace users
    report, e.g. OpenFace issue #966). The camera frame flipped in y and z (``C = diag(1, -1, -1)``) is the
    canonical-face frame of :func:`matrix_to_ypr_deg`: ``yaw = -Ry, pitch = -Rx, roll = +Rz`` for small
    angles, exact by decomposing ``C R C``."""
    cx, sx, cy, sy, cz, sz = (f(a) for a in (rx_rad, ry_rad, rz_rad) for f in (math.cos, math.sin))
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    flip = np.diag([1.0, -1.0, -1.0])
    return matrix_to_ypr_deg(flip @ (rx @ ry @ rz) @ flip, field="pose_R*")
