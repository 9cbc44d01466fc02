"""The JSON objects of a recorded file, each with the line it starts on, however they were written:

* JSON lines (one object per line; servoface's own recordings);
* objects one after another, pretty-printed over many lines (``JSON.stringify(result, null, 4)`` appended
  per frame, as MediaPipe JS results are often dumped);
* one JSON array of objects (``json.dump(results, f, indent=2)``), or one object.

Blank lines and lines starting with ``#`` between objects are skipped. An object that does not parse is
yielded as a :class:`BadRow` naming its line and JSON's own line/column, and reading resumes at the next line
(so one torn line of a JSON-lines file costs one row). A broken array cannot be resumed: that is an
:class:`InputError` naming the line and column.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.tolerance import BadRow

_DECODER = json.JSONDecoder()
_SPACE = " \t\r\n"


def json_items(text: str, source: str) -> Iterator[tuple[int, Any | BadRow]]:
    """``(line, object)`` for every top-level object (or array element); ``(line, BadRow)`` for one that does
    not parse (see the module doc)."""
    pos = _skip(text, 0)
    if pos < len(text) and text[pos] == "[":
        yield from _array(text, pos, source)
        return
    lines = _Lines(text)
    while pos < len(text):
        line = lines.at(pos)
        try:
            obj, end = _DECODER.raw_decode(text, pos)
        except (ValueError, RecursionError) as err:
            yield line, BadRow(f"{source}: line {line}: not valid JSON: {_why(err)}", "lines that are not JSON")
            newline = text.find("\n", pos)
            pos = _skip(text, len(text) if newline < 0 else newline + 1)
            continue
        yield line, obj
        pos = _skip(text, end)


def _array(text: str, pos: int, source: str) -> Iterator[tuple[int, Any]]:
    lines = _Lines(text)
    pos = _skip(text, pos + 1, comments=False)
    if pos < len(text) and text[pos] == "]":
        pos += 1
    else:
        while True:
            line = lines.at(pos)
            try:
                obj, pos = _DECODER.raw_decode(text, pos)
            except (ValueError, RecursionError) as err:
                raise InputError(f"{source}: line {line}: not valid JSON in the array: {_why(err)}") from err
            yield line, obj
            pos = _skip(text, pos, comments=False)
            if text[pos : pos + 1] == ",":
                pos = _skip(text, pos + 1, comments=False)
                continue
            if text[pos : pos + 1] == "]":
                pos += 1
                break
            raise InputError(f"{source}: line {lines.at(pos)}: expected ',' or ']' between the array's objects")
    rest = _skip(text, pos)
    if rest < len(text):
        raise InputError(f"{source}: line {lines.at(rest)}: text after the JSON array's closing ']'")


def _skip(text: str, pos: int, *, comments: bool = True) -> int:
    """The next position that is not white space (nor, between top-level objects, a ``#`` comment line)."""
    while pos < len(text):
        if text[pos] in _SPACE:
            pos += 1
        elif comments and text[pos] == "#":
            newline = text.find("\n", pos)
            pos = len(text) if newline < 0 else newline + 1
        else:
            break
    return pos


def _why(err: Exception) -> str:
    if isinstance(err, json.JSONDecodeError):
        return f"{err.msg} (line {err.lineno}, column {err.colno})"
    return str(err)


class _Lines:
    """1-based line numbers of increasing positions, without rescanning the text."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.pos = 0
        self.line = 1

    def at(self, pos: int) -> int:
        if pos < self.pos:
            return self.text.count("\n", 0, pos) + 1
        self.line += self.text.count("\n", self.pos, pos)
        self.pos = pos
        return self.line
