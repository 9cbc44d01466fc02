"""A direct AU -> actuator-target table: per AU, what each servo's actuator does at full intensity.

The way HEAD's and Bottango's motor maps work, for heads without skin (or a builder who prefers to tune
servos, not muscles). File format (``direct.toml`` beside ``head.toml``, named by ``au_direct``)::

    schema_version = 1
    face_type = "human"

    [AU1]                                   # Inner Brow Raiser
    targets = { "brow_{side}" = 12.0 }      # deg (joint) or mm (anchor) from the actuator's neutral, at 1.0

    [AU5.counter]                           # DFACS: what a NEGATIVE intensity does, at -1
    targets = { "ear_l" = -20.0 }

An AU listed here is driven from this table only (its muscle-model row is not used); every other AU goes
through the muscle model. ``{side}`` becomes ``l`` / ``r`` for a sided AU (AU1L moves ``brow_l``); a role
without ``{side}`` in a sided AU takes half from each side, as in the AU tables. Contributions of all AUs
are summed, then clamped to each actuator's range: the same blending and clamping rules as the muscle
model. ``derive_direct_table`` writes this table from a head's muscle model (a start to edit).
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.errors import HeadProfileError
from servoface.sim.textfile import read_utf8

FloatArray = NDArray[np.float64]
_KEY_RE = re.compile(r"^AU([1-9]\d{0,2})$")
_ROLE_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\{side\}[A-Za-z0-9_]*)?$")
TOP_KEYS = {"schema_version", "face_type", "description"}


@dataclass(frozen=True)
class DirectRow:
    """One AU of a direct table: role templates -> target offset at +1 (and at -1 for a signed AU)."""

    number: int
    targets: tuple[tuple[str, float], ...]
    counter: tuple[tuple[str, float], ...] | None = None


@dataclass(frozen=True)
class DirectTable:
    face_type: str
    rows: dict[int, DirectRow]
    path: Path


def _targets(value: Any, where: str) -> tuple[tuple[str, float], ...]:
    if not isinstance(value, Mapping):
        raise HeadProfileError(f"{where}.targets: expected a table of role = number (deg or mm), got {value!r}")
    out = []
    for role, x in value.items():
        if not _ROLE_RE.match(role):
            raise HeadProfileError(f"{where}.targets: {role!r} is not an actuator role (letters, digits, _, {{side}})")
        if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x):
            raise HeadProfileError(f"{where}.targets.{role}: expected a finite number (deg or mm), got {x!r}")
        out.append((role, float(x)))
    return tuple(out)


def _row(number: int, data: Any, where: str) -> DirectRow:
    if not isinstance(data, Mapping):
        raise HeadProfileError(f"{where}: expected a table with targets = {{ role = value }}, got {data!r}")
    unknown = sorted(set(data) - {"targets", "counter", "name", "note"})
    if unknown:
        raise HeadProfileError(f"{where}: unknown key(s) {unknown}; allowed: counter, name, note, targets")
    counter = None
    if "counter" in data:
        c = data["counter"]
        if not isinstance(c, Mapping) or set(c) - {"targets", "name", "note"}:
            raise HeadProfileError(f"{where}.counter: expected a table with targets = {{ role = value }}, got {c!r}")
        counter = _targets(c.get("targets", {}), f"{where}.counter")
    return DirectRow(number, _targets(data.get("targets", {}), where), counter)


def load_direct_table(path: str | Path) -> DirectTable:
    """Load and validate a direct table; errors (HeadProfileError) name the file and key path."""
    path = Path(path)
    try:
        text = read_utf8(path, HeadProfileError, what="a direct AU table")
    except FileNotFoundError as err:
        raise HeadProfileError(f"{path}: direct AU table not found") from err
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise HeadProfileError(f"{path}: not valid TOML: {err}") from err
    if raw.get("schema_version") != 1:
        raise HeadProfileError(f"{path}: schema_version: expected 1, got {raw.get('schema_version')!r}")
    face_type = raw.get("face_type")
    if face_type not in ("human", "dog"):
        raise HeadProfileError(f"{path}: face_type: expected 'human' or 'dog', got {face_type!r}")
    rows: dict[int, DirectRow] = {}
    for key, data in raw.items():
        if key in TOP_KEYS:
            continue
        match = _KEY_RE.match(key)
        if match is None:
            raise HeadProfileError(f"{path}: {key!r} is neither a header key nor an AU row like [AU12]")
        rows[int(match.group(1))] = _row(int(match.group(1)), data, f"{path}: {key}")
    return DirectTable(str(face_type), rows, path)


class DirectMapping:
    """A direct table bound to one head's roles and an AU mapping's channels.

    ``matrix`` (R, 2K): column c < K = channel c's positive part, K + c = its counter, like `AUMapping`.
    Roles the table names but the head lacks are skipped and listed in ``missing`` (per AU in ``notes``).
    """

    def __init__(
        self,
        table: DirectTable,
        channels: Sequence[tuple[int, str]],
        sided: Mapping[int, bool],
        roles: Sequence[str],
    ) -> None:
        self.table = table
        self.roles = tuple(roles)
        index = {r: i for i, r in enumerate(self.roles)}
        k = len(channels)
        self.matrix = np.zeros((len(self.roles), 2 * k))
        self.missing: set[str] = set()
        self.notes: dict[int, list[str]] = {}
        self.numbers = frozenset(n for n in table.rows if n in sided)
        self.unknown_aus = sorted(n for n in table.rows if n not in sided)
        if self.unknown_aus:  # a typo (AU99 for AU9) must not pass silently and move nothing
            known = ", ".join(f"AU{n}" for n in sorted(sided))
            raise HeadProfileError(
                f"{table.path}: AU{self.unknown_aus[0]}: expected an AU of the {table.face_type} AU table "
                f"({known}), got AU{self.unknown_aus[0]}"
            )
        for col, (number, side) in enumerate(channels):
            row = table.rows.get(number)
            if row is None:
                continue
            counter = row.counter if row.counter is not None else tuple((r, -w) for r, w in row.targets)
            for offset, targets in ((0, row.targets), (k, counter)):
                for template, weight in targets:
                    if "{side}" in template and not sided[number]:
                        raise HeadProfileError(
                            f"{table.path}: AU{number}.targets: {template!r} uses {{side}} but AU{number} is not sided"
                        )
                    if "{side}" in template:
                        role, share = template.replace("{side}", side.lower()), 1.0
                    else:
                        role, share = template, (0.5 if side else 1.0)
                    if role not in index:  # noted for every AU that names it, not only the first
                        notes = self.notes.setdefault(number, [])
                        if (note := f"actuator {role!r} is not in the head") not in notes:
                            notes.append(note)
                        self.missing.add(role)
                        continue
                    self.matrix[index[role], col + offset] += share * weight
        self.active_rows = np.flatnonzero(np.abs(self.matrix).sum(axis=1) > 0)

    def deltas(self, split: FloatArray) -> FloatArray:
        """(R,) target offsets from neutral for a split channel vector (2K,) (see `AUMapping.evaluate`)."""
        return np.asarray(self.matrix @ split, dtype=np.float64)


def derive_direct_table(model: Any, *, note: str = "") -> str:
    """The direct table (TOML text) equivalent to ``model``'s muscle model at full intensity of each AU.

    ``model`` is a `servoface.sim.face_model.FaceModel`. Each row is the actuator targets of that AU alone
    minus the neutral targets; a sided AU is solved on the left and written with ``{side}`` for the roles
    that end in ``_l`` (their ``_r`` twin takes the right). Targets under 0.01 deg/mm are left out.
    """
    table = model.mapping.table
    neutral = model.solve({}).actuator_targets
    roles = list(neutral)
    lines = [
        f"# Direct AU -> actuator targets for head {model.head.name!r}, derived from its muscle model.",
        "# Values: deg (joint actuators) or mm (anchor actuators) from each actuator's neutral, at full intensity.",
        "# An AU listed here is driven from this table only; delete a row to give it back to the muscle model.",
        "# Format: servoface.sim.au.direct (docstring). Edit freely: this is a start, not a measurement.",
    ]
    if note:
        lines.append(f"# {note}")
    lines += ["", "schema_version = 1", f'face_type = "{table.face_type}"', ""]

    def row_for(value: float, number: int, sided: bool) -> dict[str, float]:
        both = model.solve({f"AU{number}": value}).actuator_targets
        left = model.solve({f"AU{number}L": value}).actuator_targets if sided else both
        out: dict[str, float] = {}
        for role in roles:
            if sided and role.endswith("_l") and role[:-2] + "_r" in neutral:
                d = left[role] - neutral[role]
                key = role[:-2] + "_{side}"
            elif sided and role.endswith("_r") and role[:-2] + "_l" in neutral:
                continue
            else:
                d = both[role] - neutral[role]
                key = role
            d /= abs(value)
            if abs(d) >= 0.01:
                out[key] = round(d, 2)
        return out

    for number in sorted(table.entries):
        entry = table.entries[number]
        lo, hi = entry.range
        pos = row_for(hi, number, entry.sided) if hi > 0 else {}
        neg = row_for(lo, number, entry.sided) if lo < 0 else {}
        if not pos and not neg:
            continue
        title = entry.action.name.replace('"', "'")
        lines.append(f"[AU{number}]  # {title}")
        lines.append(f"targets = {_inline(pos)}")
        if neg:
            lines += [f"[AU{number}.counter]", f"targets = {_inline(neg)}"]
        lines.append("")
    return "\n".join(lines)


def _inline(values: Mapping[str, float]) -> str:
    if not values:
        return "{}"
    return "{ " + ", ".join(f'"{k}" = {v:g}' for k, v in values.items()) + " }"
