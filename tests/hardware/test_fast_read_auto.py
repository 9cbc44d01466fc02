"""``fast_sync_read="auto"`` (the default): one Fast Sync Read probe when the driver starts decides how positions
are read, from the emulator's side of the wire (the stock SDK in process against the emulated chain): a chain
that answers it is read fast; a servo whose firmware predates the instruction, or a probe reply lost or
corrupted, leaves plain Sync Read, with an event and `Driver.fast_read_info`, never an error; ``True`` /
``False`` still force it (and a forced fast read on an old chain still falls back after a few cycles)."""

from __future__ import annotations

import time

import pytest
from servoface.hardware.bus import open_bus
from servoface.hardware.driver import Driver, FastSyncRead
from servoface.hardware.emulator import ServoChain
from servoface.hardware.emulator.models import FAST_READ_MIN_FIRMWARE
from servoface.hardware.errors import HardwareConfigError
from servoface.hardware.servo_config import ServoSpec
from servoface.hardware.snapshot import FaultKind

from tests.hardware.driver_helpers import run

SYNC_READ, FAST_SYNC_READ = 0x82, 0x8A
IDS = (1, 2, 3, 4)
GOALS = {1: 2600, 2: 1700, 3: 1200, 4: 2050}
POSITION_READ = bytes((132, 0, 4, 0))  # address 132, length 4: Present Position (the probe reads it)
SENTINEL_READ = bytes((224, 0, 3, 0))  # the cycle's: the position sentinel's Indirect Data (3 bytes)


def _chain(old_firmware: tuple[int, ...] = ()) -> ServoChain:
    chain = ServoChain.create(ids=list(IDS), model="XL330-M288", baud=1_000_000, wire_time=False, clock="manual")
    for sid in old_firmware:
        chain.servo(sid).set_firmware(FAST_READ_MIN_FIRMWARE - 1)
    return chain


def _driver(chain: ServoChain, fast: FastSyncRead = "auto", *, configure: bool = True) -> Driver:
    specs = [ServoSpec(i, "XL330-M288", min_position_tick=1024, max_position_tick=3072) for i in IDS]
    driver = Driver(open_bus("emulator", chain=chain), specs, clock=chain.clock, fast_sync_read=fast)
    if configure:
        driver.configure()
        driver.torque_on()
    return driver


def _position_reads(chain: ServoChain, after: int = 0) -> list[tuple[int, bytes]]:
    """(instruction, params) of every Sync / Fast Sync Read of Present Position alone the chain received."""
    return [
        (e.instruction, e.params)
        for e in chain.log.kept()[after:]
        if e.instruction in (SYNC_READ, FAST_SYNC_READ) and e.params[:4] in (POSITION_READ, SENTINEL_READ)
    ]


def _settled(chain: ServoChain, driver: Driver) -> None:
    snaps = run(chain, driver, GOALS, seconds=1.0)
    assert {sid: snaps[-1][sid].position_tick for sid in IDS} == GOALS
    assert not any(s.missing or s.stale for s in snaps[-1].servos.values())


def test_a_chain_that_answers_is_read_fast() -> None:
    chain = _chain()
    driver = _driver(chain)
    assert driver.fast_sync_read and "Fast Sync Read" in driver.fast_read_info and "auto" in driver.fast_read_info
    probe = _position_reads(chain)
    assert probe == [(FAST_SYNC_READ, POSITION_READ + bytes(IDS))]  # the probe: every servo, Present Position
    n = len(chain.log.kept())
    _settled(chain, driver)
    reads = [inst for inst, _ in _position_reads(chain, n)]
    assert reads and set(reads) == {FAST_SYNC_READ}
    assert not chain.instructions(SYNC_READ)  # nothing read with plain Sync Read (slow groups fast too)
    assert not [e for e in driver.events if "Fast Sync Read" in e.reaction]


@pytest.mark.parametrize("old", [(3,), (1,), (4,), (1, 2, 3, 4)])
def test_a_servo_without_it_leaves_plain_sync_read(old: tuple[int, ...]) -> None:
    """Firmware before the instruction: that servo stays silent (the first one: no packet at all; a later
    one: a short combined reply), the probe fails, positions are read with Sync Read, no crash."""
    chain = _chain(old_firmware=old)
    assert chain.servo(old[0]).read_register("Firmware Version") == FAST_READ_MIN_FIRMWARE - 1
    driver = _driver(chain)
    assert not driver.fast_sync_read and "plain Sync Read" in driver.fast_read_info
    news = [e for e in driver.events if "Fast Sync Read probe failed" in e.reaction]
    assert len(news) == 1 and news[0].kind in (FaultKind.TIMEOUT, FaultKind.CORRUPT) and news[0].servo_id is None
    n = len(chain.log.kept())
    _settled(chain, driver)
    reads = [inst for inst, _ in _position_reads(chain, n)]
    assert reads and set(reads) == {SYNC_READ}
    assert len(chain.instructions(FAST_SYNC_READ)) == 1  # the probe only
    assert not [e for e in driver.events if e.kind == FaultKind.MISSING]


@pytest.mark.parametrize("fault", ["no_reply", "corrupt_crc", "dropped_bytes"])
@pytest.mark.parametrize("servo", [1, 3])
def test_a_lost_or_corrupt_probe_reply_leaves_plain_sync_read(fault: str, servo: int) -> None:
    """The probe at the first cycle of a driver that did not configure the chain: its reply spoiled once."""
    chain = _chain()
    driver = _driver(chain, configure=False)
    assert not driver.fast_sync_read and "not probed" in driver.fast_read_info
    chain.faults.inject(servo, fault, replies=1)
    snap = driver.cycle({})
    assert not driver.fast_sync_read and "plain Sync Read" in driver.fast_read_info
    assert [e for e in snap.events if "Fast Sync Read probe failed" in e.reaction]
    assert _position_reads(chain)[0][0] == FAST_SYNC_READ and _position_reads(chain)[1][0] == SYNC_READ
    driver.torque_on()
    _settled(chain, driver)
    assert len(chain.instructions(FAST_SYNC_READ)) == 1


def test_forcing_it_still_works() -> None:
    chain = _chain()
    driver = _driver(chain, fast=False)
    assert not driver.fast_sync_read and "forced" in driver.fast_read_info
    _settled(chain, driver)
    assert not chain.instructions(FAST_SYNC_READ)  # no probe, no fast read

    chain = _chain(old_firmware=(2,))  # forced on a chain that cannot: no probe; the cycles' fallback
    driver = _driver(chain, fast=True)
    assert driver.fast_sync_read and not chain.instructions(FAST_SYNC_READ)
    snaps = run(chain, driver, GOALS, seconds=1.0)
    assert not driver.fast_sync_read and "cycles running" in driver.fast_read_info
    assert any("Fast Sync Read failed" in e.reaction for e in driver.events)
    assert {sid: snaps[-1][sid].position_tick for sid in IDS} == GOALS

    chain = _chain()
    driver = _driver(chain, fast=True)
    _settled(chain, driver)
    assert not chain.instructions(SYNC_READ) and driver.fast_sync_read


def test_the_option_is_checked() -> None:
    with pytest.raises(HardwareConfigError, match="fast_sync_read"):
        _driver(_chain(), fast="yes", configure=False)  # type: ignore[arg-type]
    with pytest.raises(HardwareConfigError, match="fast_sync_read"):
        _driver(_chain(), fast=1, configure=False)  # type: ignore[arg-type]


def test_firmware_is_kept_across_reboot_and_factory_reset() -> None:
    chain = _chain(old_firmware=(2,))
    servo = chain.servo(2)
    servo.reboot()
    assert servo.read_register("Firmware Version") == FAST_READ_MIN_FIRMWARE - 1
    servo.factory_reset(0x02)
    assert servo.read_register("Firmware Version") == FAST_READ_MIN_FIRMWARE - 1
    assert chain.servo(1).read_register("Firmware Version") == chain.servo(1).spec.firmware_version


def test_a_failed_probe_at_the_first_cycle_does_not_leave_a_tripped_watchdog() -> None:
    """Torque on (Bus Watchdog armed, 0.1 s) before the first cycle of a driver that did not configure the
    chain, real clock: the failed probe (reply window, then a quiet line) is a pause like any other, so the
    cycle clears and re-arms the watchdog before its goals; they are obeyed."""
    chain = ServoChain.create(ids=list(IDS), model="XL330-M288", baud=1_000_000, wire_time=False)
    chain.servo(1).set_firmware(FAST_READ_MIN_FIRMWARE - 1)  # the first one silent: the probe times out
    try:
        driver = _driver(chain, configure=False)
        driver.torque_on()
        deadline = time.monotonic() + 5.0
        snap = driver.cycle(GOALS)
        assert not driver.fast_sync_read and driver.watchdog_rearms >= 1
        while time.monotonic() < deadline and {sid: snap[sid].position_tick for sid in IDS} != GOALS:
            time.sleep(0.01)
            snap = driver.cycle(GOALS)
        assert {sid: snap[sid].position_tick for sid in IDS} == GOALS
    finally:
        chain.close()
