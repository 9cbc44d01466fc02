"""An exclusive lock on a serial port, so two controllers never drive one chain.

A lock file per port (``servoface-<port path>.lock`` in ``$SERVOFACE_LOCK_DIR``, else ``/run/lock`` when
writable, else the temp folder) is held with ``flock`` for as long as the port is open and holds the
holder's pid and command line. The kernel drops a ``flock`` when its process dies — killed, crashed or out
of memory — so a stale file never blocks the next run. A second opener gets `PortLockedError` naming the
holder's pid. Works the same for a USB adapter and for the pty of ``servoface emulate``.
"""

from __future__ import annotations

import fcntl
import os
import sys
import tempfile
from pathlib import Path

from servoface.hardware.errors import PortLockedError


def lock_dir() -> Path:
    """Where lock files live (``SERVOFACE_LOCK_DIR`` overrides)."""
    env = os.environ.get("SERVOFACE_LOCK_DIR")
    if env:
        return Path(env)
    run_lock = Path("/run/lock")
    if run_lock.is_dir() and os.access(run_lock, os.W_OK):
        return run_lock
    return Path(tempfile.gettempdir())


def lock_path(port: str) -> Path:
    """The lock file of ``port`` (symlinks resolved, so /dev/serial/by-id/... and /dev/ttyUSB0 share one)."""
    real = os.path.realpath(port)
    name = real.strip("/").replace("/", "_") or "root"
    return lock_dir() / f"servoface-{name}.lock"


class PortLock:
    """``flock`` on the port's lock file; `acquire` raises `PortLockedError` if another process holds it."""

    def __init__(self, port: str) -> None:
        self.port = port
        self.path = lock_path(port)
        self._fd: int | None = None

    @property
    def held(self) -> bool:
        return self._fd is not None

    def acquire(self) -> None:
        if self._fd is not None:
            return
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _read_holder(fd)
            os.close(fd)
            raise PortLockedError(self.port, holder, self.path) from None
        except BaseException:
            os.close(fd)
            raise
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n{' '.join(sys.argv)[:200]}\n".encode(errors="replace"))
        self._fd = fd

    def release(self) -> None:
        fd, self._fd = self._fd, None
        if fd is None:
            return
        try:
            os.ftruncate(fd, 0)
            fcntl.flock(fd, fcntl.LOCK_UN)
        finally:
            os.close(fd)

    def __enter__(self) -> PortLock:
        self.acquire()
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def _read_holder(fd: int) -> int | None:
    try:
        text = os.pread(fd, 64, 0).decode(errors="replace")
        return int(text.split("\n", 1)[0])
    except (OSError, ValueError):
        return None
