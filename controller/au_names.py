"""Valid AU names per face type, and the grammar every AU name follows.

Grammar: ``AU<number>`` with an optional side suffix ``L`` / ``R`` (the head's OWN left / right, as FACS
codes the subject's own side). Names are case-insensitive on input (``au12l`` -> ``AU12L``, PyLips writes
``AU4l``) and canonical upper-case everywhere inside servoface. Leading zeros are dropped (``AU01`` ->
``AU1``, OpenFace style).

The authoritative per-head sets come from MUSCLES' AU tables (``sim/au/``); until a head's table is wired
in, :func:`default_au_names` gives the sets below (FACS AUs a face robot uses, facs-human.md §1; DFACS
AUs 1-19, dfacs-dog.md §2). Every validator takes the allowed set as a parameter.
"""

from __future__ import annotations

import re
import unicodedata
from functools import cache
from typing import Any

from servoface.controller.errors import FrameError
from servoface.sim.rig import FaceType

_NAME_RE = re.compile(r"AU0*([0-9]{1,3})([LR]?)", re.ASCII)  # fullmatch: ASCII digits, nothing around

#: Human FACS AUs a robot face uses (facs-human.md §1): facial 1-46, head 51-58, eyes 61-66.
HUMAN_FACIAL_AUS: tuple[int, ...] = (
    1, 2, 4, 5, 6, 7, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 22, 23, 24, 25, 26, 27, 28,
    34, 38, 39, 41, 42, 43, 44, 45, 46,
)  # fmt: skip
HUMAN_HEAD_AUS: tuple[int, ...] = (51, 52, 53, 54, 55, 56, 57, 58)
HUMAN_EYE_AUS: tuple[int, ...] = (61, 62, 63, 64, 65, 66)
#: Facial AUs that may be given per side (AU12L / AU12R). Midline actions (17, 18, 19, 22-28, 34) may not.
HUMAN_SIDED_AUS: tuple[int, ...] = (
    1,
    2,
    4,
    5,
    6,
    7,
    9,
    10,
    11,
    12,
    13,
    14,
    15,
    16,
    20,
    38,
    39,
    41,
    42,
    43,
    44,
    45,
    46,
)

#: DFACS face AUs 1-19 (dfacs-dog.md §2); sided where the dog head has a servo per side.
DOG_AUS: tuple[int, ...] = tuple(range(1, 20))
DOG_SIDED_AUS: tuple[int, ...] = (1, 2, 4, 5, 6, 15)


def canonical_au(name: str, *, field: str = "AU name") -> str:
    """Return the canonical spelling of an AU name (``au12l`` -> ``AU12L``), or raise FrameError.

    The DFACS counter AU is a NEGATIVE VALUE on the plain name (``AU7 = -0.5`` closes the mandible);
    spellings such as ``-AU7`` or ``AU7c`` are not AU names and are rejected with that hint.
    """
    if not isinstance(name, str):
        raise FrameError(f"{field}: expected an AU name string like 'AU12' or 'AU12L', got {_shown(name)}")
    text = unicodedata.normalize("NFC", name)  # then matched exactly: no stray whitespace, ASCII digits only
    match = _NAME_RE.fullmatch(text.upper()) if text.isascii() else None
    if match is None:
        hint = ""
        if text.startswith("-") or text.upper().endswith("C"):
            hint = " (a DFACS counter AU is a negative value on the plain name, e.g. AU7 = -0.5)"
        raise FrameError(
            f"{field}: {_shown(name)} is not an AU name; expected 'AU<number>' with optional side L/R, "
            f"e.g. 'AU12', 'AU12L'{hint}"
        )
    return f"AU{int(match.group(1))}{match.group(2)}"


def _shown(value: object) -> str:
    try:
        text = repr(value)  # escapes control characters and lone surrogates
    except (RecursionError, ValueError):
        text = f"<{type(value).__name__} nested too deeply>"
    return text if len(text) <= 40 else text[:37] + "..."


def au_number(name: str) -> int:
    """The AU number of a canonical name (``AU12L`` -> 12)."""
    return int(name[2:].rstrip("LR"))


def au_side(name: str) -> str:
    """``"L"``, ``"R"`` or ``""`` for a canonical name."""
    return name[-1] if name[-1] in "LR" else ""


@cache
def default_au_names(face_type: FaceType) -> frozenset[str]:
    """The allowed AU names of a face type: the built-in AU table of ``servoface.sim.au`` when it loads, else the
    sets above."""
    table = _au_table(face_type)
    if table is not None:
        return frozenset(table.names())
    return builtin_au_names(face_type)


@cache
def au_ranges(face_type: FaceType) -> dict[str, tuple[float, float]]:
    """Per-AU intensity ranges that differ from the face's range (DFACS AU15 blink and AU16 lick have no
    counter: 0..1), from ``servoface.sim.au``'s table."""
    table = _au_table(face_type)
    out: dict[str, tuple[float, float]] = {}
    if table is None:
        if face_type == "dog":
            out = {f"AU{n}{s}": (0.0, 1.0) for n in (15, 16) for s in ("", "L", "R")}
        return out
    for entry in table.entries.values():
        rng = (float(entry.range[0]), float(entry.range[1]))
        if rng != tuple(table.intensity):
            out[entry.key] = rng
            out[f"{entry.key}L"] = out[f"{entry.key}R"] = rng
    return out


def head_au_ranges(head: Any) -> dict[str, tuple[float, float]]:
    """The intensity range of every AU name a head takes (sided names too), from its own AU table
    (``head.au_table_path``) when it has one, else its face type's built-in table. Empty when no table
    loads (the face type's range then holds for every name)."""
    table = _own_au_table(head)
    if table is None and getattr(head, "face_type", None) in ("human", "dog"):
        table = _au_table(head.face_type)
    out: dict[str, tuple[float, float]] = {}
    for entry in () if table is None else table.entries.values():
        rng = (float(entry.range[0]), float(entry.range[1]))
        out[entry.key] = rng
        if entry.sided:
            out[f"{entry.key}L"] = out[f"{entry.key}R"] = rng
    return out


def _own_au_table(head: Any) -> Any:
    """The head's own AU table (``head.au_table_path``), None when it has none; FrameError naming the head and
    the file when it cannot be read."""
    path = getattr(head, "au_table_path", None)
    if not path:
        return None
    try:
        from servoface.sim.au import load_au_table

        return load_au_table(path)
    except Exception as err:  # noqa: BLE001 - report any table problem as a frame-side error
        raise FrameError(f"head {getattr(head, 'name', '?')}: cannot read its AU table {path}: {err}") from err


def _au_table(face_type: FaceType) -> Any:
    try:
        from servoface.sim.au import load_au_table
    except ImportError:
        return None
    try:
        return load_au_table(face_type)
    except Exception:  # noqa: BLE001 - a broken data file must not break frames; fall back to the sets
        return None


def head_au_names(head: Any) -> frozenset[str]:
    """The AU names a head accepts: its own AU table (``head.au_table_path``, a ``servoface.sim.head.Head``) when it
    has one, else its face type's default set."""
    table = _own_au_table(head)
    return frozenset(table.names()) if table is not None else default_au_names(getattr(head, "face_type", None))


def builtin_au_names(face_type: FaceType) -> frozenset[str]:
    """The built-in sets of this module (facs-human.md §1, dfacs-dog.md §2)."""
    if face_type == "human":
        numbers = HUMAN_FACIAL_AUS + HUMAN_HEAD_AUS + HUMAN_EYE_AUS
        sided = HUMAN_SIDED_AUS
    elif face_type == "dog":
        numbers, sided = DOG_AUS, DOG_SIDED_AUS
    else:
        raise FrameError(f"face type: expected 'human' or 'dog', got {face_type!r}")
    names = {f"AU{n}" for n in numbers}
    names |= {f"AU{n}{side}" for n in sided for side in "LR"}
    return frozenset(names)


def intensity_range(face_type: FaceType) -> tuple[float, float]:
    """Allowed intensity interval: human FACS 0..1, DFACS signed -1..1 (negative = counter AU)."""
    if face_type == "human":
        return (0.0, 1.0)
    if face_type == "dog":
        return (-1.0, 1.0)
    raise FrameError(f"face type: expected 'human' or 'dog', got {face_type!r}")
