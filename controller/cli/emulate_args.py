"""Parsers for `servoface emulate`'s chain and fault descriptions (each raises ValueError naming the part).

parse_ids("1-4,7")                          -> [1, 2, 3, 4, 7]
parse_servos("1-17:XL330-M288,18-21:XL430-W250") -> [(1, "XL330-M288"), ..., (21, "XL430-W250")]
parse_fault("3:no_reply@2s+0.5s")            -> FaultSpec(3, "no_reply", start_s=2.0, duration_s=0.5)
parse_fault("3:no_reply*1")                  -> FaultSpec(3, "no_reply", replies=1): one lost reply
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from servoface.hardware.emulator.faults import REPLY_KINDS

MAX_SERVO_ID = 252


def parse_ids(text: str) -> list[int]:
    """``"1-4,7,10-12"`` -> [1, 2, 3, 4, 7, 10, 11, 12]; raises ValueError naming the bad part."""
    ids: list[int] = []
    for part in text.split(","):
        ids.extend(_id_range(part, text))
    _check_ids(ids, text)
    return ids


def _id_range(part: str, text: str) -> list[int]:
    part = part.strip()
    if not part:
        raise ValueError(f"empty element in id list {text!r}")
    if "-" in part:
        lo_text, _, hi_text = part.partition("-")
        try:
            lo, hi = int(lo_text), int(hi_text)
        except ValueError:
            raise ValueError(f"id range {part!r}: expected two integers like 1-24") from None
        if lo > hi:
            raise ValueError(f"id range {part!r}: start must not exceed end")
        return list(range(lo, hi + 1))
    try:
        return [int(part)]
    except ValueError:
        raise ValueError(f"id {part!r}: expected an integer or a range like 1-24") from None


def _check_ids(ids: list[int], text: str) -> None:
    bad = [i for i in ids if not 0 <= i <= MAX_SERVO_ID]
    if bad:
        raise ValueError(f"ids {bad}: expected 0..{MAX_SERVO_ID}")
    if len(set(ids)) != len(ids):
        raise ValueError(f"id list {text!r} names some id twice")


def parse_servos(text: str) -> list[tuple[int, str]]:
    """``"1-17:XL330-M288,18-21:XL430-W250"`` -> (id, model) pairs; every group is IDS:MODEL."""
    pairs: list[tuple[int, str]] = []
    for group in text.split(","):
        ids_text, sep, model = group.strip().rpartition(":")
        if not sep or not ids_text or not model.strip():
            raise ValueError(f"servo group {group.strip()!r}: expected IDS:MODEL, e.g. 1-17:XL330-M288")
        pairs.extend((sid, model.strip()) for sid in _id_range(ids_text, text))
    _check_ids([sid for sid, _ in pairs], text)
    return pairs


@dataclass(frozen=True)
class FaultSpec:
    """One scripted fault: on servo ``servo_id`` from ``start_s`` (after serving starts) for ``duration_s``
    (None = until the emulator stops); ``value`` is late_reply's delay (s) or dropped_bytes' count;
    ``replies``: a reply fault that spoils only this many of the servo's status packets, then ends."""

    servo_id: int
    kind: str
    start_s: float = 0.0
    duration_s: float | None = None
    value: float | None = None
    replies: int | None = None


def _seconds(text: str, what: str) -> float:
    t = text.strip().lower()
    scale = 1.0
    if t.endswith("ms"):
        t, scale = t[:-2], 1e-3
    elif t.endswith("s"):
        t = t[:-1]
    try:
        value = float(t) * scale
    except ValueError:
        raise ValueError(f"{what} {text!r}: expected seconds like 2s, 0.5 or 250ms") from None
    if not math.isfinite(value) or value < 0:
        raise ValueError(f"{what} {text!r}: expected a finite time >= 0")
    return value


def parse_fault(text: str, kinds: frozenset[str] | None = None) -> FaultSpec:
    """``ID:KIND[=VALUE][*N][@START[+DURATION]]``, e.g. ``3:no_reply@2s+0.5s``, ``5:late_reply=20ms@1s``,
    ``2:overload@3s`` (from 3 s on), ``4:disconnect`` (now, for good), ``3:no_reply*1`` (servo 3's next
    reply lost, exactly one: ``*N`` counts a reply fault's spoiled status packets)."""
    head, sep, kind_part = text.strip().partition(":")
    if not sep:
        raise ValueError(f"fault {text!r}: expected ID:KIND[=VALUE][*N][@START[+DURATION]], e.g. 3:no_reply@2s+0.5s")
    try:
        servo_id = int(head)
    except ValueError:
        raise ValueError(f"fault {text!r}: servo id {head!r} is not an integer") from None
    kind_text, _, when = kind_part.partition("@")
    kind_text, star, count_text = kind_text.partition("*")
    kind, eq, value_text = kind_text.partition("=")
    kind = kind.strip()
    if kinds is not None and kind not in kinds:
        raise ValueError(f"fault {text!r}: kind {kind!r}, expected one of {sorted(kinds)}")
    value = None
    if eq:
        if kind == "late_reply":
            value = _seconds(value_text, f"fault {text!r} delay")
        elif kind == "dropped_bytes":
            try:
                value = float(int(value_text))
            except ValueError:
                raise ValueError(f"fault {text!r}: dropped_bytes={value_text!r}, expected an integer") from None
        else:
            raise ValueError(f"fault {text!r}: only late_reply=DELAY and dropped_bytes=N take a value")
    replies = None
    if star:
        if kind not in REPLY_KINDS:
            raise ValueError(f"fault {text!r}: only reply faults {sorted(REPLY_KINDS)} take *N")
        try:
            replies = int(count_text)
        except ValueError:
            raise ValueError(f"fault {text!r}: *{count_text!r}, expected a count of replies >= 1") from None
        if replies < 1:
            raise ValueError(f"fault {text!r}: *{count_text!r}, expected a count of replies >= 1")
    start_s, duration_s = 0.0, None
    if when:
        start_text, plus, duration_text = when.partition("+")
        start_s = _seconds(start_text, f"fault {text!r} start")
        if plus:
            duration_s = _seconds(duration_text, f"fault {text!r} duration")
    return FaultSpec(servo_id, kind, start_s, duration_s, value, replies)
