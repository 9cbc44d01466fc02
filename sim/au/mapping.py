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

    A muscle or joint the table names but the head lacks is an error (HeadProfileError naming the AU),
    unless ``allow_missing``: then it is skipped and listed in ``missing`` (a smaller head reusing a
    built-in table: its AUs still validate, the parts it lacks just do not move).
    """

    def __init__(
        self,
        table: AUTable,
        muscle_names: Sequence[str],
        joint_names: Sequence[str],
        allow_missing: bool = False,
    ) -> None:
        self.table = table
        self.allow_missing = allow_missing
        self.missing: set[str] = set()
        self.muscle_names = tuple(muscle_names)
        self.joint_names = tuple(joint_names)
        m_index = {n: i for i, n in enumerate(self.muscle_names)}
        j_index = {n: i for i, n in enumerate(self.joint_names)}
        self.channels: list[tuple[int, str]] = []
        for number in sorted(table.entries):
            entry = table.entries[number]
            self.channels += [(number, "L"), (number, "R")] if entry.sided else [(number, "")]
        self.channel_index = {ch: i for i, ch in enumerate(self.channels)}
        k = len(self.channels)
        # columns 0..k-1: positive part; k..2k-1: magnitude of the negative (counter) part
        self.to_muscles = np.zeros((len(self.muscle_names), 2 * k))
        self.to_joints = np.zeros((len(self.joint_names), 2 * k))
        self.low = np.zeros(k)
        self.high = np.zeros(k)
        for col, (number, side) in enumerate(self.channels):
            entry = table.entries[number]
            self.low[col], self.high[col] = entry.range
            counter = entry.counter if entry.counter is not None else _mirror(entry.action)
            for offset, action in ((0, entry.action), (k, counter)):
                self._fill(entry, side, action, col + offset, m_index, j_index)
        self.contraction_low, self.contraction_high = table.contraction

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
                    continue
                if name not in index:
                    raise HeadProfileError(
                        f"{where}: {kind} {name!r} is not in the head (known {kind}s: {sorted(index)})"
                    )
                matrix[index[name], col] += share * weight

    # --- validation -------------------------------------------------------------------------------------

    def channel_values(self, aus: Mapping[str, float]) -> FloatArray:
        """Validate ``aus`` and return the summed, clamped value of every channel (K,)."""
        values = np.zeros(len(self.channels))
        for name, value in aus.items():
            number, side, x = check_au(self.table, name, value)
            for s in ("L", "R") if self.table.entries[number].sided and not side else (side,):
                values[self.channel_index[(number, s)]] += x
        return np.clip(values, self.low, self.high)

    # --- evaluation -------------------------------------------------------------------------------------

    def evaluate(self, aus: Mapping[str, float]) -> tuple[FloatArray, FloatArray]:
        """(contractions (M,) clamped to the table's range, joint offsets (J,) deg, unclamped)."""
        x = self.channel_values(aus)
        split = np.concatenate([np.maximum(x, 0.0), np.maximum(-x, 0.0)])
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
    x = float(value)
    if not math.isfinite(x) or not entry.range[0] <= x <= entry.range[1]:
        hint = " (this AU has no counter AU)" if entry.range[0] >= 0.0 and x < 0.0 else ""
        raise ActionUnitValueError(f"{name}: expected a finite intensity in {list(entry.range)}, got {value!r}{hint}")
    return number, side, x


def _mirror(action: AUAction) -> AUAction:
    return AUAction(
        f"counter of {action.name}",
        tuple((n, -w) for n, w in action.muscles),
        tuple((n, -w) for n, w in action.joints),
    )
