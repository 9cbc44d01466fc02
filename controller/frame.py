"""AU frames: a time and a validated mapping of action units to intensities.

``AUFrame(t_s, aus)`` is what every input (preset, timeline, file, live stream) hands to the pipeline.
Construction always checks what is true for every face: ``t_s`` finite, names follow the AU grammar
(:mod:`servoface.controller.au_names`), values are real, finite and within -1..1. Give ``face_type`` (and
optionally the head's own ``allowed`` name set from its AU table) for the full check: human FACS 0..1,
DFACS signed -1..1 (negative = the counter AU), names known to that face. Failures raise
:class:`servoface.controller.errors.FrameError` naming the AU and what was expected; nothing is half-built.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from servoface.controller.au_names import (
    au_ranges,
    canonical_au,
    default_au_names,
    head_au_names,
    intensity_range,
)
from servoface.controller.errors import FrameError
from servoface.sim.rig import FaceType

FACE_TYPES: tuple[FaceType, ...] = ("human", "dog")
MAX_AUS = 256  # far more than any face has names for


def _shown(value: Any) -> str:
    try:
        text = repr(value)  # escapes control characters and lone surrogates
    except (RecursionError, ValueError):
        text = f"<{type(value).__name__} nested too deeply>"
    return text if len(text) <= 40 else text[:37] + "..."


def check_face_type(face_type: Any, *, field: str = "face type") -> FaceType:
    """Return ``face_type`` if it is "human" or "dog", else raise FrameError."""
    if face_type not in FACE_TYPES:
        raise FrameError(f"{field}: expected 'human' or 'dog', got {_shown(face_type)}")
    return face_type  # type: ignore[no-any-return]


def check_intensity(value: Any, *, field: str, lo: float = -1.0, hi: float = 1.0, what: str = "AU intensity") -> float:
    """Return ``value`` as a float if it is a finite real number in [lo, hi], else raise FrameError."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise FrameError(f"{field}: expected a number ({what} {lo:g}..{hi:g}), got {_shown(value)}")
    try:
        number = float(value)
    except OverflowError:  # a huge integer
        number = math.inf if value > 0 else -math.inf
    if not math.isfinite(number):
        raise FrameError(f"{field}: expected a finite {what} in {lo:g}..{hi:g}, got {_shown(value)}")
    if number < lo or number > hi:
        raise FrameError(f"{field}: {what} {number:g} is out of range, expected {lo:g}..{hi:g}")
    return number


def validate_aus(
    aus: Mapping[str, Any],
    face_type: FaceType | None = None,
    allowed: frozenset[str] | None = None,
    *,
    where: str = "",
) -> dict[str, float]:
    """Validate an AU mapping and return it with canonical names and float values.

    ``face_type`` None checks only the universal rules (grammar, finite, -1..1); with a face type the
    names must be in ``allowed`` (default: :func:`default_au_names`) and values in the face's range.
    ``where`` prefixes every message (e.g. ``"poses.smile"``) so errors name the whole path.
    """
    if not isinstance(aus, Mapping):
        raise FrameError(f"{where or 'aus'}: expected a mapping of AU name -> intensity, got {type(aus).__name__}")
    lo, hi = (-1.0, 1.0) if face_type is None else intensity_range(check_face_type(face_type))
    names = None
    ranges: dict[str, tuple[float, float]] = {}
    if face_type is not None:
        names = allowed if allowed is not None else default_au_names(face_type)
        ranges = au_ranges(face_type)
    out: dict[str, float] = {}
    if len(aus) > MAX_AUS:
        raise FrameError(f"{where or 'aus'}: {len(aus)} entries; an AU frame has at most {MAX_AUS}")
    for raw, value in aus.items():
        if names is not None and type(value) is float and raw in names and raw not in out:
            a, b = ranges.get(raw, (lo, hi))
            if a <= value <= b:  # a canonical name and a finite float in range: what the checks below return
                out[raw] = value
                continue
        shown = raw if isinstance(raw, str) and raw.isprintable() and len(raw) <= 40 else _shown(raw)
        field = f"{where}.{shown}" if where else str(shown)
        name = raw if names is not None and raw in names else canonical_au(raw, field=field)
        if names is not None and name not in names:
            raise FrameError(f"{field}: {name} is not an AU of the {face_type} face; expected one of {_sample(names)}")
        if name in out:
            raise FrameError(f"{field}: {name} is given twice (names are case-insensitive)")
        kind = "DFACS intensity" if face_type == "dog" else "FACS intensity" if face_type else "AU intensity"
        a, b = ranges.get(name, (lo, hi))
        out[name] = check_intensity(value, field=field, lo=a, hi=b, what=kind)
    return out


def _sample(names: frozenset[str]) -> str:
    ordered = sorted(names, key=lambda n: (int(n[2:].rstrip("LR")), n))
    shown = ", ".join(ordered[:12])
    return f"{shown}, ... ({len(ordered)} names)" if len(ordered) > 12 else shown


@dataclass(frozen=True, init=False, eq=False)
class AUFrame:
    """One control frame: time ``t_s`` (seconds on the timeline clock) and AU intensities.

    ``aus`` is stored read-only with canonical names; AUs not present are 0 (neutral).
    """

    t_s: float
    aus: Mapping[str, float]
    face_type: FaceType | None

    def __init__(
        self,
        t_s: float,
        aus: Mapping[str, float],
        face_type: FaceType | None = None,
        *,
        allowed: frozenset[str] | None = None,
    ) -> None:
        if isinstance(t_s, bool) or not isinstance(t_s, int | float) or not math.isfinite(t_s):
            raise FrameError(f"t_s: expected a finite time in seconds, got {_shown(t_s)}")
        if face_type is not None:
            check_face_type(face_type)
        elif allowed is not None:
            raise FrameError("allowed: an allowed AU-name set needs face_type ('human' or 'dog') too")
        clean = validate_aus(aus, face_type, allowed)
        object.__setattr__(self, "t_s", float(t_s))
        object.__setattr__(self, "aus", MappingProxyType(clean))
        object.__setattr__(self, "face_type", face_type)

    def get(self, au: str, default: float = 0.0) -> float:
        """Intensity of ``au`` (any accepted spelling), ``default`` when absent."""
        return self.aus.get(canonical_au(au), default)

    def __getitem__(self, au: str) -> float:
        return self.get(au)

    def __iter__(self) -> Iterator[str]:
        return iter(self.aus)

    def __len__(self) -> int:
        return len(self.aus)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, AUFrame):
            return NotImplemented
        return (self.t_s, dict(self.aus), self.face_type) == (other.t_s, dict(other.aus), other.face_type)

    __hash__ = None  # type: ignore[assignment]

    def nonzero(self, eps: float = 1e-9) -> dict[str, float]:
        """The AUs whose magnitude exceeds ``eps``."""
        return {k: v for k, v in self.aus.items() if abs(v) > eps}

    def with_time(self, t_s: float) -> AUFrame:
        """The same intensities at another time."""
        return AUFrame(t_s, self.aus, self.face_type)

    def __repr__(self) -> str:
        shown = ", ".join(f"{k}={v:.3g}" for k, v in sorted(self.nonzero().items()))
        return f"AUFrame(t_s={self.t_s:.4f}, {{{shown}}}, face_type={self.face_type!r})"


@dataclass(frozen=True)
class FrameValidator:
    """A reusable validator bound to one face: ``validator(t_s, aus) -> AUFrame``.

    ``allowed`` is the head's AU-name set (from MUSCLES' AU table); None = the built-in default set.
    """

    face_type: FaceType
    allowed: frozenset[str] | None = None

    def __post_init__(self) -> None:
        check_face_type(self.face_type)

    @classmethod
    def for_head(cls, head: Any) -> FrameValidator:
        """A validator for a loaded head (``servoface.sim.head.Head``): its face type and its AU table's names."""
        return cls(check_face_type(getattr(head, "face_type", None)), head_au_names(head))

    @property
    def names(self) -> frozenset[str]:
        return self.allowed if self.allowed is not None else default_au_names(self.face_type)

    @property
    def range(self) -> tuple[float, float]:
        return intensity_range(self.face_type)

    def __call__(self, t_s: float, aus: Mapping[str, float]) -> AUFrame:
        return AUFrame(t_s, aus, self.face_type, allowed=self.allowed)

    def pose(self, aus: Mapping[str, Any], *, where: str = "") -> dict[str, float]:
        """Validate a pose (no time) for this face; returns canonical names."""
        return validate_aus(aus, self.face_type, self.allowed, where=where)
