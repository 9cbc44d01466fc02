"""Reading the human-written text files of a head (profile, AU and direct tables, expression libraries).

TOML is UTF-8. Editors that write a byte-order mark first (Notepad, some spreadsheet exports) are accepted;
a file in another encoding (Latin-1, Windows-1252) is refused naming the line and the byte, instead of a
codec message with a byte offset.
"""

from __future__ import annotations

from pathlib import Path

_BOM = b"\xef\xbb\xbf"


def undecodable(raw: bytes) -> str | None:
    """Why ``raw`` is not UTF-8 text (``"line N: ..."``), or None when it is (with or without a BOM)."""
    try:
        raw.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        start = err.start + (len(_BOM) if raw.startswith(_BOM) else 0)
        line = raw[:start].count(b"\n") + 1
        return f"line {line}: expected UTF-8 text, got byte 0x{raw[start]:02x}; save the file as UTF-8"
    return None


def read_utf8(path: Path) -> tuple[str | None, str]:
    """(text, "") for a UTF-8 file (a leading byte-order mark dropped), (None, why) for any other encoding.
    OSError (a missing or unreadable file) propagates: the caller names it in its own error type."""
    raw = Path(path).read_bytes()
    why = undecodable(raw)
    if why is not None:
        return None, why
    return raw.decode("utf-8-sig"), ""
