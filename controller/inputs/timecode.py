"""Timecode cells ``HH:MM:SS:FF[.sub]`` -> seconds, as real blendshape CSVs write them.

Who writes them: Live Link Face (column ``Timecode``, e.g. ``00:32:09:07.867``: frame 7 of a 60 fps
timecode plus 0.867 of a frame) and freemocap skellytracker's ``blendshapes_to_csv`` (column ``Timestamp``,
``00:00:01:02.032``). ``;`` (drop-frame) reads like ``:``.

* The frame rate of the ``FF`` field is ``fps`` when given. Otherwise it is inferred: once the seconds have
  rolled over, the largest ``FF`` seen bounds the rate and the smallest common timecode rate above it is
  taken (Live Link Face: ``FF`` 0..59 -> 60, also when it records a row every second frame; skellytracker:
  0..29 -> 30). A take too short to roll over is read at 60 fps, with a note.
* skellytracker rolls the seconds and minutes fields over at 30, not 60: a file whose seconds never pass 29
  while its minutes advance is read that way (noted).
* A take across midnight (23:59:59 -> 00:00:00) keeps counting up.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

from servoface.controller.inputs.tolerance import BadRow

_TIMECODE = re.compile(r"^\s*(\d{1,2})[:;](\d{1,2})[:;](\d{1,2})[:;](\d{1,3})(\.\d+)?\s*$")
RATES = (24.0, 25.0, 30.0, 48.0, 50.0, 60.0, 100.0, 120.0, 240.0)
DEFAULT_RATE = 60.0
_DAY_S = 86400.0


@dataclass(frozen=True)
class Timecode:
    hours: int
    minutes: int
    seconds: int
    frame: int
    sub: float  # fraction of a frame, 0..1


def looks_like_timecode(text: str) -> bool:
    return _TIMECODE.match(text) is not None


def parse_timecode(text: str, where: str) -> Timecode:
    """One cell; BadRow naming ``where`` and the expected form otherwise."""
    match = _TIMECODE.match(text)
    if match is None:
        raise BadRow(f"{where}: {text!r} is not a timecode HH:MM:SS:FF[.sub]", "bad timecode")
    h, m, s, f = (int(match.group(k)) for k in range(1, 5))
    if m > 59 or s > 59:
        raise BadRow(f"{where}: {text!r}: minutes and seconds must be 0..59", "bad timecode")
    return Timecode(h, m, s, f, float(match.group(5) or 0.0))


def timecode_seconds(codes: Sequence[Timecode], fps: float | None) -> tuple[list[float], str]:
    """Seconds for each timecode (see the module doc) and a line saying how they were read."""
    if not codes:
        return [], ""
    rolled = any(_whole(a) != _whole(b) for a, b in zip(codes, codes[1:], strict=False))
    top = max(c.frame for c in codes)
    notes: list[str] = []
    if fps is not None:
        rate, how = fps, "given"
        if top >= fps:
            notes.append(f"the frame field reaches {top}, not below the given {fps:g} fps")
    elif rolled:
        rate = next((r for r in RATES if r > top), float(top + 1))
        how = f"inferred: frames run to {top} before the seconds roll over; set the fps option to override"
    else:
        rate, how = DEFAULT_RATE, "assumed: the take never rolls over a second; set the fps option"
    base = 60
    minutes_advance = any((a.hours, a.minutes) != (b.hours, b.minutes) for a, b in zip(codes, codes[1:], strict=False))
    if minutes_advance and max(c.seconds for c in codes) < 30:
        base = 30
        notes.append("seconds and minutes roll over at 30 (as skellytracker writes them)")
    out: list[float] = []
    offset = 0.0
    for code in codes:
        t = ((code.hours * base + code.minutes) * base + code.seconds) + (code.frame + code.sub) / rate + offset
        if out and t < out[-1] - _DAY_S / 2:  # past midnight
            offset += _DAY_S
            t += _DAY_S
        out.append(t)
    text = f"HH:MM:SS:FF timecode, frames at {rate:g} fps ({how})"
    return out, "; ".join([text, *notes])


def _whole(code: Timecode) -> tuple[int, int, int]:
    return code.hours, code.minutes, code.seconds
