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


def folder_could_be_made(folder: Path) -> None:
    """Check, making nothing, that ``folder`` could be made (if missing) and written: the nearest part of
    its path that exists must be a folder this process may write in and search. NotADirectoryError or
    PermissionError naming that part; the later write still reports its own failure (``os.access``
    cannot see everything, e.g. as root)."""
    existing = folder
    while not os.path.lexists(existing) and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        why = "not a folder" if existing == folder else f"{str(existing)!r} is not a folder"
        raise NotADirectoryError(20, f"{why}; expected an output folder (made if missing)", str(existing))
    if not os.access(existing, os.W_OK | os.X_OK):
        raise PermissionError(13, f"cannot write in {str(existing)!r} (permission denied)", str(existing))
