"""A late status packet of another servo ahead of a Fast Sync Read's combined reply (seen on loaded
machines: a reply to an earlier instruction arriving in the next one's window). The stock SDK's
``GroupSyncRead.fastSyncRead`` raises IndexError on it; servoface's bus skips it, as the SDK's plain Sync
Read skips a packet of another id, and anything it cannot read is a typed bus error. The stray bytes are
put on the wire from the emulator's side, the SDK parses them."""

from __future__ import annotations

from typing import Any

import pytest
from servoface.hardware.dynamixel_bus import DynamixelBus
from servoface.hardware.emulator import ServoChain
from servoface.hardware.emulator.packet import Instruction, build_status
from servoface.hardware.errors import BusError
from servoface.hardware.registers import Register
from servoface.hardware.stock_loop import StockSdkLoop

IDS = [1, 2, 3]


class _StraySerial:
    """The chain's serial endpoint, plus ``strays`` status packets put on the wire ahead of the reply to
    the next ``arm``-ed Fast Sync Reads (the late replies of servo 2 to some earlier read)."""

    def __init__(self, inner: Any) -> None:
        self._inner = inner
        self.strays = 0
        self._queued = b""

    def write(self, data: Any) -> int:
        n = int(self._inner.write(data))
        if self.strays and len(data) > 7 and data[7] == Instruction.FAST_SYNC_READ:
            self._queued = build_status(2, 0, (2048).to_bytes(4, "little")) * self.strays
        return n

    def read(self, size: int = 1) -> bytes:
        if self._queued:
            out, self._queued = self._queued[:size], self._queued[size:]
            return out
        return bytes(self._inner.read(size))

    @property
    def in_waiting(self) -> int:
        return len(self._queued) + int(self._inner.in_waiting)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)


class _StrayChain:
    def __init__(self) -> None:
        self.chain = ServoChain.create(ids=IDS, model="XL330-M288", baud=1_000_000, wire_time=False)
        self.serial = _StraySerial(self.chain.open_serial())

    def open_serial(self) -> Any:
        return self.serial


@pytest.fixture
def stray() -> Any:
    rig = _StrayChain()
    with DynamixelBus(rig, 1_000_000) as bus:
        yield rig, bus
    rig.chain.close()


def test_a_late_packet_of_another_id_is_skipped_before_the_combined_reply(stray: Any) -> None:
    rig, bus = stray
    plain = bus.sync_read(IDS, (Register.PRESENT_POSITION,))
    rig.serial.strays = 1
    assert bus.sync_read(IDS, (Register.PRESENT_POSITION,), fast=True) == plain
    assert bus.stats.stray == 1 and bus.stats.corrupt == 0
    rig.serial.strays = 0
    assert bus.sync_read(IDS, (Register.PRESENT_POSITION,), fast=True) == plain  # the next one is clean


def test_only_stray_packets_is_a_typed_bus_error_not_an_index_error(stray: Any) -> None:
    rig, bus = stray
    rig.chain.faults.inject_now(1, "no_reply")  # the combined reply starts with servo 1's block: none comes
    rig.serial.strays = 2
    with pytest.raises(BusError):
        bus.sync_read(IDS, (Register.PRESENT_POSITION,), fast=True)
    assert bus.stats.stray == 2
    rig.chain.faults.clear()
    rig.serial.strays = 0
    assert set(bus.sync_read(IDS, (Register.PRESENT_POSITION,), fast=True)) == set(IDS)  # the bus recovers


def test_the_stock_sdk_loop_counts_it_as_a_failed_read(stray: Any) -> None:
    rig, bus = stray
    loop = StockSdkLoop(bus, IDS, fast=True)
    assert set(loop.cycle(2048)) == set(IDS)
    rig.serial.strays = 1  # the SDK's fastSyncRead would raise IndexError here
    assert loop.cycle(2048) == {} and loop.failures == 1
    rig.serial.strays = 0
    assert set(loop.cycle(2048)) == set(IDS)


def test_read_ahead_hands_over_the_same_bytes_and_clear_drops_them() -> None:
    """The port reads what has arrived in one go and hands it to the SDK as it asks: the bytes the SDK
    sees, their order and the bytes available are those of the port itself; clearing drops them."""
    from servoface.hardware.emulator.packet import build_instruction

    with (
        ServoChain.create(ids=IDS, model="XL330-M288", baud=1_000_000, wire_time=False) as chain,
        DynamixelBus(chain, 1_000_000) as bus,
    ):
        port, packet = bus.sdk_handlers()
        raw = chain.open_serial()
        port.clearPort()
        port.writePort(build_instruction(0xFE, Instruction.PING))
        first = port.readPort(3)
        assert port.getBytesAvailable() == 3 * 14 - 3  # three ping replies, 14 bytes each
        rest = b"".join(iter(lambda: port.readPort(5), b""))
        assert len(first + rest) == 42 and (first + rest).count(b"\xff\xff\xfd\x00") == 3
        port.writePort(build_instruction(0xFE, Instruction.PING))
        port.readPort(1)
        port.clearPort()
        assert port.getBytesAvailable() == 0 and raw.in_waiting == 0 and port.readPort(8) == b""
        assert sorted(packet.broadcastPing(port)[0]) == IDS  # the SDK's own multi-reply read still works
