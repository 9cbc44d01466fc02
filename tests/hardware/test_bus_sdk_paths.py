"""`DynamixelBus` sends its Sync Write and (Fast) Sync Read instructions through the SDK's packet-level calls
(``syncWriteTxOnly`` / ``syncReadTx``) with parameters it builds, instead of ``GroupSyncWrite`` /
``GroupSyncRead``: the bytes that reach the emulator are the same as the group helpers', byte for byte
(stuffing included), and the values read back are the same, on random ids, registers and values."""

from __future__ import annotations

import random
from typing import Any

import numpy as np
import pytest
from servoface.hardware.bus import open_bus
from servoface.hardware.dynamixel_bus import DynamixelBus, TableCrcPacketHandler, sdk
from servoface.hardware.emulator import ServoChain
from servoface.hardware.registers import Register

IDS = list(range(1, 11))
WRITABLE = (Register.GOAL_POSITION, Register.PROFILE_VELOCITY, Register.GOAL_PWM, Register.LED, Register.GOAL_CURRENT)
READS = (
    (Register.PRESENT_POSITION,),
    (Register.MOVING, Register.PRESENT_CURRENT, Register.PRESENT_VELOCITY, Register.PRESENT_POSITION),
    (Register.PRESENT_POSITION, Register.PRESENT_INPUT_VOLTAGE, Register.PRESENT_TEMPERATURE),
    (Register.TORQUE_ENABLE, Register.HARDWARE_ERROR_STATUS),
)


def _raw_log(chain: ServoChain) -> list[bytes]:
    """Every chunk of bytes the host writes, as the chain receives it (before any parsing)."""
    seen: list[bytes] = []
    write = chain.host_write

    def tap(data: Any, baud: int) -> int:
        seen.append(bytes(data))
        return write(data, baud)

    chain.host_write = tap  # type: ignore[method-assign]
    return seen


def _value(rng: random.Random, register: Register) -> int:
    lo, hi = register.value_range
    if rng.random() < 0.2 and register.size == 4:  # bytes that need stuffing: FF FF FD inside the parameters
        return int.from_bytes(bytes((0xFF, 0xFF, 0xFD, rng.randint(0, 0x7F))), "little", signed=register.signed)
    return rng.randint(lo, hi)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_sync_write_sends_the_group_helpers_bytes(seed: int) -> None:
    rng = random.Random(seed)
    chain = ServoChain.create(ids=IDS, wire_time=False)
    seen = _raw_log(chain)
    bus = open_bus("emulator", chain=chain)
    assert isinstance(bus, DynamixelBus)
    port, packet = bus.sdk_handlers()
    try:
        for _ in range(300):
            register = rng.choice(WRITABLE)
            ids = rng.sample(IDS, rng.randint(1, len(IDS)))
            values = {sid: _value(rng, register) for sid in ids}
            bus.sync_write(register, values)
            ours = seen.pop()
            group = sdk.GroupSyncWrite(port, packet, register.address, register.size)
            for sid in ids:
                group.addParam(sid, list(register.encode(values[sid])))
            assert group.txPacket() == sdk.COMM_SUCCESS
            assert ours == seen.pop(), (register, values)
        assert not seen
    finally:
        bus.close()


def _previous_sync_write_param(register: Register, values: dict[int, Any]) -> list[int]:
    """The parameters as `DynamixelBus.sync_write` built them before its packed path (kept as the reference)."""
    lo, hi = register.value_range
    param: list[int] = []
    for sid, value in values.items():
        param.append(sid)
        if type(value) is int and lo <= value <= hi:
            param += value.to_bytes(register.size, "little", signed=register.signed)
        else:
            param += register.encode(value)
    return param


def _odd_value(rng: random.Random, register: Register) -> Any:
    lo, hi = register.value_range
    return rng.choice((lo - 1, hi + 1, True, False, 1.0, 2.5, float("nan"), "7", None, np.int64(rng.randint(lo, hi))))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_sync_write_odd_values_give_the_previous_bytes_or_error(seed: int) -> None:
    """Frames with values that are not plain in-range ints (bools, floats, numpy ints, out of range, junk)
    take the per-value path: the same bytes on the wire, or the same error with nothing sent."""
    rng = random.Random(seed)
    chain = ServoChain.create(ids=IDS, wire_time=False)
    seen = _raw_log(chain)
    bus = open_bus("emulator", chain=chain)
    port, packet = bus.sdk_handlers()  # type: ignore[attr-defined]
    try:
        for _ in range(300):
            register = rng.choice(WRITABLE)
            ids = rng.sample(IDS, rng.randint(1, len(IDS)))
            values = {sid: _value(rng, register) if rng.random() < 0.8 else _odd_value(rng, register) for sid in ids}
            try:
                expected: Any = _previous_sync_write_param(register, values)
            except Exception as err:
                expected = (type(err), str(err))
            try:
                bus.sync_write(register, values)
            except Exception as err:
                assert (type(err), str(err)) == expected and not seen
                continue
            ours = seen.pop()
            assert isinstance(expected, list) and not seen
            assert packet.syncWriteTxOnly(port, register.address, register.size, expected, len(expected)) == 0
            assert ours == seen.pop(), (register, values)
    finally:
        bus.close()


@pytest.mark.parametrize("seed", [1, 2])
@pytest.mark.parametrize("fast", [False, True])
def test_sync_read_sends_the_group_helpers_bytes_and_reads_the_same_values(seed: int, fast: bool) -> None:
    rng = random.Random(seed)
    chain = ServoChain.create(ids=IDS, wire_time=False)
    seen = _raw_log(chain)
    bus = open_bus("emulator", chain=chain)
    assert isinstance(bus, DynamixelBus)
    port, packet = bus.sdk_handlers()
    try:
        for _ in range(150):
            registers = rng.choice(READS)
            ids = rng.sample(IDS, rng.randint(1, len(IDS)))
            got = bus.sync_read(ids, registers, fast=fast)
            ours = seen.pop()
            start = min(r.address for r in registers)
            length = max(r.address + r.size for r in registers) - start
            group = sdk.GroupSyncRead(port, packet, start, length)
            for sid in ids:
                group.addParam(sid)
            assert (group.fastSyncRead() if fast else group.txRxPacket()) == sdk.COMM_SUCCESS
            assert ours == seen.pop(), (registers, ids)
            for sid in ids:
                for r in registers:
                    raw = group.getData(sid, r.address, r.size)
                    assert got[sid][r] == int.from_bytes(raw.to_bytes(r.size, "little"), "little", signed=r.signed)
    finally:
        bus.close()


def _combined(rng: random.Random, ids: list[int], length: int) -> bytes:
    """A combined Fast Sync Read reply's parameters: usually well formed, sometimes not (ids out of place or
    wrong, truncated), with random error bytes (Alert bits)."""
    blocks = [bytes((rng.choice((0, 0, 0x80, 0x81)), sid)) + rng.randbytes(length + 2) for sid in ids]
    kind = rng.random()
    if kind < 0.15:
        rng.shuffle(blocks)
    elif kind < 0.3:
        k = rng.randrange(len(blocks))
        blocks[k] = blocks[k][:1] + bytes((rng.randrange(256),)) + blocks[k][2:]
    raw = b"".join(blocks)
    if rng.random() < 0.2:
        raw = raw[: rng.randrange(len(raw) + 1)]
    return raw


def _blocks_parse(bus: DynamixelBus) -> Any:
    """The parse before the one-pass path: the blocks dict, then the per-field values."""

    def parse(raw: bytes, ids: list[int], length: int, fields: Any, what: str) -> Any:
        return bus._values(bus._fast_blocks(raw, ids, length, what), ids, length, fields, what)

    return parse


def _outcome(bus: DynamixelBus, parse: Any, raw: bytes, ids: list[int], length: int, fields: Any) -> tuple[Any, ...]:
    try:
        result: Any = parse(raw, ids, length, fields, "read")
    except Exception as err:  # noqa: BLE001 - the error is part of what must be equal
        result = (type(err), str(err))
    stats = bus.stats
    return result, stats.alerts, stats.corrupt, stats.transactions, set(bus.alerts)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_fast_read_one_pass_parse_equals_the_blocks_parse(seed: int) -> None:
    """`DynamixelBus._fast_values` (one pass for the position read) gives what the blocks dict then the
    per-field values gave: the same values, exceptions, counters and alerts, on random combined replies."""
    rng = random.Random(seed)
    buses = [open_bus("emulator", chain=ServoChain.create(ids=IDS, wire_time=False)) for _ in range(2)]
    fast, plain = buses
    assert isinstance(fast, DynamixelBus) and isinstance(plain, DynamixelBus)
    try:
        for _ in range(400):
            registers = rng.choice(READS[:1] * 3 + READS[1:])
            start = min(r.address for r in registers)
            length = max(r.address + r.size for r in registers) - start
            fields = tuple((r, r.address - start, r.address - start + r.size, r.signed) for r in registers)
            ids = rng.sample(IDS, rng.randint(1, len(IDS)))
            raw = _combined(rng, ids, length)
            got = _outcome(fast, fast._fast_values, raw, ids, length, fields)
            want = _outcome(plain, _blocks_parse(plain), raw, ids, length, fields)
            assert got == want, (registers, ids, raw.hex())
    finally:
        for bus in buses:
            bus.close()


def _sdk_crc(handler: Any, crc: int, data: Any, size: int) -> Any:
    try:
        return handler.updateCRC(crc, data, size)
    except Exception as err:  # noqa: BLE001 - the error is part of what must be equal
        return type(err)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_table_crc_packet_handler_equals_the_sdk_crc(seed: int) -> None:
    """The bus's packet handler (`TableCrcPacketHandler.updateCRC`) returns what the SDK's byte loop does, on
    random packets as the SDK passes them (lists, bytes), any size argument, start value and odd values."""
    rng = random.Random(seed)
    ours, stock = TableCrcPacketHandler(), sdk.PacketHandler(2.0)
    for _ in range(3000):
        data: Any = [rng.randrange(256) for _ in range(rng.randrange(0, 120))]
        if rng.random() < 0.05 and data:
            data[rng.randrange(len(data))] = rng.choice((256, 511, -1))  # the SDK masks; bytes() cannot
        if rng.random() < 0.3:
            data = bytes(x & 0xFF for x in data)
        size = rng.choice((len(data), len(data) - 2, rng.randrange(-2, len(data) + 3)))
        crc = rng.choice((0, 0, rng.randrange(0x10000), rng.randrange(0x10000, 0x30000)))
        assert _sdk_crc(ours, crc, data, size) == _sdk_crc(stock, crc, data, size), (crc, size, data)
