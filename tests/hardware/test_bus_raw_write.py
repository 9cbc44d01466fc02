"""`_WindowedPort.writePort` writes pyserial's posix ``Serial`` with one ``os.write`` (`write_raw`): the same
bytes, return values and errors as pyserial's own ``write`` on a real pty — random packets (lists of ints and
bytes), a value that is no byte, a full kernel buffer (partial writes, EAGAIN), an OSError of the fd, the far
end closed, a port closed under the SDK. (A bus and a driver over a pty, raw and pyserial's alike, see the
same values and the same disconnect: tests/hardware/test_bus_fast_read.py.)"""

from __future__ import annotations

import errno
import os
import random
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from tests.hardware.pty_pair import PtyPort, pty_pair

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals need a POSIX system")


@pytest.fixture
def ptys() -> Iterator[tuple[PtyPort, PtyPort]]:
    yield from pty_pair()


def test_a_pyserial_port_is_written_raw(ptys: tuple[PtyPort, PtyPort]) -> None:
    assert ptys[1].port._raw_write and not ptys[0].port._raw_write


@pytest.mark.parametrize("seed", range(3))
def test_the_same_bytes_as_pyserial(ptys: tuple[PtyPort, PtyPort], seed: int) -> None:
    rng = random.Random(seed)
    for _ in range(60):
        values = [rng.randrange(256) for _ in range(rng.choice((10, 14, 44, 164, rng.randint(1, 1000))))]
        if rng.random() < 0.1:
            values[rng.randrange(len(values))] = rng.choice((256, -1, 1000))  # no byte: pyserial's ValueError
        packet: Any = bytes(values) if rng.random() < 0.3 and max(values) < 256 and min(values) >= 0 else values
        theirs, ours = ptys[0].write(packet), ptys[1].write(packet)
        assert ours == theirs
        if rng.random() < 0.3:
            assert ptys[1].drain() == ptys[0].drain()
    assert ptys[1].drain() == ptys[0].drain()


def test_a_full_buffer_waits_and_keeps_every_byte(ptys: tuple[PtyPort, PtyPort]) -> None:
    """More than the pty holds, the far end reading late: partial writes and EAGAIN, then the rest."""
    rng = random.Random(7)
    packets = [[rng.randrange(256) for _ in range(1000)] for _ in range(120)]  # ~120 KB
    for p in ptys:
        got: list[bytes] = []

        def reader(p: PtyPort = p, got: list[bytes] = got) -> None:
            time.sleep(0.1)
            got.append(p.drain(expect=sum(len(packet) for packet in packets)))

        t = threading.Thread(target=reader)
        t.start()
        results = [p.write(packet) for packet in packets]
        t.join()
        got.append(p.drain())
        assert results == [("ok", 1000)] * len(packets)
        assert b"".join(got) == b"".join(bytes(packet) for packet in packets)


@pytest.mark.parametrize("code", [errno.EIO, errno.EBADF, errno.EAGAIN, errno.EINTR])
def test_an_os_error_of_the_fd_is_pyserials(
    ptys: tuple[PtyPort, PtyPort], code: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """EIO (a USB adapter pulled), EBADF: pyserial's ``SerialException('write failed: ...')``; EAGAIN / EINTR
    once: retried, every byte written."""
    fds = {p.port.ser.fd for p in ptys}
    real_write: Callable[[int, Any], int] = os.write
    failed: set[int] = set()

    def failing(fd: int, data: Any) -> int:
        if fd in fds and (code not in (errno.EAGAIN, errno.EINTR) or fd not in failed):
            failed.add(fd)
            raise OSError(code, os.strerror(code))
        return real_write(fd, data)

    monkeypatch.setattr(os, "write", failing)
    theirs, ours = ptys[0].write([1, 2, 3, 4, 5]), ptys[1].write([1, 2, 3, 4, 5])
    monkeypatch.undo()
    assert ours == theirs
    if code in (errno.EAGAIN, errno.EINTR):
        assert ours == ("ok", 5) and ptys[1].drain() == ptys[0].drain() == b"\x01\x02\x03\x04\x05"
    else:
        assert ours[0] == "SerialException" and "write failed" in ours[1]


def test_the_far_end_closed_is_pyserials_error(ptys: tuple[PtyPort, PtyPort]) -> None:
    for p in ptys:
        os.close(p.master)
    for _ in range(2):
        theirs, ours = ptys[0].write([0xFF, 0xFF, 0xFD, 0]), ptys[1].write([0xFF, 0xFF, 0xFD, 0])
        assert ours == theirs


def test_a_port_closed_under_the_sdk_is_pyserials_error(ptys: tuple[PtyPort, PtyPort]) -> None:
    for p in ptys:
        p.port.ser.close()
    theirs, ours = ptys[0].write([1, 2]), ptys[1].write([1, 2])
    assert ours == theirs and ours[0] == "PortNotOpenError"


def test_a_reopened_port_is_written_raw_again(ptys: tuple[PtyPort, PtyPort]) -> None:
    port = ptys[1].port
    port.closePort()
    assert not port._raw_write
    assert port.openPort() and port._raw_write
    assert ptys[1].write([7, 8, 9]) == ("ok", 3) and ptys[1].drain() == b"\x07\x08\x09"
