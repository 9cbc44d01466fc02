"""The pseudo-terminal transport, opened with pyserial and with the stock SDK's PortHandler."""

from __future__ import annotations

import os
import sys
import time

import pytest
import serial
from servoface.hardware.emulator import ServoChain, build_instruction
from servoface.hardware.emulator.packet import PacketReceiver

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals need a POSIX system")


def _read_until(port: serial.Serial, n: int, timeout_s: float = 2.0) -> bytes:
    data = b""
    deadline = time.monotonic() + timeout_s
    while len(data) < n and time.monotonic() < deadline:
        data += port.read(n - len(data))
    return data


def test_pyserial_ping_over_pty() -> None:
    with ServoChain.create(ids=[1, 2], baud=1_000_000) as chain:
        path = chain.serve_pty()
        assert os.path.exists(path)
        with serial.Serial(path, 1_000_000, timeout=0.05) as port:
            port.write(build_instruction(2, 0x01))
            (status,) = PacketReceiver().feed(_read_until(port, 14))
            assert (status.id, status.error, status.data) == (2, 0, bytes((0xB0, 0x04, 52)))
    assert chain.log[-1].instruction == 0x01


def test_wrong_baud_on_pty_is_silent() -> None:
    with ServoChain.create(ids=[1], baud=57_600, wire_time=False) as chain:
        path = chain.serve_pty()
        with serial.Serial(path, 1_000_000, timeout=0.05) as port:
            port.write(build_instruction(1, 0x01))
            assert _read_until(port, 14, 0.3) == b""
            port.baudrate = 57_600
            port.write(build_instruction(1, 0x01))
            assert len(_read_until(port, 14)) == 14


def test_stock_sdk_over_pty() -> None:
    import dynamixel_sdk as sdk

    with ServoChain.create(ids=range(1, 5), baud=1_000_000) as chain:
        path = chain.serve_pty()
        port = sdk.PortHandler(path)
        assert port.openPort()
        ph = sdk.PacketHandler(2.0)
        try:
            assert ph.ping(port, 3) == (1200, 0, 0)
            assert ph.write4ByteTxRx(port, 4, 112, 77) == (0, 0)
            group = sdk.GroupSyncRead(port, ph, 112, 4)
            for sid in (4, 1):
                group.addParam(sid)
            assert group.txRxPacket() == 0
            assert (group.getData(4, 112, 4), group.getData(1, 112, 4)) == (77, 0)
        finally:
            port.closePort()


def test_close_stops_serving() -> None:
    chain = ServoChain.create(ids=[1])
    path = chain.serve_pty()
    assert chain.serve_pty() == path  # one server per chain
    chain.close()
    assert not os.path.exists(path) or not _pty_answers(path)


def _pty_answers(path: str) -> bool:
    try:
        with serial.Serial(path, 1_000_000, timeout=0.05) as port:
            port.write(build_instruction(1, 0x01))
            return bool(_read_until(port, 14, 0.2))
    except (OSError, serial.SerialException):
        return False
