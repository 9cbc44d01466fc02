"""One contract for every bus backend: in-process port and pty, both driving the stock dynamixel-sdk.

Assertions are on the emulator's state and its packet log, never on canned bytes.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator

import pytest
from servoface.hardware.bus import ServoBus, open_bus
from servoface.hardware.emulator import ServoChain
from servoface.hardware.errors import (
    BusClosedError,
    BusCorruptError,
    BusTimeoutError,
    HardwareConfigError,
    ServoStatusError,
)
from servoface.hardware.registers import Register

SYNC_WRITE, SYNC_READ, FAST_SYNC_READ, BULK_WRITE = 0x83, 0x82, 0x8A, 0x93
IDS = [1, 2, 3, 4]


def _arrives(check: Callable[[], bool], timeout_s: float = 2.0) -> bool:
    """Broadcast writes get no reply; over a pty the emulator thread may not have read them yet."""
    deadline = time.monotonic() + timeout_s
    while not check():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.002)
    return True


@pytest.fixture(params=["in_process", "pty"])
def chain_and_bus(request: pytest.FixtureRequest) -> Iterator[tuple[ServoChain, ServoBus]]:
    chain = ServoChain.create(ids=IDS, model="XL330-M288", baud=1_000_000, wire_time=False)
    if request.param == "in_process":
        bus = open_bus("emulator", chain=chain)
    else:
        bus = open_bus("dynamixel", port=chain.serve_pty(), baud=1_000_000)
    yield chain, bus
    bus.close()
    chain.close()


def test_ping_reports_model_and_firmware(chain_and_bus: tuple[ServoChain, ServoBus]) -> None:
    chain, bus = chain_and_bus
    reply = bus.ping(3)
    assert reply.servo_id == 3 and reply.model_number == 1200
    assert reply.firmware_version == chain.servo(3).read_register("FIRMWARE_VERSION")
    with pytest.raises(BusTimeoutError) as err:
        bus.ping(9)
    assert err.value.servo_ids == (9,)


def test_write_then_read_back_matches_the_servo(chain_and_bus: tuple[ServoChain, ServoBus]) -> None:
    chain, bus = chain_and_bus
    bus.write(2, Register.PROFILE_VELOCITY, 77)
    assert chain.servo(2).read_register("PROFILE_VELOCITY") == 77
    assert bus.read(2, Register.PROFILE_VELOCITY) == 77
    chain.servo(4).move_by_hand(1234)
    got = bus.read_many(4, [Register.PRESENT_POSITION, Register.PRESENT_TEMPERATURE])
    assert got[Register.PRESENT_POSITION] == 1234
    assert got[Register.PRESENT_TEMPERATURE] == chain.servo(4).read_register("PRESENT_TEMPERATURE")


def test_eeprom_write_with_torque_on_is_an_access_error(chain_and_bus: tuple[ServoChain, ServoBus]) -> None:
    chain, bus = chain_and_bus
    bus.write(1, Register.TORQUE_ENABLE, 1)
    with pytest.raises(ServoStatusError) as err:
        bus.write(1, Register.MAX_POSITION_LIMIT, 3000)
    assert err.value.servo_id == 1 and err.value.error_number == 7
    assert chain.servo(1).read_register("MAX_POSITION_LIMIT") == 4095


def test_sync_write_is_one_packet_and_reaches_every_servo(chain_and_bus: tuple[ServoChain, ServoBus]) -> None:
    chain, bus = chain_and_bus
    before = len(chain.instructions(SYNC_WRITE))
    bus.sync_write(Register.GOAL_POSITION, {1: 1000, 2: 2000, 3: 3000, 4: 4000})
    assert _arrives(lambda: len(chain.instructions(SYNC_WRITE)) == before + 1)
    assert sorted((sid, goal) for _, sid, goal in chain.goal_writes()) == [
        (1, 1000),
        (2, 2000),
        (3, 3000),
        (4, 4000),
    ]
    with pytest.raises(ValueError):  # does not fit: nothing sent
        bus.sync_write(Register.GOAL_POSITION, {1: 5, 2: 2**40})
    bus.ping(1)  # a round trip: anything sent before it has been heard
    assert len(chain.instructions(SYNC_WRITE)) == before + 1


@pytest.mark.parametrize("fast", [False, True])
def test_sync_read_returns_each_servos_values(chain_and_bus: tuple[ServoChain, ServoBus], fast: bool) -> None:
    chain, bus = chain_and_bus
    for sid in IDS:
        chain.servo(sid).move_by_hand(1000 + 100 * sid)
    got = bus.sync_read(IDS, [Register.PRESENT_POSITION], fast=fast)
    assert {sid: v[Register.PRESENT_POSITION] for sid, v in got.items()} == {sid: 1000 + 100 * sid for sid in IDS}
    assert chain.instructions(FAST_SYNC_READ if fast else SYNC_READ)


def test_sync_read_of_a_block_decodes_signed_fields(chain_and_bus: tuple[ServoChain, ServoBus]) -> None:
    chain, bus = chain_and_bus
    regs = [Register.PRESENT_CURRENT, Register.PRESENT_VELOCITY, Register.PRESENT_POSITION]
    got = bus.sync_read([1, 2], regs)
    for sid in (1, 2):
        live = chain.servo(sid).present_values()
        assert got[sid][Register.PRESENT_POSITION] == live["Present Position"]
        assert got[sid][Register.PRESENT_CURRENT] == live["Present Current"]


@pytest.mark.parametrize("fast", [False, True])
def test_sync_read_is_all_or_nothing(chain_and_bus: tuple[ServoChain, ServoBus], fast: bool) -> None:
    chain, bus = chain_and_bus
    chain.faults.inject(3, "no_reply")
    with pytest.raises((BusTimeoutError, BusCorruptError)) as err:
        bus.sync_read(IDS, [Register.PRESENT_POSITION], fast=fast)
    assert err.value.servo_ids == tuple(IDS)
    assert bus.read(2, Register.PRESENT_POSITION) == chain.servo(2).position_tick  # the others still answer


def test_corrupt_reply_is_reported_as_corrupt(chain_and_bus: tuple[ServoChain, ServoBus]) -> None:
    chain, bus = chain_and_bus
    chain.faults.inject(2, "corrupt_crc")
    with pytest.raises(BusCorruptError):
        bus.read(2, Register.PRESENT_POSITION)
    before = bus.stats.corrupt
    with pytest.raises(BusCorruptError):
        bus.sync_read(IDS, [Register.PRESENT_POSITION])
    assert bus.stats.corrupt == before + 1


def test_alert_bit_is_recorded_not_raised(chain_and_bus: tuple[ServoChain, ServoBus]) -> None:
    chain, bus = chain_and_bus
    chain.faults.inject(4, "overload")
    assert bus.read(4, Register.PRESENT_POSITION) == chain.servo(4).position_tick
    assert 4 in bus.alerts
    assert bus.read(4, Register.HARDWARE_ERROR_STATUS) & 0x20


def test_bulk_read_and_write(chain_and_bus: tuple[ServoChain, ServoBus]) -> None:
    chain, bus = chain_and_bus
    bus.bulk_write({1: {Register.PROFILE_ACCELERATION: 5, Register.PROFILE_VELOCITY: 50}, 2: {Register.LED: 1}})
    assert _arrives(lambda: bool(chain.instructions(BULK_WRITE)))
    assert chain.servo(1).read_register("PROFILE_VELOCITY") == 50 and chain.servo(2).read_register("LED") == 1
    for fast in (False, True):
        got = bus.bulk_read(
            {1: [Register.PROFILE_VELOCITY], 2: [Register.LED, Register.STATUS_RETURN_LEVEL]}, fast=fast
        )
        assert got[1][Register.PROFILE_VELOCITY] == 50 and got[2][Register.LED] == 1
    with pytest.raises(HardwareConfigError, match="gaps"):
        bus.bulk_write({1: {Register.LED: 1, Register.PROFILE_VELOCITY: 3}})


def test_reboot_clears_a_latched_error(chain_and_bus: tuple[ServoChain, ServoBus]) -> None:
    chain, bus = chain_and_bus
    chain.faults.inject(1, "overload", duration_s=0.0)
    bus.read(1, Register.PRESENT_POSITION)
    assert chain.servo(1).hardware_error & 0x20
    bus.reboot(1)
    assert chain.instructions(0x08)
    assert chain.servo(1).hardware_error == 0


def test_closed_bus_refuses_work(chain_and_bus: tuple[ServoChain, ServoBus]) -> None:
    _, bus = chain_and_bus
    bus.close()
    assert not bus.is_open
    with pytest.raises(BusClosedError):
        bus.ping(1)
    bus.open()
    assert bus.ping(1).model_number == 1200


def test_broadcast_ping_finds_the_chain(chain_and_bus: tuple[ServoChain, ServoBus]) -> None:
    _, bus = chain_and_bus
    found = bus.broadcast_ping()  # waits the SDK's fixed window (~0.8 s)
    assert sorted(found) == IDS and {r.model_number for r in found.values()} == {1200}


def test_factory_rejects_unknown_interfaces_and_bauds() -> None:
    with pytest.raises(ValueError, match="unknown bus interface 'can'"):
        open_bus("can", port="/dev/null")
    with pytest.raises(HardwareConfigError, match="4500000"):
        open_bus("dynamixel", port="/dev/null", baud=4_500_000)
    with pytest.raises(ValueError, match="chain="):
        open_bus("emulator", port="/dev/ttyUSB0")


def test_ping_answers_even_with_status_return_level_zero(chain_and_bus: tuple[ServoChain, ServoBus]) -> None:
    chain, bus = chain_and_bus
    bus.write(2, Register.STATUS_RETURN_LEVEL, 0)  # the write itself is still answered (level applies after)
    reply = bus.ping(2)
    assert (reply.model_number, reply.firmware_version) == (
        1200,
        chain.servo(2).read_register("FIRMWARE_VERSION"),
    )
    with pytest.raises(BusTimeoutError):
        bus.read(2, Register.PRESENT_POSITION)
