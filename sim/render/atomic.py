"""Output files written all or nothing, so a render that fails partway leaves no truncated file behind.

A writer fills a hidden temporary next to the target (``.clip.mp4.partial-4711-1a2b3c4d.mp4``: the writing
process's id and a random tag): the same folder, so the final rename stays on one file system and is
atomic, and the same suffix, which is what Pillow and ffmpeg choose the format and container by. Only when
the writer finished is it renamed onto the target; on any failure (a render error, the frame source raising,
Ctrl-C) the temporary is removed and a file already at the target is left as it was.

A process killed outright (SIGKILL, a power cut) cannot remove its temporary. The next write to the same
target removes such leftovers: temporaries of that target whose process no longer runs on this machine and
that nothing has written to for `STALE_S` (a live writer on another machine sharing the folder keeps its
file fresh).
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import secrets
import stat
import time
from collections.abc import Iterator
from pathlib import Path

PARTIAL = ".partial-"
STALE_S = 60.0  # a leftover temporary untouched this long, of a process that is gone, is removed
_NAME_BYTES = 96  # of the target's name kept in the temporary's (a name near the 255-byte limit still fits)


def _refuse(code: int, path: str | os.PathLike[str]) -> OSError:
    """The OSError ``open(path, "wb")`` would raise, naming the target (as the writers did before)."""
    return OSError(code, os.strerror(code), os.fspath(path))


def _partial_stem(target: Path) -> str:
    """What every temporary of ``target`` starts with: a dot and (the start of) its name, then `PARTIAL`."""
    return f".{os.fsdecode(os.fsencode(target.name)[:_NAME_BYTES])}{PARTIAL}"


def _partial_name(target: Path, suffix: str) -> str:
    """A fresh hidden temporary name for ``target``: its name, this process's id, a random tag, ``suffix``."""
    return f"{_partial_stem(target)}{os.getpid()}-{secrets.token_hex(4)}{suffix}"


_TAG = re.compile(r"([1-9][0-9]{0,9})-[0-9a-f]{8}(\.[^/]*)?")  # what follows the stem: pid, tag, suffix
_MAX_PID = 2**31 - 1  # a larger number is no process id: not a temporary of ours


def _gone(pid: int) -> bool:
    """Whether no process ``pid`` runs on this machine (one of another user still counts as running; a
    number no process can have is not ours to judge: False)."""
    if pid > _MAX_PID:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except (OSError, OverflowError):  # EPERM: it runs, as someone else
        return False
    return False


def remove_leftovers(target: Path, now_s: float | None = None) -> list[Path]:
    """Remove the temporaries an earlier writer of ``target`` left when it was killed (see the module
    docstring); returns those removed. Only files named like ours, of a process that is gone, untouched
    for `STALE_S`; anything that cannot be read or removed is left alone."""
    stem = _partial_stem(target)
    now = time.time() if now_s is None else now_s
    removed: list[Path] = []
    try:
        names = [n for n in os.listdir(target.parent) if n.startswith(stem)]
    except OSError:
        return removed
    for name in names:
        found = _TAG.fullmatch(name[len(stem) :])
        if found is None or int(found.group(1)) == os.getpid() or not _gone(int(found.group(1))):
            continue
        leftover = target.parent / name
        try:
            st = os.lstat(leftover)
            if stat.S_ISREG(st.st_mode) and now - st.st_mtime >= STALE_S:
                os.unlink(leftover)
                removed.append(leftover)
        except OSError:
            continue
    return removed


def _reserve(target: Path, shown: str | os.PathLike[str]) -> Path:
    """Create an empty temporary next to ``target``, exclusively (so it is ours), with what the umask makes
    of 0o666, as ``open`` would (mkstemp's 0o600 would hide the result from others). Its suffix is the one
    of the name given: a symlink ``clip.mp4`` may point at a file without one."""
    suffix = Path(shown).suffix
    for _ in range(100):
        tmp = target.with_name(_partial_name(target, suffix))
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0), 0o666)
        except FileExistsError:
            continue
        except OSError as err:  # no such folder, not writable: name the target, as open(target) would
            raise _refuse(err.errno or errno.EIO, shown) from err
        os.close(fd)
        return tmp
    raise _refuse(errno.EEXIST, shown)  # 100 random names taken: something is badly wrong with the folder


def _flush(path: Path) -> None:
    """Get the file's data onto the disk before it is renamed into place (no empty file after a crash)."""
    fd = os.open(path, os.O_RDWR)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield the path to write to instead of ``path``; it becomes ``path`` when the block completes.

    A symlink is followed (the file it points at is replaced, as writing through it would). A folder, or an
    existing file that may not be written, is refused before any work, with the OSError ``open`` would
    raise. Something that is not a regular file (a FIFO, a device) cannot be replaced: it is written
    directly. On any exception, ``BaseException`` included, the temporary is removed and the error re-raised.
    """
    target = Path(os.path.realpath(path))
    try:
        mode = os.stat(target).st_mode
    except FileNotFoundError:
        mode = None
    except OSError as err:
        raise _refuse(err.errno or errno.EIO, path) from err
    if mode is not None:
        if stat.S_ISDIR(mode):
            raise _refuse(errno.EISDIR, path)
        if not os.access(target, os.W_OK):
            raise _refuse(errno.EACCES, path)
        if not stat.S_ISREG(mode):
            yield target
            return
    remove_leftovers(target)
    tmp = _reserve(target, path)
    try:
        yield tmp
        _flush(tmp)
        if mode is not None:  # a replaced file keeps its permissions, as writing into it would have
            os.chmod(tmp, stat.S_IMODE(mode))
        os.replace(tmp, target)
    except BaseException as err:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(err, OSError):
            _name_target(err, tmp, path)
        raise


def _name_target(err: OSError, tmp: Path, path: str | os.PathLike[str]) -> None:
    """An OSError of the write (a full disk: ``[Errno 28] No space left on device``) names the file the user
    asked for, not the hidden temporary, and not nothing (Pillow's and the encoders' name no file)."""
    if err.errno is None or err.strerror is None:
        return  # an OSError with a message of its own: str() would not show a file name as asked
    if err.filename is None or os.fspath(err.filename) == os.fspath(tmp):
        err.filename = os.fspath(path)
