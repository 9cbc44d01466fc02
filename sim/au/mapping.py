"""An AU table compiled against one head: AU intensities -> muscle contractions and joint angles.

Every AU channel (one per side for sided AUs) has a positive and a negative (counter) column in two small
dense matrices, so a frame is two matrix-vector products, a sum and a clamp. Validation comes first and
changes nothing: an unknown name raises ``UnknownActionUnitError``, a non-finite or out-of-range value
``ActionUnitValueError``; both name the AU and what was expected.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray
from servoface.sim.au.table import AUAction, AUEntry, AUTable
from servoface.sim.errors import ActionUnitValueError, HeadProfileError, UnknownActionUnitError

FloatArray = NDArray[np.float64]
_NAME_RE = re.compile(r"^AU0*([1-9]\d{0,2})([LR]?)$")


def canonical_au_name(name: object) -> tuple[int, str]:
    """(number, side) of an AU name: "AU12" -> (12, ""), "au12l" / "AU012L" -> (12, "L")."""
    if not isinstance(name, str):
        raise UnknownActionUnitError(f"AU name {name!r}: expected a string like 'AU12' or 'AU12L'")
    match = _NAME_RE.match(name.strip().upper())
    if match is None:
        raise UnknownActionUnitError(
            f"AU name {name!r}: expected 'AU<number>' with optional side L/R, e.g. 'AU12', 'AU12L' "
            "(a DFACS counter AU is a negative value on the plain name)"
        )
    return int(match.group(1)), match.group(2)


class AUMapping:
    """An AU table bound to a head's muscle order and joint order.

    The table is applied to what the head has: with ``allow_missing`` (the default) a muscle or joint the
    table names but the head lacks is skipped, listed in ``missing`` and noted per AU in ``notes``; an AU
    whose row reaches nothing on this head is listed in ``unreachable`` (it still validates, it just moves
    nothing). ``allow_missing=False`` makes a missing name a HeadProfileError naming the AU (strict, for a
    table written for exactly this head). ``skip``: AUs whose rows are not compiled (driven elsewhere, e.g.
    by a direct table).
    """

    def __init__(
        self,
        table: AUTable,
        muscle_names: Sequence[str],
        joint_names: Sequence[str],
        allow_missing: bool = True,
        skip: frozenset[int] = frozenset(),
    ) -> None:
        self.table = table
        self.allow_missing = allow_missing
        self.skip = skip
        self.missing: set[str] = set()
        self._missing_by_au: dict[int, dict[str, list[str]]] = {}
        self.muscle_names = tuple(muscle_names)
        self.joint_names = tuple(joint_names)
        m_index = {n: i for i, n in enumerate(self.muscle_names)}
        j_index = {n: i for i, n in enumerate(self.joint_names)}
        self.channels: list[tuple[int, str]] = []
        for number in sorted(table.entries):
            entry = table.entries[number]
            self.channels += [(number, "L"), (number, "R")] if entry.sided else [(number, "")]
        self.channel_index = {ch: i for i, ch in enumerate(self.channels)}
        self._names: dict[str, tuple[tuple[int, ...], float, float]] = {}  # see `channel_values`
        k = len(self.channels)
        # columns 0..k-1: positive part; k..2k-1: magnitude of the negative (counter) part
        self.to_muscles = np.zeros((len(self.muscle_names), 2 * k))
        self.to_joints = np.zeros((len(self.joint_names), 2 * k))
        self.low = np.zeros(k)
        self.high = np.zeros(k)
        for col, (number, side) in enumerate(self.channels):
            entry = table.entries[number]
            self.low[col], self.high[col] = entry.range
            if number in skip:
                continue
            counter = entry.counter if entry.counter is not None else _mirror(entry.action)
            for offset, action in ((0, entry.action), (k, counter)):
                self._fill(entry, side, action, col + offset, m_index, j_index)
        self.contraction_low, self.contraction_high = table.contraction
        self.notes: dict[int, list[str]] = {
            n: [_missing_note(kind, names, bool(m_index)) for kind, names in by_kind.items()]
            for n, by_kind in self._missing_by_au.items()
        }
        self.unreachable: dict[int, str] = {}
        used = (np.abs(self.to_muscles).sum(axis=0) + np.abs(self.to_joints).sum(axis=0)) > 0
        for number in sorted(table.entries):
            cols = [i for i, (n, _) in enumerate(self.channels) if n == number]
            if number in skip or used[cols].any() or used[[c + k for c in cols]].any():
                continue
            notes = self.notes.get(number)
            if notes:
                self.unreachable[number] = "; ".join(notes)
            else:
                self.unreachable[number] = table.entries[number].note or "its AU table row moves nothing"

    def _fill(
        self,
        entry: AUEntry,
        side: str,
        action: AUAction,
        col: int,
        m_index: Mapping[str, int],
        j_index: Mapping[str, int],
    ) -> None:
        where = f"{self.table.path}: AU{entry.number}"
        for names, index, matrix, kind in (
            (action.muscles, m_index, self.to_muscles, "muscle"),
            (action.joints, j_index, self.to_joints, "joint"),
        ):
            for template, weight in names:
                if "{side}" in template:
                    name, share = template.replace("{side}", side.lower()), 1.0
                else:
                    name, share = template, (0.5 if side else 1.0)
                if name not in index and self.allow_missing:
                    self.missing.add(name)
                    self._missing_by_au.setdefault(entry.number, {}).setdefault(kind, [])
                    if name not in self._missing_by_au[entry.number][kind]:
                        self._missing_by_au[entry.number][kind].append(name)
                    continue
                if name not in index:
                    raise HeadProfileError(
                        f"{where}: {kind} {name!r} is not in the head (known {kind}s: {sorted(index)})"
                    )
                matrix[index[name], col] += share * weight

    # --- validation -------------------------------------------------------------------------------------

    def channel_values(self, aus: Mapping[str, float]) -> FloatArray:
        """Validate ``aus`` and return the summed, clamped value of every channel (K,).

        A name seen before is not parsed again (`_channels_of`); a plain finite float inside its range is
        taken as `check_au` would take it, anything else goes through `check_au` (which raises)."""
        values = np.zeros(len(self.channels))
        names = self._names
        for name, value in aus.items():
            known = names.get(name) if type(name) is str else None
            if known is not None and type(value) is float and known[1] <= value <= known[2]:
                x = value  # (NaN fails the comparison, +-inf is outside every range)
                channels = known[0]
            else:
                number, side, x = check_au(self.table, name, value)
                channels = self._channels_of(name, number, side)
            for ch in channels:
                values[ch] += x
        return np.clip(values, self.low, self.high)

    def _channels_of(self, name: object, number: int, side: str) -> tuple[int, ...]:
        """The channel columns of a validated AU name, kept with its range for the next frame."""
        entry = self.table.entries[number]
        channels = tuple(self.channel_index[(number, s)] for s in (("L", "R") if entry.sided and not side else (side,)))
        if type(name) is str:
            self._names[name] = (channels, float(entry.range[0]), float(entry.range[1]))
        return channels

    # --- evaluation -------------------------------------------------------------------------------------

    def split(self, aus: Mapping[str, float]) -> FloatArray:
        """(2K,) validated channel values split into positive parts and counter magnitudes."""
        x = self.channel_values(aus)
        out: FloatArray = np.maximum(np.concatenate((x, -x)), 0.0)  # (one maximum over both halves)
        return out

    def evaluate(self, aus: Mapping[str, float]) -> tuple[FloatArray, FloatArray]:
        """(contractions (M,) clamped to the table's range, joint offsets (J,) deg, unclamped)."""
        return self.evaluate_split(self.split(aus))

    def evaluate_split(self, split: FloatArray) -> tuple[FloatArray, FloatArray]:
        """`evaluate` from an already validated `split` vector."""
        contractions = np.clip(self.to_muscles @ split, self.contraction_low, self.contraction_high)
        return contractions, self.to_joints @ split


def check_au(table: AUTable, name: object, value: object) -> tuple[int, str, float]:
    """Validate one AU entry against a table: (number, side, intensity) or a typed error naming the AU."""
    number, side = canonical_au_name(name)
    entry = table.entries.get(number)
    if entry is None:
        known = ", ".join(f"AU{n}" for n in sorted(table.entries))
        raise UnknownActionUnitError(f"{name}: not in the {table.face_type} AU table (known: {known})")
    if side and not entry.sided:
        raise UnknownActionUnitError(f"{name}: AU{number} has no left/right variant; use 'AU{number}'")
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise ActionUnitValueError(f"{name}: expected a number in {list(entry.range)}, got {value!r}")
    try:
        x = float(value)
    except OverflowError:  # an integer past float range (e.g. 10**400)
        x = math.inf if value > 0 else -math.inf
    if not math.isfinite(x) or not entry.range[0] <= x <= entry.range[1]:
        hint = " (this AU has no counter AU)" if entry.range[0] >= 0.0 and x < 0.0 else ""
        raise ActionUnitValueError(
            f"{name}: expected a finite intensity in {list(entry.range)}, got {_short(value)}{hint}"
        )
    return number, side, x


def _short(value: object) -> str:
    """``repr`` of a number for a message, a huge integer by its size (its digits are no use to anyone)."""
    if isinstance(value, int | np.integer) and abs(int(value)) >= 10**15:
        return f"an integer of {len(str(abs(int(value))))} digits" if abs(int(value)) < 10**4000 else "a huge integer"
    return repr(value)


def _missing_note(kind: str, names: list[str], has_muscles: bool) -> str:
    """'muscles zygomatic_major_l, zygomatic_major_r are not in the head' (or: the head has no muscles)."""
    listed = ", ".join(names)
    if kind == "muscle" and not has_muscles:
        return f"this head has no muscles ({listed})"
    plural = f"{kind}s {listed} are" if len(names) > 1 else f"{kind} {listed} is"
    return f"{plural} not in the head"


def _mirror(action: AUAction) -> AUAction:
    return AUAction(
        f"counter of {action.name}",
        tuple((n, -w) for n, w in action.muscles),
        tuple((n, -w) for n, w in action.joints),
    )
