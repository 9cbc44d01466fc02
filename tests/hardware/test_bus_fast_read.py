"""`_WindowedPort` reads pyserial's posix ``Serial`` with one ``os.read`` on its fd (no ``select`` first): the
same bytes and the same errors as pyserial's own ``read`` on a real pty — data in random chunks, nothing
waiting, the far end closed, an OSError of the fd (EIO), EAGAIN, a port closed under the SDK — and a bus and a
driver over a pty see the same values, and the same disconnect (error, message, fault reaction), either way."""

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
from servoface.hardware.bus import open_bus
from servoface.hardware.driver import Driver
from servoface.hardware.dynamixel_bus import DynamixelBus, TableCrcPacketHandler, sdk
from servoface.hardware.emulator import ServoChain
from servoface.hardware.registers import Register
from servoface.hardware.servo_config import ServoSpec

from tests.hardware.pty_pair import PtyPort, pty_pair

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals need a POSIX system")


@pytest.fixture
def ptys() -> Iterator[tuple[PtyPort, PtyPort]]:
    yield from pty_pair()


def test_a_pyserial_port_is_read_raw(ptys: tuple[PtyPort, PtyPort]) -> None:
    """The point of it (and that the reference really is pyserial's read and write)."""
    assert ptys[1].port._raw_read and not ptys[0].port._raw_read
    assert ptys[1].port._raw_write and not ptys[0].port._raw_write


@pytest.mark.parametrize("seed", range(3))
def test_the_same_bytes_as_pyserial(ptys: tuple[PtyPort, PtyPort], seed: int) -> None:
    rng = random.Random(seed)
    for _ in range(150):
        if rng.random() < 0.7:
            data = bytes(rng.randrange(256) for _ in range(rng.choice((1, 2, 11, 15, rng.randint(1, 600)))))
            for p in ptys:
                p.feed(data)
        size = rng.choice((1, 4, 11, 4096, rng.randint(1, 700)))
        theirs, ours = ptys[0].read(size), ptys[1].read(size)
        assert ours == theirs
    while (theirs := ptys[0].read(4096)) != ("ok", b""):
        assert ptys[1].read(4096) == theirs
    assert ptys[1].read(4096) == ("ok", b"")


@pytest.mark.parametrize("pending", [b"", b"\xff\xff\xfd\x00\x01"])
def test_the_far_end_closed_is_pyserials_error(ptys: tuple[PtyPort, PtyPort], pending: bytes) -> None:
    for p in ptys:
        if pending:
            p.feed(pending)
        os.close(p.master)
    for _ in range(3):  # whatever was waiting first (if the pty kept it), then the same error every time
        theirs, ours = ptys[0].read(4096), ptys[1].read(4096)
        assert ours == theirs
    assert ours[0] == "SerialException"


def test_a_port_closed_under_the_sdk_is_pyserials_error(ptys: tuple[PtyPort, PtyPort]) -> None:
    for p in ptys:
        p.port.ser.close()
    theirs, ours = ptys[0].read(11), ptys[1].read(11)
    assert ours == theirs and ours[0] == "PortNotOpenError"


@pytest.mark.parametrize("code", [errno.EIO, errno.EBADF, errno.EAGAIN, errno.EINTR])
def test_an_os_error_of_the_fd_is_pyserials(
    ptys: tuple[PtyPort, PtyPort], code: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """EIO (a USB adapter pulled), EBADF: pyserial's ``SerialException('read failed: ...')``; EAGAIN / EINTR:
    nothing read. Both read through the same ``os.read``, failing for the ptys' fds."""
    for p in ptys:
        p.feed(b"\x01\x02\x03")  # readable: pyserial's select lets it through to its os.read
    fds = {p.port.ser.fd for p in ptys}
    real_read: Callable[[int, int], bytes] = os.read

    def failing(fd: int, n: int) -> bytes:
        if fd in fds:
            raise OSError(code, os.strerror(code))
        return real_read(fd, n)

    monkeypatch.setattr(os, "read", failing)
    theirs, ours = ptys[0].read(11), ptys[1].read(11)
    monkeypatch.undo()
    assert ours == theirs
    assert ours == (("ok", b"") if code in (errno.EAGAIN, errno.EINTR) else ("SerialException", ours[1]))


def test_a_reopened_port_is_read_raw_again(ptys: tuple[PtyPort, PtyPort]) -> None:
    port = ptys[1].port
    port.closePort()
    assert not port._raw_read
    assert port.openPort() and port._raw_read
    ptys[1].feed(b"abc")
    assert ptys[1].read(10) == ("ok", b"abc")


# -- a bus and a driver over a pty (the emulator served in-process), raw read and pyserial's alike ----------
IDS = [1, 2, 3, 4]


def _bus_on_pty(raw: bool) -> tuple[ServoChain, DynamixelBus]:
    chain = ServoChain.create(ids=IDS, model="XL330-M288", baud=1_000_000, wire_time=True)
    bus = open_bus("dynamixel", port=chain.serve_pty(), baud=1_000_000, warn_latency=False)
    assert isinstance(bus, DynamixelBus)
    assert bus._port._raw_read and bus._port._raw_write
    if not raw:
        bus._port._raw_read = bus._port._raw_write = False  # pyserial's own read and write
    return chain, bus


@pytest.mark.parametrize("fast", [False, True])
def test_a_bus_reads_the_same_values(fast: bool) -> None:
    got = []
    for raw in (False, True):
        chain, bus = _bus_on_pty(raw)
        try:
            rng = random.Random(5)
            out = []
            for _ in range(20):
                bus.sync_write(Register.GOAL_POSITION, {sid: rng.randint(0, 4095) for sid in IDS})
                out.append(bus.sync_read(IDS, (Register.TORQUE_ENABLE, Register.PRESENT_POSITION), fast=fast))
                out.append(bus.read_many(IDS[rng.randrange(len(IDS))], (Register.MODEL_NUMBER, Register.ID)))
            out.append(bus.ping(2))
            got.append(out)
        finally:
            bus.close()
            chain.close()
    assert got[0] == got[1]


def _outcome(fn: Callable[[], Any], port_name: str) -> tuple[str, str, Any]:
    try:
        return "ok", "", fn()
    except Exception as err:
        return type(err).__name__, str(err).replace(port_name, "PORT"), None


def _disconnect(raw: bool, stage: str) -> list[tuple[str, str, Any]]:
    """What a bus, or a driver, sees when the emulator's pty goes away (the emulator process gone: its pty
    master closed) before the sync read, or while its replies are on the wire (between the two halves)."""
    chain, bus = _bus_on_pty(raw)
    seen = []
    try:
        if stage == "driver":
            driver = Driver(bus, [ServoSpec(sid, "XL330-M288") for sid in IDS])
            driver.configure()
            driver.torque_on()
            goals = {sid: 2048 for sid in IDS}
            driver.cycle(goals)
            chain.close()

            def cycle() -> Any:
                snap = driver.cycle(goals)
                return snap.bus_connected, [s.missing for s in snap], sorted({e.kind.name for e in driver.events})

            seen += [_outcome(cycle, bus.port_name) for _ in range(3)]
        else:
            bus.sync_read(IDS, (Register.PRESENT_POSITION,))
            if stage == "before":
                chain.close()
                seen.append(_outcome(lambda: bus.sync_read(IDS, (Register.PRESENT_POSITION,)), bus.port_name))
            else:
                bus.sync_read_start(IDS, (Register.PRESENT_POSITION,))
                chain.close()
                seen.append(_outcome(bus.sync_read_finish, bus.port_name))
            seen.append(_outcome(lambda: bus.read(1, Register.ID), bus.port_name))
    finally:
        bus.close()
        chain.close()
    return seen


@pytest.mark.parametrize("stage", ["before", "during", "driver"])
def test_a_vanished_pty_is_the_same_disconnect(stage: str) -> None:
    theirs, ours = _disconnect(False, stage), _disconnect(True, stage)
    assert ours == theirs


def _later(p: PtyPort, data: bytes, after_s: float) -> threading.Thread:
    t = threading.Thread(target=lambda: (time.sleep(after_s), os.write(p.master, data)))
    t.start()
    return t


def test_bytes_that_come_during_the_wait_are_the_next_reads(ptys: tuple[PtyPort, PtyPort]) -> None:
    """An empty read waits (until the reply window ends) and wakes when bytes come: it returns nothing, as
    pyserial's read before the wait did, and the next read gets them — the SDK checks its window in between."""
    reads: list[list[bytes]] = []
    for p in ptys:
        p.port.setPacketTimeoutMillis(5000.0)
        t = _later(p, b"\xff\xff\xfd\x00\x07", 0.02)
        got = [p.port.readPort(11)]
        while not got[-1]:
            got.append(p.port.readPort(11))
        t.join()
        reads.append(got)
    theirs, ours = reads
    assert ours == [b"", b"\xff\xff\xfd\x00\x07"]  # one wait, woken by the bytes
    assert theirs[-1] == ours[-1] and not any(theirs[:-1])


@pytest.mark.parametrize("arrives", [None, b"\xff\xff\xfd\x00\x01\x03\x00\x55\x00"])
def test_the_sdk_reply_window_ends_as_before(ptys: tuple[PtyPort, PtyPort], arrives: bytes | None) -> None:
    """The SDK's rxPacket on either port: nothing (timeout) or a truncated packet (corrupt) in its window."""
    packet = TableCrcPacketHandler()
    results = []
    for p in ptys:
        p.port.setPacketTimeout(11)
        t = _later(p, arrives, 0.002) if arrives else None
        rx, comm = packet.rxPacket(p.port, False)
        if t is not None:
            t.join()
        results.append((list(rx), comm))
    assert results[0] == results[1]
    assert results[1][1] == (sdk.COMM_RX_TIMEOUT if arrives is None else sdk.COMM_RX_CORRUPT)


def test_a_vanished_pty_is_a_disconnect_for_the_driver() -> None:
    """The SDK's clearPort (pyserial's tcflush) on a vanished pty raises termios.error, no OSError: it is a
    `BusDisconnectedError` as pyserial's read errors are, so the driver reacts as to an unplugged adapter
    (everything missing, DISCONNECTED) instead of raising it, then "port in use" on every later cycle."""
    before, _, during = (_disconnect(True, stage) for stage in ("before", "during", "driver"))
    assert before[0][0] == "BusDisconnectedError" and "Input/output error" in before[0][1]
    assert all(kind == "ok" for kind, _, _ in during)
    connected, missing, kinds = during[0][2]
    assert connected is False and all(missing) and "DISCONNECTED" in kinds
