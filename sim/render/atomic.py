"""Output files written all or nothing, so a render that fails partway leaves no truncated file behind.

A writer fills a hidden temporary next to the target (``.clip.mp4.partial-1a2b3c4d.mp4``): the same folder,
so the final rename stays on one file system and is atomic, and the same suffix, which is what Pillow and
ffmpeg choose the format and container by. Only when the writer finished is it renamed onto the target; on
any failure (a render error, the frame source raising, Ctrl-C) the temporary is removed and a file already
at the target is left as it was.
"""

from __future__ import annotations

import contextlib
import errno
import os
import secrets
import stat
from collections.abc import Iterator
from pathlib import Path

PARTIAL = ".partial-"
_NAME_BYTES = 96  # of the target's name kept in the temporary's (a name near the 255-byte limit still fits)


def _refuse(code: int, path: str | os.PathLike[str]) -> OSError:
    """The OSError ``open(path, "wb")`` would raise, naming the target (as the writers did before)."""
    return OSError(code, os.strerror(code), os.fspath(path))


def _partial_name(target: Path, suffix: str) -> str:
    """A fresh hidden temporary name for ``target``: its name, a random tag and ``suffix``."""
    name = os.fsdecode(os.fsencode(target.name)[:_NAME_BYTES])
    return f".{name}{PARTIAL}{secrets.token_hex(4)}{suffix}"


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
