"""Expression libraries: named AU poses (human) and ordered AU events (dog), as TOML data files.

File format (``sim/expressions/human.toml``, ``dog.toml``; a head profile may ship its own). A ``source``
names where the recipe comes from; the built-ins cite the sheets in the repo's ``docs/reference/``::

    schema_version = 1
    face_type = "human"                 # AUs are validated against this face type's AU table

    [happiness]
    source = "facs-human.md §2a ..."    # required
    aus = { AU6 = 0.8, AU12 = 1.0 }     # a pose: all AUs together (human style)

    [anger]
    source = "dfacs-dog.md §3 ..."
    events = [["AU14", 0.6], ["AU4", 0.4], ["AU1", 1.0]]   # ordered (AU, signed intensity) events
    apex_after = 3                      # optional: the apex is the state after this many events (default all)
    note = "..."                        # optional

An event sets its AU to the value (a later event on the same AU replaces it); the controller does the
timing. ``Expression.apex()`` is the accumulated state after ``apex_after`` events, zeros dropped.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from servoface.sim.au.mapping import check_au
from servoface.sim.au.table import AUTable, load_au_table
from servoface.sim.errors import (
    ActionUnitValueError,
    ExpressionError,
    HeadProfileError,
    UnknownActionUnitError,
)
from servoface.sim.textfile import read_utf8

EXPRESSIONS_DIR = Path(__file__).resolve().parent
FACE_TYPES = ("human", "dog")


@dataclass(frozen=True)
class Expression:
    """A named expression: its ordered AU events, where it comes from, and its apex pose."""

    name: str
    face_type: str
    source: str
    events: tuple[tuple[str, float], ...]
    apex_after: int
    note: str = ""

    def apex(self) -> dict[str, float]:
        """The AU pose at the apex: each AU's value after the first ``apex_after`` events (zeros dropped)."""
        state: dict[str, float] = {}
        for name, value in self.events[: self.apex_after]:
            state[name] = value
        return {name: value for name, value in state.items() if value != 0.0}


class ExpressionLibrary(dict[str, Expression]):
    """{name: Expression}; looking up an unknown name raises ExpressionError listing the known names."""

    source_path: Path | None = None

    def __missing__(self, name: str) -> Expression:
        where = f" in {self.source_path}" if self.source_path else ""
        raise ExpressionError(f"expression {name!r} is not in the library{where}; known: {sorted(self)}")


def library_path(face_type_or_path: str | Path) -> Path:
    if isinstance(face_type_or_path, str) and face_type_or_path in FACE_TYPES:
        return EXPRESSIONS_DIR / f"{face_type_or_path}.toml"
    return Path(face_type_or_path)


def _events(data: Mapping[str, Any], where: str, table: AUTable) -> tuple[tuple[str, float], ...]:
    if ("aus" in data) == ("events" in data):
        raise ExpressionError(f"{where}: give exactly one of 'aus' (a pose) or 'events' (ordered AU events)")
    raw: list[tuple[object, object]]
    if "aus" in data:
        if not isinstance(data["aus"], Mapping):
            raise ExpressionError(f"{where}.aus: expected a table AU = intensity, got {data['aus']!r}")
        raw = list(data["aus"].items())
    else:
        if not isinstance(data["events"], list):
            raise ExpressionError(f"{where}.events: expected a list of [AU, intensity] pairs")
        raw = []
        for i, item in enumerate(data["events"]):
            if not isinstance(item, list) or len(item) != 2:
                raise ExpressionError(f"{where}.events[{i}]: expected [AU name, intensity], got {item!r}")
            raw.append((item[0], item[1]))
    out = []
    for i, (name, value) in enumerate(raw):
        try:
            number, side, x = check_au(table, name, value)
        except (UnknownActionUnitError, ActionUnitValueError) as err:
            raise ExpressionError(f"{where} (AU entry {i}): {err}") from err
        out.append((f"AU{number}{side}", x))
    return tuple(out)


def load_library(face_type_or_path: str | Path, au_table: AUTable | None = None) -> ExpressionLibrary:
    """Load an expression library: built-in ("human", "dog") or a TOML file path.

    Every AU is validated against ``au_table`` (default: the built-in table of the file's face type).
    """
    path = library_path(face_type_or_path)
    try:
        text = read_utf8(path, ExpressionError, what="an expression library")
    except FileNotFoundError as err:
        raise ExpressionError(f"{path}: expression library not found (built-in: {list(FACE_TYPES)})") from err
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ExpressionError(f"{path}: not valid TOML: {err}") from err
    if raw.get("schema_version") != 1:
        raise ExpressionError(f"{path}: schema_version: expected 1, got {raw.get('schema_version')!r}")
    face_type = raw.get("face_type")
    if face_type not in FACE_TYPES:
        raise ExpressionError(f"{path}: face_type: expected one of {list(FACE_TYPES)}, got {face_type!r}")
    try:
        table = au_table or load_au_table(face_type)
    except HeadProfileError as err:
        raise ExpressionError(f"{path}: cannot load the {face_type} AU table: {err}") from err
    library = ExpressionLibrary()
    library.source_path = path
    allowed = {"source", "aus", "events", "apex_after", "note"}
    for name, data in raw.items():
        if name in {"schema_version", "face_type"}:
            continue
        where = f"{path}: {name}"
        if not isinstance(data, Mapping):
            raise ExpressionError(f"{where}: expected a table, got {data!r}")
        unknown = sorted(set(data) - allowed)
        if unknown:
            raise ExpressionError(f"{where}: unknown key(s) {unknown}; allowed keys are {sorted(allowed)}")
        source = data.get("source")
        if not isinstance(source, str) or not source.strip():
            raise ExpressionError(f"{where}.source: every expression needs a source")
        events = _events(data, where, table)
        apex_after = data.get("apex_after", len(events))
        if isinstance(apex_after, bool) or not isinstance(apex_after, int) or not 0 <= apex_after <= len(events):
            raise ExpressionError(f"{where}.apex_after: expected an integer in 0..{len(events)}, got {apex_after!r}")
        note = data.get("note", "")
        if not isinstance(note, str):
            raise ExpressionError(f"{where}.note: expected a string, got {note!r}")
        library[name] = Expression(name, face_type, source.strip(), events, apex_after, note)
    return library


def get_expression(library: Mapping[str, Expression], name: str) -> Expression:
    """``library[name]`` with an ExpressionError listing the known names (for any mapping)."""
    try:
        return library[name]
    except KeyError:
        raise ExpressionError(f"expression {name!r} is not in the library; known: {sorted(library)}") from None
