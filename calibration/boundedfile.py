"""Reading a user-named file with a size limit: a directory, a device (``/dev/zero``), a FIFO where none is
expected or a multi-GB file is refused with a message, never read into memory or waited on for ever.

Limits, each far beyond any real file of its kind:

- ``TEXT_LIMIT_BYTES`` = 16 MiB: human-written TOML (head profiles, AU and direct tables, expression
  libraries, scripts, blendshape tables), calibration JSON, measurement CSV, transcripts;
- ``SMALL_LIMIT_BYTES`` = 1 MiB: a users file or a PEM certificate / key;
- ``MESH_LIMIT_BYTES`` = 256 MiB: a mesh a head profile names (STL/OBJ/PLY/GLB/glTF/OFF) and the files it
  names in turn (an OBJ's material library and textures, a glTF's buffers);
- ``AUDIO_LIMIT_BYTES`` = 512 MiB: a WAV recording (ten minutes of 96 kHz stereo 32-bit PCM is 460 MB).

It lives in ``calibration`` (a leaf package) so that ``sim`` and ``controller``, which may import it, share
this one copy; ``sim.textfile.read_utf8``, the mesh loader (``sim.heads.meshes``) and
``controller.speech.audio.read_wav`` build on it.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Callable

TEXT_LIMIT_BYTES = 16 * 2**20
SMALL_LIMIT_BYTES = 2**20
MESH_LIMIT_BYTES = 256 * 2**20
AUDIO_LIMIT_BYTES = 512 * 2**20

_CHUNK_BYTES = 1 << 20


def describe_size(n_bytes: int) -> str:
    """``2.1 GiB``, ``16 MiB``, ``12 KiB``, ``300 bytes``: a size for a message."""
    for unit, scale in (("GiB", 2**30), ("MiB", 2**20)):
        if n_bytes >= scale:
            return f"{n_bytes / scale:.1f}".removesuffix(".0") + f" {unit}"
    return f"{n_bytes // 1024} KiB" if n_bytes >= 1024 else f"{n_bytes} bytes"


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISFIFO(mode):
        return "a pipe (FIFO)"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def read_bounded(
    path: str | os.PathLike[str],
    refuse: Callable[[str], Exception],
    *,
    what: str,
    limit_bytes: int = TEXT_LIMIT_BYTES,
    allow_stream: bool = False,
) -> bytes:
    """The bytes of the file at ``path`` (symlinks followed), at most ``limit_bytes`` of them.

    Refused with ``raise refuse(reason)`` (the caller's own error type; ``reason`` does not name the path, the
    caller puts it where its messages put it), e.g. ``"2.1 GiB; a script file is at most 16 MiB"`` or ``"a
    device, not a regular file; expected a script file"``:

    - a path that is not a regular file, before it is opened (``allow_stream=True`` lets a FIFO, a socket or
      a terminal through, read up to the limit: ``--input /dev/stdin`` piped, redirected or typed; a directory
      never, nor a device that is not a terminal: ``/dev/zero`` would only fill the limit with zeros);
    - a file whose size is over the limit, before a byte is read;
    - a file that grows underneath or a stream that runs past the limit: at most ``limit_bytes + 1`` bytes
      are read.

    ``what`` names the kind of file with its article (``"a script file"``). OSError (missing, unreadable)
    propagates, for the caller to word as it already does.
    """
    info = os.stat(path)
    _check(info, refuse, what, limit_bytes, allow_stream)
    # A regular file is opened with O_NONBLOCK: a FIFO swapped in after the stat opens at once (and is refused
    # below) instead of blocking. A stream the caller allowed is opened as `cat` would: waiting for a writer.
    regular = stat.S_ISREG(info.st_mode)
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_BINARY", 0) | (getattr(os, "O_NONBLOCK", 0) if regular else 0))
    with os.fdopen(fd, "rb", buffering=0) as fh:
        info = os.fstat(fd)
        _check(info, refuse, what, limit_bytes, allow_stream)
        if (stat.S_ISCHR(info.st_mode) and not os.isatty(fd)) or stat.S_ISBLK(info.st_mode):
            raise refuse(f"a device, not a regular file, a pipe or a terminal; expected {what}")
        if regular and not stat.S_ISREG(info.st_mode) and hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)  # swapped for a stream the caller allows: read it blocking
        chunks: list[bytes] = []
        total = 0
        while total <= limit_bytes:
            chunk = fh.read(min(_CHUNK_BYTES, limit_bytes + 1 - total))
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
    if total > limit_bytes:
        limit = describe_size(limit_bytes)
        raise refuse(f"more than {limit} and not at its end; {what} is at most {limit}")
    return b"".join(chunks)


def _check(info: os.stat_result, refuse: Callable[[str], Exception], what: str, limit: int, stream: bool) -> None:
    mode = info.st_mode
    if not stat.S_ISREG(mode) and (stat.S_ISDIR(mode) or not stream):
        raise refuse(f"{_kind(mode)}, not a regular file; expected {what}")
    if stat.S_ISREG(mode) and info.st_size > limit:
        size, most = describe_size(info.st_size), describe_size(limit)
        raise refuse(f"{size if size != most else f'{info.st_size} bytes'}; {what} is at most {most}")
