"""One message of face data (a JSON object) -> validated AUs. Shared by JSON-lines files and live streams.

A message is one JSON object with these keys (all optional, at least one of aus / blendshapes / head):

    {"t": 1.23,                                   sender time, s (finite; used for order, not for sampling)
     "aus": {"AU12": 0.5, "AU4L": 0.2},           FACS 0..1 (human) or DFACS -1..1 (dog), the head's names
     "blendshapes": {"mouthSmileLeft": 0.8},      ARKit / MediaPipe scores 0..1 (human only)
     "head": {"yaw_deg": 10, "pitch_deg": -5, "roll_deg": 0} or {"matrix": [[...]]}   (human only)
     "confidence": 0.93}                          tracker confidence 0..1

Unknown keys, unknown names, non-finite or out-of-range values raise :class:`InputError` naming the field
(e.g. ``aus.AU12``); one bad field rejects the whole message. Explicit ``aus`` override AUs mapped from
blendshapes or head pose. ``mirror`` swaps sides of everything (controller/inputs/sides.py).
"""

from __future__ import annotations

import json
import math
from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from servoface.controller.errors import FrameError
from servoface.controller.frame import FrameValidator, check_face_type
from servoface.controller.inputs.blendshapes import BlendshapeMap, load_blendshape_map
from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.head_pose import head_pose_aus, parse_head
from servoface.controller.inputs.head_ranges import HeadRanges
from servoface.controller.inputs.mediapipe_result import is_result, normalise_result
from servoface.controller.inputs.shape_ranges import ShapeRanges
from servoface.controller.inputs.sides import mirror_aus
from servoface.sim.rig import FaceType

KEYS = frozenset({"t", "aus", "blendshapes", "head", "confidence", "token"})
MAX_MESSAGE_BYTES = 65_536
_EYE_AUS = ("AU61", "AU62", "AU63", "AU64", "AU65", "AU66")
_HEAD_AUS = ("AU51", "AU52", "AU53", "AU54", "AU55", "AU56", "AU57", "AU58")


@dataclass(frozen=True)
class Message:
    """A decoded, validated message: sender time (None if not given), AUs (canonical), confidence."""

    t_s: float | None
    aus: dict[str, float]
    confidence: float = 1.0


class MessageDecoder:
    """Decode messages for one face. ``allowed``: the head's AU names (None = the face type's default)."""

    def __init__(
        self,
        face_type: FaceType = "human",
        *,
        allowed: frozenset[str] | None = None,
        mirror: bool = False,
        vergence: bool = False,
        blendshape_map: BlendshapeMap | None = None,
        shape_ranges: ShapeRanges | None = None,
        face_id: int = 0,
        gaze: bool = True,
        head_pose: bool = True,
        head_ranges: HeadRanges | None = None,
    ) -> None:
        """``head_ranges``: the head's own AU ranges; a value beyond one (a full smile on a head that shows
        half of one) is held at the range's end and counted in ``saturated``, not refused (`head_ranges`)."""
        self.face_type = check_face_type(face_type)
        self.face_id = int(face_id)
        self.gaze = bool(gaze)  # False: drop eye AUs 61-66 (the eyes stay the robot's own)
        self.head_pose = bool(head_pose)  # False: drop head AUs 51-58
        self.head_rest_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)  # subtracted (a rest pose)
        self.clamped = 0  # blendshape scores slightly outside 0..1 (within SCORE_SLACK) clamped so far
        self.head_ranges = head_ranges
        self.saturated: Counter[str] = Counter()  # AU -> values held at the head's own range so far
        self.validator = FrameValidator(self.face_type, allowed)
        self.mirror = bool(mirror)
        self.vergence = bool(vergence)
        self._bmap = blendshape_map
        self.shape_ranges = shape_ranges

    @classmethod
    def for_head(cls, head: Any, **options: Any) -> MessageDecoder:
        """A decoder for a loaded head: its face type, its AU table's names and ranges (``options``: the
        other keyword arguments)."""
        validator = FrameValidator.for_head(head)
        return cls(validator.face_type, allowed=validator.allowed, head_ranges=HeadRanges.of(head), **options)

    @property
    def blendshape_map(self) -> BlendshapeMap:
        if self._bmap is None:
            self._bmap = load_blendshape_map(None, self.validator.allowed)
        return self._bmap

    def decode_line(self, line: str | bytes, *, where: str = "message") -> Message:
        """Decode one JSON text (a line or a datagram)."""
        return self.decode(parse_json(line, where=where), where=where)

    def decode(self, obj: Any, *, where: str = "message") -> Message:
        """Decode one parsed JSON object."""
        if not isinstance(obj, Mapping):
            raise InputError(
                f'{where}: expected a JSON object like {{"aus": {{"AU12": 0.5}}}}, got {type(obj).__name__}'
            )
        if is_result(obj):
            obj = normalise_result(obj, face_id=self.face_id, where=where)
        unknown = set(obj) - KEYS
        if unknown:
            shown = sorted(str(k)[:40] for k in unknown)[:5]
            raise InputError(f"{where}: unknown key(s) {shown}; expected {sorted(KEYS)}")
        if not ({"aus", "blendshapes", "head"} & set(obj)):
            raise InputError(f"{where}: no face data; expected at least one of aus, blendshapes, head")
        t_s = None
        if "t" in obj:
            t_s = _finite(obj["t"], f"{where}.t", "a finite time in seconds")
        confidence = 1.0
        if "confidence" in obj:
            confidence = _finite(obj["confidence"], f"{where}.confidence", "a confidence 0..1")
            if not 0.0 <= confidence <= 1.0:
                raise InputError(f"{where}.confidence: {confidence:g} is out of range, expected 0..1")
        aus: dict[str, float] = {}
        if ("blendshapes" in obj or "head" in obj) and self.face_type != "human":
            key = "blendshapes" if "blendshapes" in obj else "head"
            raise InputError(
                f"{where}.{key}: blendshapes and head pose map to human AUs only; "
                f"send DFACS 'aus' for a {self.face_type} head"
            )
        if "blendshapes" in obj:
            clamped: list[str] = []
            aus.update(
                self.blendshape_map.to_aus(
                    obj["blendshapes"],
                    vergence=self.vergence,
                    ranges=self.shape_ranges,
                    where=f"{where}.blendshapes",
                    clamped=clamped,
                )
            )
            self.clamped += len(clamped)
        if "head" in obj:
            ypr = parse_head(obj["head"], field=f"{where}.head")
            yaw_deg, pitch_deg, roll_deg = (a - r for a, r in zip(ypr, self.head_rest_deg, strict=True))
            aus.update(head_pose_aus(yaw_deg, pitch_deg, roll_deg))
        if "aus" in obj:
            try:
                aus.update(self.validator.pose(obj["aus"], where=f"{where}.aus"))
            except FrameError as err:
                raise InputError(str(err)) from err
        if self.face_type == "human" and not (self.gaze and self.head_pose):
            drop = (() if self.gaze else _EYE_AUS) + (() if self.head_pose else _HEAD_AUS)
            aus = {k: v for k, v in aus.items() if k not in drop}
        if self.mirror:
            aus = mirror_aus(aus, self.face_type)
        if self.head_ranges is not None:
            aus, moved = self.head_ranges.saturate(aus)
            self.saturated.update(moved)
        return Message(t_s, aus, confidence)


def parse_json(raw: str | bytes, *, where: str = "message") -> Any:
    """One JSON text -> a Python value, surviving anything: more than ``MAX_MESSAGE_BYTES``, invalid UTF-8,
    nesting deeper than the parser's recursion limit, huge integers (read as floats: 400 digits -> inf,
    then refused as not finite), NaN/Infinity constants -> InputError naming ``where``."""
    if len(raw) > MAX_MESSAGE_BYTES:
        raise InputError(f"{where}: {len(raw)} bytes, more than the {MAX_MESSAGE_BYTES} allowed")
    try:
        text = raw.decode("utf-8") if isinstance(raw, bytes) else raw
        return json.loads(text, parse_constant=_reject_constant, parse_int=_parse_int)
    except UnicodeDecodeError as err:
        raise InputError(f"{where}: not valid JSON: not UTF-8 text (byte {err.start})") from err
    except RecursionError as err:
        raise InputError(f"{where}: JSON nested too deeply") from err
    except ValueError as err:
        raise InputError(f"{where}: not valid JSON: {str(err)[:120]}") from err


def _parse_int(text: str) -> int | float:
    return int(text) if len(text) <= 18 else float(text)


def _finite(value: Any, field: str, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(f"{field}: expected {what}, got {type(value).__name__}")
    try:
        number = float(value)
    except OverflowError:
        number = math.inf
    if not math.isfinite(number):
        raise InputError(f"{field}: expected {what}, got a non-finite number")
    return number


def _reject_constant(name: str) -> float:
    raise ValueError(f"{name} is not a finite number (JSON has no NaN/Infinity)")
