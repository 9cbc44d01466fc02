"""AU tables: which muscles contract and which joints turn for each action unit (TOML data files).

File format (``sim/au/human.toml``, ``sim/au/dog.toml``; a head profile may ship its own)::

    schema_version = 1
    face_type = "human"            # or "dog"
    intensity = [0.0, 1.0]         # default intensity range of every AU (DFACS: [-1.0, 1.0])
    contraction = [0.0, 1.0]       # clamp of each muscle's summed contraction (DFACS: [-1.0, 1.0])

    [AU12]
    name = "Lip Corner Puller"
    source = "facs-human.md §1 ..."          # required: where the row comes from
    sided = true                             # AU12L / AU12R allowed; AU12 drives both sides
    muscles = { "zygomatic_major_{side}" = 1.0 }   # contraction at full intensity
    joints = { "jaw" = 0.0 }                        # degrees at full intensity
    range = [0.0, 1.0]                       # optional, overrides ``intensity``

    [AU5.counter]                            # DFACS: what a NEGATIVE intensity does, at -1
    name = "Backward ears"
    muscles = { ... }
    joints = { "ear_pan_{side}" = -45.0 }

``{side}`` becomes ``l`` / ``r``. A name without ``{side}`` in a sided AU (a centre muscle such as the
procerus) takes half the weight from each side. A signed AU without a ``counter`` table mirrors its
positive row (weights negated). Contributions of all AUs are summed, then clamped (muscles to
``contraction``, joints to their limits): that is how antagonists (AU1/2 vs AU4, AU5 vs AU43/45, AU12 vs
AU15) combine.
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from servoface.sim.errors import HeadProfileError
from servoface.sim.textfile import read_utf8

AU_DIR = Path(__file__).resolve().parent
FACE_TYPES = ("human", "dog")
_KEY_RE = re.compile(r"^AU([1-9]\d{0,2})$")
_NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\{side\}[A-Za-z0-9_]*)?$")


@dataclass(frozen=True)
class AUAction:
    """What one direction of an AU does at full intensity: muscle contractions and joint degrees."""

    name: str
    muscles: tuple[tuple[str, float], ...]
    joints: tuple[tuple[str, float], ...]


@dataclass(frozen=True)
class AUEntry:
    """One row of an AU table. ``counter`` is None for a mirrored (or absent) counter AU."""

    number: int
    source: str
    sided: bool
    range: tuple[float, float]
    action: AUAction
    counter: AUAction | None = None
    note: str = ""

    @property
    def key(self) -> str:
        return f"AU{self.number}"


@dataclass(frozen=True)
class AUTable:
    """A parsed AU table (see the module docstring for the file format)."""

    face_type: str
    intensity: tuple[float, float]
    contraction: tuple[float, float]
    entries: dict[int, AUEntry]
    path: Path

    def names(self) -> frozenset[str]:
        """Every AU name this table accepts: AU<n>, plus AU<n>L / AU<n>R for sided AUs."""
        out = {e.key for e in self.entries.values()}
        out |= {f"{e.key}{s}" for e in self.entries.values() if e.sided for s in "LR"}
        return frozenset(out)


def _pair(value: object, where: str) -> tuple[float, float]:
    items: list[Any] = list(value) if isinstance(value, list) else []
    ok = len(items) == 2 and all(
        isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in items
    )
    if not ok or items[0] >= items[1]:
        raise HeadProfileError(f"{where}: expected [low, high] with low < high, got {value!r}")
    return (float(items[0]), float(items[1]))


def _weights(data: Mapping[str, Any], key: str, where: str) -> tuple[tuple[str, float], ...]:
    table = data.get(key, {})
    if not isinstance(table, Mapping):
        raise HeadProfileError(f"{where}.{key}: expected a table of name = number, got {table!r}")
    out = []
    for name, weight in table.items():
        if not _NAME_RE.match(name):
            raise HeadProfileError(f"{where}.{key}: {name!r} is not a muscle/joint name (letters, digits, _, {{side}})")
        if isinstance(weight, bool) or not isinstance(weight, int | float) or not math.isfinite(weight):
            raise HeadProfileError(f"{where}.{key}.{name}: expected a finite number, got {weight!r}")
        out.append((name, float(weight)))
    return tuple(out)


def _action(data: Mapping[str, Any], where: str, default_name: str) -> AUAction:
    name = data.get("name", default_name)
    if not isinstance(name, str):
        raise HeadProfileError(f"{where}.name: expected a string, got {name!r}")
    return AUAction(name, _weights(data, "muscles", where), _weights(data, "joints", where))


def _entry(number: int, data: Any, where: str, intensity: tuple[float, float]) -> AUEntry:
    if not isinstance(data, Mapping):
        raise HeadProfileError(f"{where}: expected a table, got {data!r}")
    allowed = {"name", "source", "sided", "muscles", "joints", "range", "counter", "note"}
    unknown = sorted(set(data) - allowed)
    if unknown:
        raise HeadProfileError(f"{where}: unknown key(s) {unknown}; allowed keys are {sorted(allowed)}")
    source = data.get("source")
    if not isinstance(source, str) or not source.strip():
        raise HeadProfileError(f"{where}.source: every AU row needs a source (reference sheet section / table)")
    sided = data.get("sided", False)
    if not isinstance(sided, bool):
        raise HeadProfileError(f"{where}.sided: expected true or false, got {sided!r}")
    rng = _pair(data["range"], f"{where}.range") if "range" in data else intensity
    counter = None
    if "counter" in data:
        if not isinstance(data["counter"], Mapping):
            raise HeadProfileError(f"{where}.counter: expected a table, got {data['counter']!r}")
        if rng[0] >= 0.0:
            raise HeadProfileError(f"{where}.counter: a counter AU needs a negative range, range is {list(rng)}")
        counter = _action(data["counter"], f"{where}.counter", f"counter of AU{number}")
    note = data.get("note", "")
    if not isinstance(note, str):
        raise HeadProfileError(f"{where}.note: expected a string, got {note!r}")
    action = _action(data, where, f"AU{number}")
    for act, w in ((action, where), (counter, f"{where}.counter")):
        if act is None:
            continue
        for name, _ in act.muscles + act.joints:
            if "{side}" in name and not sided:
                raise HeadProfileError(f"{w}: {name!r} uses {{side}} but the AU is not sided")
    return AUEntry(number, source.strip(), sided, rng, action, counter, note)


def au_table_path(face_type_or_path: str | Path) -> Path:
    """The built-in table of a face type ("human", "dog") or the given file path."""
    if isinstance(face_type_or_path, str) and face_type_or_path in FACE_TYPES:
        return AU_DIR / f"{face_type_or_path}.toml"
    return Path(face_type_or_path)


def load_au_table(face_type_or_path: str | Path) -> AUTable:
    """Load and validate an AU table; errors (HeadProfileError) name the file and key path."""
    path = au_table_path(face_type_or_path)
    try:
        text = read_utf8(path, HeadProfileError, what="an AU table")
    except FileNotFoundError as err:
        raise HeadProfileError(f"{path}: AU table not found (built-in tables: {list(FACE_TYPES)})") from err
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise HeadProfileError(f"{path}: not valid TOML: {err}") from err
    where = str(path)
    if raw.get("schema_version") != 1:
        raise HeadProfileError(f"{where}: schema_version: expected 1, got {raw.get('schema_version')!r}")
    face_type = raw.get("face_type")
    if face_type not in FACE_TYPES:
        raise HeadProfileError(f"{where}: face_type: expected one of {list(FACE_TYPES)}, got {face_type!r}")
    intensity = _pair(raw.get("intensity"), f"{where}: intensity")
    contraction = _pair(raw.get("contraction"), f"{where}: contraction")
    entries: dict[int, AUEntry] = {}
    for key, data in raw.items():
        if key in {"schema_version", "face_type", "intensity", "contraction"}:
            continue
        match = _KEY_RE.match(key)
        if match is None:
            raise HeadProfileError(f"{where}: {key!r} is neither a header key nor an AU row like [AU12]")
        entries[int(match.group(1))] = _entry(int(match.group(1)), data, f"{where}: {key}", intensity)
    if not entries:
        raise HeadProfileError(f"{where}: the table has no AU rows")
    return AUTable(face_type, intensity, contraction, entries, path)


def with_vocabulary(table: AUTable, base: AUTable) -> AUTable:
    """``table`` plus an empty row for every AU of ``base`` it lacks (same face type): a head's own table
    need not list every AU of its face type; the AUs it leaves out validate as usual and move nothing."""
    if table.face_type != base.face_type:
        return table
    entries = dict(table.entries)
    for number, entry in base.entries.items():
        if number not in entries:
            entries[number] = AUEntry(
                number,
                entry.source,
                entry.sided,
                entry.range,
                AUAction(entry.action.name, (), ()),
                None,
                f"not in this head's AU table ({table.path.name})",
            )
    return AUTable(table.face_type, table.intensity, table.contraction, entries, table.path)
