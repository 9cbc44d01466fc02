"""Typed reading of a parsed TOML script with key paths in every error (used by servoface.controller.script).

Errors are :class:`servoface.controller.errors.ScriptError` with ``file``, ``key_path`` and (best effort) ``line``
attributes; the message reads ``<file>:<line>: <key.path>: <what was expected>``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from typing import Any, NoReturn

from servoface.controller.errors import ScriptError


def line_of(text: str, path: str) -> int | None:
    """Best-effort 1-based line of ``path`` (e.g. ``play[2].expression``) in the TOML ``text``."""
    if not text:
        return None
    parts = [p for p in re.split(r"\.(?![^\[]*\])", path) if p]
    lines = text.splitlines()
    lo, hi = 0, len(lines)
    for depth, part in enumerate(parts):
        name, _, idx = part.partition("[")
        header_path = ".".join(re.sub(r"\[\d+\]", "", p) for p in parts[: depth + 1])
        index = int(idx.rstrip("]")) if idx else None
        if index is not None:
            headers = [i for i in range(lo, hi) if re.match(rf"^\s*\[\[\s*{re.escape(header_path)}\s*\]\]", lines[i])]
            if index < len(headers):
                if depth == len(parts) - 1:
                    return headers[index] + 1
                lo = headers[index] + 1
                hi = next((i for i in range(lo, len(lines)) if re.match(r"^\s*\[", lines[i])), len(lines))
                continue
        header = next(
            (i for i in range(lo, hi) if re.match(rf"^\s*\[\s*{re.escape(header_path)}\s*\]", lines[i])), None
        )
        if header is not None and depth < len(parts) - 1:
            lo = header + 1
            hi = next((i for i in range(lo, len(lines)) if re.match(r"^\s*\[", lines[i])), len(lines))
            continue
        key_re = re.compile(rf"(^|[{{,\s]){re.escape(name)}\s*=")
        found = [i for i in range(lo, hi) if key_re.search(lines[i].split("#", 1)[0])]
        if found:
            lo, hi = found[0], found[0] + 1
            if depth == len(parts) - 1 or index is not None:
                return found[0] + 1
        elif header is not None:
            return header + 1
    return lo + 1 if hi - lo == 1 else None


class Reader:
    """Reads values out of a parsed script, raising ScriptError that names file, key path and line."""

    def __init__(self, source: str, text: str = "") -> None:
        self.source = source
        self.text = text

    def fail(self, path: str, message: str, cause: BaseException | None = None) -> NoReturn:
        line = line_of(self.text, path) if path else None
        where = f"{self.source}:{line}" if line else self.source
        err = ScriptError(f"{where}: {path + ': ' if path else ''}{message}")
        err.file, err.key_path, err.line = self.source, path, line  # type: ignore[attr-defined]
        raise err from cause

    def table(self, value: Any, path: str) -> Mapping[str, Any]:
        if not isinstance(value, Mapping):
            self.fail(path, f"expected a table, got {_kind(value)}")
        return value

    def keys(self, table: Mapping[str, Any], path: str, allowed: Sequence[str]) -> None:
        for key in table:
            if key not in allowed:
                self.fail(_join(path, key), f"unknown key; expected one of: {', '.join(allowed)}")

    def get(self, table: Mapping[str, Any], key: str, path: str, default: Any = ..., *, required: bool = False) -> Any:
        if key not in table:
            if required or default is ...:
                self.fail(_join(path, key), "missing; this key is required")
            return default
        return table[key]

    def number(
        self, table: Mapping[str, Any], key: str, path: str, default: Any = ..., *, lo: float = -math.inf,
        hi: float = math.inf, what: str = "a number",
    ) -> Any:  # fmt: skip
        value = self.get(table, key, path, default)
        if value is None and (key not in table or table[key] is not None):
            return None  # the default None: not given
        number = _finite(value)
        if number is None:
            self.fail(_join(path, key), f"expected {what}, got {shown(value)}")
        if not lo <= number <= hi:
            self.fail(_join(path, key), f"expected {what} in {lo:g}..{hi:g}, got {shown(value)}")
        return number

    def integer(
        self, table: Mapping[str, Any], key: str, path: str, default: Any = ..., *, lo: int = 0, hi: int = 2**31 - 1
    ) -> int:
        value = self.get(table, key, path, default)
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            self.fail(_join(path, key), f"expected an integer within {lo}..{hi}, got {shown(value)}")
        return value

    def string(self, table: Mapping[str, Any], key: str, path: str, default: Any = ...) -> str:
        value = self.get(table, key, path, default)
        if not isinstance(value, str):
            self.fail(_join(path, key), f"expected a string, got {_kind(value)} {shown(value)}")
        return value

    def array(self, table: Mapping[str, Any], key: str, path: str, default: Any = ...) -> list[Any]:
        value = self.get(table, key, path, default)
        if not isinstance(value, list):
            self.fail(_join(path, key), f"expected an array, got {_kind(value)}")
        return value


def _finite(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    try:
        number = float(value)
    except OverflowError:
        return None
    return number if math.isfinite(number) else None


def shown(value: Any, limit: int = 60) -> str:
    """A short repr for messages (never raises: deep nesting, huge integers; escapes control characters)."""
    try:
        text = repr(value)
    except (RecursionError, ValueError):
        text = f"<{type(value).__name__} nested too deeply>"
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def _kind(value: Any) -> str:
    return {dict: "a table", list: "an array", str: "a string", bool: "a boolean"}.get(
        type(value), type(value).__name__
    )
