"""Authoring: the TOML scripts `servoface play` reads, as documents the browser edits.

A *document* is the script's TOML as a JSON object, key for key; saving writes it back with ``tomli_w``,
so load -> save -> load is lossless (the same document; only comments are dropped, and saving the TOML
text instead keeps even those). Everything is validated by the one script parser
(:func:`servoface.controller.script.parse_script`) before it is written or played, and its errors (file,
key path, line) become a 422 naming ``document.<key path>``. Files live in one folder (``--scripts-dir``)
under bare names: the browser never names a path."""

from __future__ import annotations

import math
import os
import re
import tempfile
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from servoface.controller.errors import ControllerError, ScriptError
from servoface.controller.script import Script, parse_script
from servoface.controller.studio.errors import InvalidValueError, NotFoundError
from servoface.sim.textfile import read_bounded

NAME_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,95}\.toml$")
STEM_RE = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]{0,95}$")  # a name to read: the .toml may be left off
MAX_SAMPLES = 5000
MAX_DEPTH = 32


def check_name(name: object, *, field: str = "name") -> str:
    if not isinstance(name, str) or not NAME_RE.fullmatch(name) or ".." in name:
        raise InvalidValueError(
            f"{field}: expected a bare file name like 'smile.toml' ([A-Za-z0-9_.-]), got {name!r}", field=field
        )
    return name


def _check_tree(value: Any, path: str, depth: int = 0) -> None:
    """Only what TOML can hold: tables with string keys, arrays, strings, finite numbers, booleans."""
    if depth > MAX_DEPTH:
        raise InvalidValueError(f"{path}: nested too deeply", field=path)
    if isinstance(value, Mapping):
        for key, item in value.items():
            if not isinstance(key, str) or not key:
                raise InvalidValueError(f"{path}: keys must be non-empty strings", field=path)
            _check_tree(item, f"{path}.{key}", depth + 1)
    elif isinstance(value, list):
        for i, item in enumerate(value):
            _check_tree(item, f"{path}[{i}]", depth + 1)
    elif value is None:
        raise InvalidValueError(f"{path}: null has no TOML form; leave the key out", field=path)
    elif isinstance(value, float) and not math.isfinite(value):
        raise InvalidValueError(f"{path}: expected a finite number", field=path)
    elif not isinstance(value, str | int | float | bool):
        raise InvalidValueError(f"{path}: {type(value).__name__} has no TOML form", field=path)


def document_to_toml(document: Mapping[str, Any]) -> str:
    import tomli_w

    _check_tree(document, "document")
    try:
        return tomli_w.dumps(dict(document))
    except (TypeError, ValueError) as err:
        raise InvalidValueError(f"document: cannot be written as TOML: {err}", field="document") from err


def toml_to_document(text: str, *, source: str = "<script>") -> dict[str, Any]:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise InvalidValueError(f"toml: {source}: TOML syntax error: {err}", field="toml") from err
    except RecursionError as err:
        raise InvalidValueError(f"toml: {source}: nested too deeply", field="toml") from err
    _check_tree(data, "document")  # dates and times: TOML has them, scripts do not
    return data


def build(text: str, *, source: str, allowed: frozenset[str] | None, field: str = "document") -> Script:
    """The script of ``text``, or InvalidValueError naming ``field.<key path>``."""
    try:
        return parse_script(text, source=source, allowed=allowed)
    except ScriptError as err:
        key = getattr(err, "key_path", "") or ""
        raise InvalidValueError(str(err), field=f"{field}.{key}" if key else field) from err
    except (ControllerError, RecursionError, ValueError, TypeError, OverflowError) as err:
        raise InvalidValueError(f"{field}: {err}", field=field) from err


def text_of(document: Mapping[str, Any] | None, toml: str | None) -> tuple[str, str]:
    """(TOML text, field name) from exactly one of ``document`` / ``toml``."""
    if (document is None) == (toml is None):
        raise InvalidValueError("give exactly one of 'document' (an object) or 'toml' (text)", field="document")
    if toml is not None:
        toml_to_document(toml)  # syntax first, with its own field name
        return toml, "toml"
    return document_to_toml(document or {}), "document"


def summary(script: Script, document: Mapping[str, Any]) -> dict[str, Any]:
    plays = document.get("play", [])
    tracks = (
        sorted({str(p.get("track", "face")) for p in plays if isinstance(p, Mapping)})
        if isinstance(plays, list)
        else []
    )
    exprs = document.get("expressions", {})
    return {
        "face": script.face_type,
        "title": script.title,
        "end_s": round(float(script.end_s), 6),
        "tracks": tracks,
        "expressions": sorted(exprs) if isinstance(exprs, Mapping) else [],
    }


def sample(script: Script, fps: float) -> dict[str, Any]:
    end = float(script.end_s)
    n = min(MAX_SAMPLES, int(math.floor(end * fps + 1e-9)) + 1)
    frames = []
    for i in range(n):
        t = i / fps
        aus = script.timeline.sample_aus(t)
        frames.append({"t_s": round(t, 6), "aus": {k: round(float(v), 4) for k, v in aus.items() if abs(v) > 1e-6}})
    return {"fps": fps, "end_s": round(end, 6), "frames": frames}


class ScriptFolder:
    """The folder the studio reads and writes scripts in; shipped scripts are readable by name."""

    def __init__(self, folder: Path, allowed: frozenset[str] | None) -> None:
        self.folder = Path(folder)
        self.allowed = allowed

    def names(self) -> list[str]:
        if not self.folder.is_dir():
            return []
        return sorted(p.name for p in self.folder.glob("*.toml") if p.is_file() and NAME_RE.fullmatch(p.name))

    def path_of(self, name: str, *, must_exist: bool = True) -> Path:
        """The file ``name`` means: ``smile.toml`` in the folder; for reading also a shipped script as
        everywhere else (:mod:`servoface.controller.shipped`): ``human_performance``,
        ``human_performance.toml`` or ``script:human_performance`` -- the folder's own copy first, except
        with the ``script:`` prefix, which always means the shipped one."""
        if not must_exist:
            return self.folder / check_name(name)
        from servoface.controller.shipped import SCRIPT_PREFIX, shipped_scripts

        prefixed = isinstance(name, str) and name.startswith(SCRIPT_PREFIX)
        spec = name[len(SCRIPT_PREFIX) :] if prefixed else name
        if not isinstance(spec, str) or not STEM_RE.fullmatch(spec) or ".." in spec:
            raise InvalidValueError(
                f"name: expected a bare file name like 'smile.toml' or a shipped script name like "
                f"'human_performance' ([A-Za-z0-9_.-]), got {name!r}",
                field="name",
            )
        stem = spec[: -len(".toml")] if spec.endswith(".toml") else spec
        if not prefixed:
            own = self.folder / f"{stem}.toml"
            if own.is_file():
                return own
        shipped = shipped_scripts()
        if stem in shipped:
            return Path(shipped[stem])
        raise NotFoundError(
            f"no script {name!r} in {self.folder} (nor a shipped one; shipped: {sorted(shipped)})", field="name"
        )

    def load(self, name: str) -> dict[str, Any]:
        p = self.path_of(name)

        def refuse(reason: str) -> InvalidValueError:
            return InvalidValueError(f"name: cannot read {p.name}: {reason}", field="name")

        try:
            text = read_bounded(p, refuse, what="a script file").decode("utf-8")
        except (OSError, UnicodeDecodeError) as err:
            raise InvalidValueError(f"name: cannot read {p.name}: {err}", field="name") from err
        document = toml_to_document(text, source=p.name)
        script = build(text, source=p.name, allowed=self.allowed, field="document")
        return {"name": name, "toml": text, "document": document, "summary": summary(script, document)}

    def save(self, name: str, text: str, field: str) -> dict[str, Any]:
        check_name(name)
        script = build(text, source=name, allowed=self.allowed, field=field)
        self.folder.mkdir(parents=True, exist_ok=True)
        p = self.path_of(name, must_exist=False)
        fd, tmp = tempfile.mkstemp(prefix=".studio-", suffix=".toml", dir=self.folder)
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(text)
            os.chmod(tmp, 0o644)  # as a file written in place (mkstemp makes it 0600)
            os.replace(tmp, p)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        return {"name": name, "path": str(p.resolve()), "summary": summary(script, tomllib.loads(text))}
