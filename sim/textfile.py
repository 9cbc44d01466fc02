"""Reading the human-written text files of a head (profile, AU and direct tables, expression libraries,
scripts).

TOML is UTF-8. Editors that write a byte-order mark first (Notepad, some spreadsheet exports) are accepted;
a file in another encoding (Latin-1, Windows-1252) is refused naming the line and the byte, instead of a
codec message with a byte offset.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

_BOM = b"\xef\xbb\xbf"


def read_utf8(path: Path, error: Callable[[str], Exception]) -> str:
    """The text of a UTF-8 file (a leading byte-order mark dropped). Another encoding raises
    ``error("PATH: line N: ...")`` (the caller's own error type); OSError (a missing or unreadable file)
    propagates, for the caller to name in its own words."""
    raw = Path(path).read_bytes()
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        start = err.start + (len(_BOM) if raw.startswith(_BOM) else 0)
        line = raw[:start].count(b"\n") + 1
        raise error(
            f"{path}: line {line}: expected UTF-8 text, got byte 0x{raw[start]:02x}; save the file as UTF-8"
        ) from err
