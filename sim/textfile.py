"""Reading the human-written text files of a head (profile, AU and direct tables, expression libraries,
scripts).

TOML is UTF-8. Editors that write a byte-order mark first (Notepad, some spreadsheet exports) are accepted;
a file in another encoding (Latin-1, Windows-1252) is refused naming the line and the byte, instead of a
codec message with a byte offset. A path that is not a regular file (a directory, ``/dev/zero``, a FIFO) or
a file over 16 MiB (``TEXT_LIMIT_BYTES``, far beyond any real one) is refused before it is read
(:mod:`servoface.calibration.boundedfile`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from servoface.calibration.boundedfile import SMALL_LIMIT_BYTES, TEXT_LIMIT_BYTES, read_bounded

__all__ = ["SMALL_LIMIT_BYTES", "TEXT_LIMIT_BYTES", "read_bounded", "read_utf8"]

_BOM = b"\xef\xbb\xbf"


def read_utf8(path: Path, error: Callable[[str], Exception], *, what: str, limit_bytes: int = TEXT_LIMIT_BYTES) -> str:
    """The text of a UTF-8 file (a leading byte-order mark dropped). Another encoding raises
    ``error("PATH: line N: ...")`` (the caller's own error type); so does a path that is not a regular file or
    a file over ``limit_bytes`` (``error("PATH: 2.1 GiB; a script file is at most 16 MiB")``, ``what`` being
    ``"a script file"``). OSError (a missing or unreadable file) propagates, for the caller to name in its
    own words."""
    raw = read_bounded(path, lambda reason: error(f"{path}: {reason}"), what=what, limit_bytes=limit_bytes)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        start = err.start + (len(_BOM) if raw.startswith(_BOM) else 0)
        line = raw[:start].count(b"\n") + 1
        raise error(
            f"{path}: line {line}: expected UTF-8 text, got byte 0x{raw[start]:02x}; save the file as UTF-8"
        ) from err
