"""Check an output file or folder before the work that fills it, so a bad path fails in a second with a
message (not a traceback after a minute of rendering)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path


def writable_folder(folder: Path) -> Path:
    """Create ``folder`` (and its parents) and prove a file can be written there; OSError if not."""
    folder.mkdir(parents=True, exist_ok=True)
    try:
        fd, probe = tempfile.mkstemp(prefix=".servoface-probe-", dir=folder)
    except OSError as err:
        raise type(err)(err.errno, f"{err.strerror or err} (cannot write in this folder)", str(folder)) from err
    os.close(fd)
    os.unlink(probe)
    return folder


def writable_file(path: Path) -> Path:
    """Check that ``path`` can be written (its folder exists and takes a file, it is not a folder)."""
    if path.is_dir():
        raise IsADirectoryError(21, "is a folder, expected a file name", str(path))
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise FileNotFoundError(2, f"folder {str(folder)!r} does not exist", str(path))
    writable_folder(folder)
    return path
