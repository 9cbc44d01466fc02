"""ARKit / MediaPipe blendshapes (0..1) -> human FACS AUs, through the prior table in ``blendshapes.toml``.

    bmap = load_blendshape_map()                       # the built-in table (facs-human.md §3)
    aus = bmap.to_aus({"mouthSmileLeft": 0.8, "jawOpen": 0.3}, mirror=False)
    # {"AU12L": 0.8, "AU25": 1.0, "AU26": 0.417, ...}

Every score must be a known shape name (ARKit's 52 + MediaPipe's ``_neutral``) with a finite value in
0..1; anything else raises :class:`InputError` naming the field. Names are matched exactly (ARKit spells
``eyeBlinkLeft``; Live Link Face's ``EyeBlinkLeft`` and Furhat's ``EYE_BLINK_LEFT`` are accepted by a
fallback that ignores case and underscores).

Eyes: the eight ``eyeLook{In,Out,Up,Down}{Left,Right}`` shapes become a gaze. Yaw towards the subject's own
left = mean of (left eye: Out - In) and (right eye: In - Out) -> AU61 (eyes turn left) / AU62 (right);
pitch = mean(Up) - mean(Down) -> AU63 / AU64. With ``vergence=True`` the difference between the eyes
becomes AU65 (walleye) / AU66 (cross-eye). Score 1 = the AU's full scale (the robot eye's limit).
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

from servoface.controller.au_names import default_au_names
from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.shape_ranges import ShapeRanges
from servoface.controller.inputs.sides import mirror_aus

TABLE_PATH = Path(__file__).with_name("blendshapes.toml")


@dataclass(frozen=True)
class ShapeTerm:
    """One AU a shape drives: ``weight * clamp((score - lo) / (hi - lo), 0, 1)``."""

    au: str
    side: str = ""
    weight: float = 1.0
    lo: float = 0.0
    hi: float = 1.0

    def value(self, score: float) -> float:
        return self.weight * min(1.0, max(0.0, (score - self.lo) / (self.hi - self.lo)))


@dataclass(frozen=True)
class ShapeEntry:
    name: str
    terms: tuple[ShapeTerm, ...]
    gaze: tuple[str, str] | None  # (eye "L"/"R", direction in/out/up/down) for the eyeLook shapes
    note: str = ""


class BlendshapeMap:
    """The blendshape -> AU prior for one set of allowed human AU names."""

    def __init__(
        self, entries: Mapping[str, ShapeEntry], allowed: frozenset[str] | None = None, source: str = ""
    ) -> None:
        self.entries = dict(entries)
        self.allowed = allowed if allowed is not None else default_au_names("human")
        self.source = source
        self._folded = {_fold(name): name for name in self.entries}

    @property
    def names(self) -> frozenset[str]:
        return frozenset(self.entries)

    def resolve(self, name: Any, *, field: str) -> str:
        """The table's spelling of a shape name, or InputError naming the field."""
        if isinstance(name, str):
            if name in self.entries:
                return name
            folded = self._folded.get(_fold(name))
            if folded is not None:
                return folded
        raise InputError(
            f"{field}: {name!r} is not an ARKit/MediaPipe blendshape name; expected one of "
            f"{', '.join(sorted(self.entries)[:8])}, ... ({len(self.entries)} names)"
        )

    def _au_name(self, term: ShapeTerm) -> str:
        sided = f"{term.au}{term.side}"
        return sided if term.side and sided in self.allowed else term.au

    def to_aus(
        self,
        shapes: Mapping[str, Any],
        *,
        mirror: bool = False,
        vergence: bool = False,
        ranges: ShapeRanges | None = None,
        where: str = "blendshapes",
        clamped: list[str] | None = None,
    ) -> dict[str, float]:
        """Validate ``shapes`` (name -> score 0..1) and map them to AUs (0..1, canonical names); ``ranges``
        rescales the validated scores per user first (shape_ranges.py). A score within ``SCORE_SLACK`` of
        0..1 is clamped (its field appended to ``clamped``), beyond that it is an error."""
        if not isinstance(shapes, Mapping):
            raise InputError(
                f"{where}: expected a mapping of blendshape name -> score 0..1, got {type(shapes).__name__}"
            )
        scores: dict[str, float] = {}
        for raw, value in shapes.items():
            field = f"{where}.{raw}"
            name = self.resolve(raw, field=field)
            if name in scores:
                raise InputError(f"{field}: {name} is given twice")
            scores[name] = check_score(value, field=field, clamped=clamped)
        if ranges is not None:
            scores = ranges.apply(scores)
        out: dict[str, float] = {}
        gaze: dict[tuple[str, str], float] = {}
        for name, score in scores.items():
            entry = self.entries[name]
            if entry.gaze is not None:
                gaze[entry.gaze] = score
            for term in entry.terms:
                au = self._au_name(term)
                out[au] = max(out.get(au, 0.0), term.value(score))
        out.update(gaze_aus(gaze, vergence=vergence))
        out = {au: min(1.0, max(0.0, v)) for au, v in out.items() if au in self.allowed}
        return mirror_aus(out, "human") if mirror else out


def gaze_aus(look: Mapping[tuple[str, str], float], *, vergence: bool = False) -> dict[str, float]:
    """Eye-look scores keyed (eye, direction) -> AU61..64 (and 65/66 with ``vergence``)."""
    if not look:
        return {}

    def s(eye: str, d: str) -> float:
        return look.get((eye, d), 0.0)

    yaw_l = s("L", "out") - s("L", "in")  # + = towards the subject's own left
    yaw_r = s("R", "in") - s("R", "out")
    yaw = (yaw_l + yaw_r) / 2
    pitch = (s("L", "up") + s("R", "up") - s("L", "down") - s("R", "down")) / 2
    out = {"AU61": max(0.0, yaw), "AU62": max(0.0, -yaw), "AU63": max(0.0, pitch), "AU64": max(0.0, -pitch)}
    if vergence:
        spread = (yaw_l - yaw_r) / 2  # + = the eyes turn apart
        out |= {"AU65": max(0.0, spread), "AU66": max(0.0, -spread)}
    return out


SCORE_SLACK = 0.1  # Live Link Face writes eye-look scores up to 1.076; py-feat/MediaPipe -1e-7


def check_score(value: Any, *, field: str, clamped: list[str] | None = None) -> float:
    """A finite blendshape score in 0..1 (within ``SCORE_SLACK`` beyond: clamped, noted in ``clamped``), or
    InputError naming the field."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(f"{field}: expected a blendshape score (a number 0..1), got {_short(value)}")
    try:
        number = float(value)
    except OverflowError:
        number = math.inf
    if not math.isfinite(number) or not -SCORE_SLACK <= number <= 1.0 + SCORE_SLACK:
        raise InputError(f"{field}: blendshape score {_short(value)} is out of range, expected a finite 0..1")
    if not 0.0 <= number <= 1.0:
        if clamped is not None:
            clamped.append(field)
        number = min(1.0, max(0.0, number))
    return number


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else f"{text[:30]}... ({len(text)} characters)"


def load_blendshape_map(path: str | Path | None = None, allowed: frozenset[str] | None = None) -> BlendshapeMap:
    """Load a blendshape table (default: the built-in ``blendshapes.toml``)."""
    if path is None and allowed is None:
        return _builtin()
    return _load(Path(path) if path is not None else TABLE_PATH, allowed)


@cache
def _builtin() -> BlendshapeMap:
    return _load(TABLE_PATH, None)


def _load(path: Path, allowed: frozenset[str] | None) -> BlendshapeMap:
    from servoface.sim.textfile import read_utf8

    try:
        text = read_utf8(path, InputError, what="a blendshape table")
        data = tomllib.loads(text)
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise InputError(f"{path}: cannot read the blendshape table: {err}") from err
    if data.get("schema_version") != 1:
        raise InputError(f"{path}: schema_version: expected 1, got {data.get('schema_version')!r}")
    shapes = data.get("shapes")
    if not isinstance(shapes, dict) or not shapes:
        raise InputError(f"{path}: [shapes]: expected a table of blendshape entries")
    entries: dict[str, ShapeEntry] = {}
    for name, body in shapes.items():
        key = f"{path}: shapes.{name}"
        if not isinstance(body, dict) or not isinstance(body.get("aus"), list):
            raise InputError(f'{key}.aus: expected a list of {{ au = "AUn", ... }} tables')
        terms = tuple(_term(t, f"{key}.aus[{i}]") for i, t in enumerate(body["aus"]))
        gaze = body.get("gaze")
        if gaze is not None and not (
            isinstance(gaze, list)
            and len(gaze) == 2
            and gaze[0] in ("L", "R")
            and gaze[1] in ("in", "out", "up", "down")
        ):
            raise InputError(f'{key}.gaze: expected ["L"|"R", "in"|"out"|"up"|"down"], got {gaze!r}')
        entries[name] = ShapeEntry(name, terms, (gaze[0], gaze[1]) if gaze else None, str(body.get("note", "")))
    return BlendshapeMap(entries, allowed, str(data.get("source", "")))


def _term(raw: Any, key: str) -> ShapeTerm:
    if not isinstance(raw, dict) or not isinstance(raw.get("au"), str):
        raise InputError(f'{key}: expected {{ au = "AUn", side = "L"|"R", weight, from, to }}')
    unknown = set(raw) - {"au", "side", "weight", "from", "to"}
    if unknown:
        raise InputError(f"{key}: unknown key(s) {sorted(unknown)}")
    side = raw.get("side", "")
    if side not in ("", "L", "R"):
        raise InputError(f'{key}.side: expected "L" or "R", got {side!r}')
    nums = {}
    for k, default in (("weight", 1.0), ("from", 0.0), ("to", 1.0)):
        v = raw.get(k, default)
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise InputError(f"{key}.{k}: expected a finite number, got {v!r}")
        nums[k] = float(v)
    if not 0.0 <= nums["from"] < nums["to"] <= 1.0 or not 0.0 < nums["weight"] <= 1.0:
        raise InputError(f"{key}: expected 0 <= from < to <= 1 and 0 < weight <= 1")
    return ShapeTerm(raw["au"].strip().upper(), side, nums["weight"], nums["from"], nums["to"])


def _fold(name: str) -> str:
    """Spelling-insensitive key: Live Link Face's ``EyeBlinkLeft`` and Furhat's ``EYE_BLINK_LEFT`` both match
    ARKit's ``eyeBlinkLeft``."""
    return name.strip().replace("_", "").lower()
