"""Configure-time reads are retried (bounded): a lost or late reply while a head opens must not fail the
open — a loaded machine delays the emulator's (or a real adapter's) reply past the SDK's window. Faults
injected on the emulator's side of the wire; the stock SDK runs every transaction."""

from __future__ import annotations

import pytest
from servoface.hardware.bus import open_bus
from servoface.hardware.driver import Driver
from servoface.hardware.emulator import ServoChain
from servoface.hardware.emulator.errors import EmulatorConfigError
from servoface.hardware.errors import BusTimeoutError
from servoface.hardware.fault_policy import FaultPolicy
from servoface.hardware.servo_config import ServoSpec
from servoface.hardware.snapshot import FaultKind

IDS = (1, 2, 3, 4)


def _chain_and_driver(clock: str = "manual", policy: FaultPolicy | None = None) -> tuple[ServoChain, Driver]:
    chain = ServoChain.create(ids=list(IDS), model="XL330-M288", baud=1_000_000, wire_time=False, clock=clock)
    bus = open_bus("emulator", chain=chain)
    specs = [ServoSpec(i, "XL330-M288", role=f"r{i}", min_position_tick=1024, max_position_tick=3072) for i in IDS]
    return chain, Driver(bus, specs, policy=policy)


@pytest.mark.parametrize("lost", [1, 2])
def test_lost_replies_while_configuring_are_retried(lost: int) -> None:
    chain, driver = _chain_and_driver()
    try:
        chain.faults.inject(3, "no_reply", replies=lost)  # the next `lost` status packets of servo 3 vanish
        reports = driver.configure()
        assert sorted(reports) == list(IDS)
        assert driver.configure_retries == lost
        assert chain.servo(3).read_register("Max Position Limit") == 3072  # really configured
    finally:
        chain.close()


def test_the_retry_is_bounded_and_names_the_servo() -> None:
    chain, driver = _chain_and_driver(policy=FaultPolicy(configure_attempts=3))
    try:
        chain.faults.inject(3, "no_reply", replies=3)  # one more than the retries
        with pytest.raises(BusTimeoutError, match=r"\[3\]"):
            driver.configure()
        assert driver.configure_retries == 2
    finally:
        chain.close()


def test_allow_missing_marks_a_servo_missing_only_after_every_attempt() -> None:
    chain, driver = _chain_and_driver(policy=FaultPolicy(configure_attempts=2))
    try:
        chain.faults.inject(2, "no_reply", replies=2)
        reports = driver.configure(allow_missing=True)
        assert sorted(reports) == [1, 3, 4]
        assert [e.servo_id for e in driver.events if e.kind is FaultKind.MISSING] == [2]
    finally:
        chain.close()


def test_a_late_reply_during_configure_is_drained_then_retried() -> None:
    """Real clock: the reply comes 20 ms late (past the SDK's window or not, depending on the machine's
    load); either way the open succeeds and the late bytes are never taken for another answer."""
    chain, driver = _chain_and_driver(clock="real")
    try:
        chain.faults.inject(3, "late_reply", delay_s=0.02, replies=1)
        reports = driver.configure()
        assert sorted(reports) == list(IDS)
        assert driver.configure_retries in (0, 1)
        driver.torque_on()
        assert driver.read_state().positions_tick().keys() == set(IDS)
    finally:
        chain.close()


def test_a_counted_fault_needs_a_reply_kind_and_a_positive_count() -> None:
    chain = ServoChain.create(ids=[1], model="XL330-M288", wire_time=False, clock="manual")
    try:
        with pytest.raises(EmulatorConfigError, match="replies"):
            chain.faults.inject(1, "overload", replies=1)
        with pytest.raises(EmulatorConfigError, match="replies"):
            chain.faults.inject(1, "no_reply", replies=0)
    finally:
        chain.close()


def test_configure_attempts_is_validated() -> None:
    with pytest.raises(ValueError, match="configure_attempts"):
        FaultPolicy(configure_attempts=0)
