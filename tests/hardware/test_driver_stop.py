"""Stopping a chain: torque off reaches every servo it can (retried, carrying on past failures), the Bus
Watchdog is armed while driving and disarmed on a clean close, short hardware faults recover (reboot
back-off), and the port is locked against a second controller."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from servoface.hardware.bus import open_bus
from servoface.hardware.driver import Driver
from servoface.hardware.emulator import ServoChain
from servoface.hardware.errors import PortLockedError
from servoface.hardware.fault_policy import FaultPolicy
from servoface.hardware.servo_config import ServoSpec
from servoface.hardware.snapshot import FaultKind

from tests.hardware.driver_helpers import events_of, make_driver, run

IDS = tuple(range(1, 22))


def _torque(chain: ServoChain) -> dict[int, int]:
    return {i: chain.servo(i).read_register("Torque Enable") for i in chain.ids}


@pytest.mark.parametrize("silent", [1, 5, 21])
def test_a_silent_servo_does_not_keep_the_others_powered(silent: int) -> None:
    chain, driver = make_driver(IDS)
    run(chain, driver, {}, 0.05)
    chain.faults.inject_now(silent, "disconnect")  # gone from the bus: cannot even hear the torque-off
    unreached = driver.torque_off()
    assert unreached == (silent,)
    assert [i for i, t in _torque(chain).items() if t and i != silent] == []
    assert events_of(driver, FaultKind.UNREACHED, silent)


def test_a_late_reply_is_retried_and_reported_while_every_other_servo_goes_off() -> None:
    chain = ServoChain.create(ids=list(IDS), model="XL330-M288", baud=1_000_000, wire_time=False)
    bus = open_bus("emulator", chain=chain)
    driver = Driver(bus, [ServoSpec(i, "XL330-M288", role=f"r{i}") for i in IDS])
    driver.configure()
    driver.torque_on()
    chain.faults.inject_now(5, "late_reply", delay_s=0.2)
    unreached = driver.torque_off()
    assert unreached in ((5,), ())  # a reply 0.2 s late misses every window: not confirmed
    assert [i for i, t in _torque(chain).items() if t] == []  # servo 5 heard it; the rest confirmed
    chain.close()


def test_watchdog_armed_on_torque_on_stops_the_servo_when_the_host_goes_quiet() -> None:
    chain, driver = make_driver((1, 2))
    assert chain.servo(1).read_register("Bus Watchdog") == FaultPolicy().watchdog_units == 5
    driver.cycle({1: 3000})
    chain.advance(0.05)
    moving_at = chain.servo(1).position_tick
    chain.advance(0.2)  # the host said nothing for 0.25 s > 0.1 s
    stopped_at = chain.servo(1).position_tick
    chain.advance(0.5)
    assert chain.servo(1).read_register("Bus Watchdog") == -1  # tripped
    assert chain.servo(1).position_tick == stopped_at != 3000 and stopped_at >= moving_at


def test_after_a_pause_the_driver_rearms_the_watchdog_and_goals_get_through() -> None:
    chain, driver = make_driver((1, 2))
    driver.cycle({1: 2048})
    chain.advance(0.5)  # tripped
    assert chain.servo(1).read_register("Bus Watchdog") == -1
    run(chain, driver, {1: 2400}, 1.0)
    assert driver.watchdog_rearms >= 1
    assert chain.servo(1).read_register("Bus Watchdog") == 5
    assert abs(chain.servo(1).position_tick - 2400) <= 2


def test_clean_close_turns_torque_off_and_disarms_the_watchdog() -> None:
    chain, driver = make_driver((1, 2, 3))
    run(chain, driver, {1: 2100}, 0.1)
    assert driver.close(torque_off=True) == ()
    for i in (1, 2, 3):
        assert chain.servo(i).read_register("Torque Enable") == 0
        assert chain.servo(i).read_register("Bus Watchdog") == 0


def test_watchdog_off_when_policy_says_so() -> None:
    chain, driver = make_driver((1,), policy=FaultPolicy(watchdog_s=0))
    assert chain.servo(1).read_register("Bus Watchdog") == 0
    with pytest.raises(ValueError, match="watchdog_s"):
        FaultPolicy(watchdog_s=5.0)


@pytest.mark.parametrize("kind", ["input_voltage", "overheating"])
def test_a_half_second_hardware_fault_recovers_instead_of_latching(kind: str) -> None:
    chain, driver = make_driver((1, 2, 3))
    run(chain, driver, {}, 0.2)
    chain.faults.inject(3, kind, start_s=chain.time_s, duration_s=0.5)
    snaps = run(chain, driver, {}, 6.0)
    assert not driver.servo_problems()["latched"]
    assert snaps[-1][3].torque_on and FaultKind.LATCHED not in snaps[-1][3].faults
    reboots = events_of(driver, FaultKind.REBOOTED, 3)
    assert 1 <= len(reboots) <= 3
    gaps = [b.t_s - a.t_s for a, b in zip(reboots, reboots[1:], strict=False)]
    assert all(g2 >= 1.5 * g1 for g1, g2 in zip(gaps, gaps[1:], strict=False))  # exponential back-off
    if kind == "input_voltage":  # the bit is named as such, not as a low reading (the supply reads fine)
        assert events_of(driver, FaultKind.INPUT_VOLTAGE, 3)
        assert not events_of(driver, FaultKind.VOLTAGE_LOW, 3)


def test_a_persisting_fault_still_latches() -> None:
    chain, driver = make_driver((1, 2))
    run(chain, driver, {}, 0.2)
    chain.faults.inject(2, "input_voltage", start_s=chain.time_s)
    run(chain, driver, {}, 30.0, dt_s=0.02)
    assert driver.servo_problems()["latched"] == (2,)


# -- port lock -----------------------------------------------------------------------------------------


def test_a_second_controller_on_the_same_port_is_refused_naming_the_holder(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setenv("SERVOFACE_LOCK_DIR", str(tmp_path))
    chain = ServoChain.create(ids=[1], model="XL330-M288", wire_time=False)
    port = chain.serve_pty()
    try:
        first = open_bus("dynamixel", port=port)
        with pytest.raises(PortLockedError, match=f"process {os.getpid()}") as err:
            open_bus("dynamixel", port=port)
        assert err.value.holder_pid == os.getpid()
        first.reopen()  # a re-open keeps the lock
        with pytest.raises(PortLockedError):
            open_bus("dynamixel", port=port)
        first.close()
        second = open_bus("dynamixel", port=port)  # released on close
        second.ping(1)
        second.close()
    finally:
        chain.close()


def test_the_lock_dies_with_its_process(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setenv("SERVOFACE_LOCK_DIR", str(tmp_path))
    port = "/dev/pts/999999-not-a-port"
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time; from servoface.hardware.port_lock import PortLock; "
            f"PortLock({port!r}).acquire(); print('held', flush=True); time.sleep(60)",
        ],
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "SERVOFACE_LOCK_DIR": str(tmp_path)},
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        from servoface.hardware.port_lock import PortLock

        with pytest.raises(PortLockedError, match=f"process {holder.pid}"):
            PortLock(port).acquire()
        holder.send_signal(signal.SIGKILL)
        holder.wait(timeout=10)
        deadline = time.monotonic() + 10
        lock = PortLock(port)
        lock.acquire()  # the kernel dropped the dead holder's flock
        assert lock.held and time.monotonic() < deadline
        lock.release()
    finally:
        if holder.poll() is None:
            holder.kill()
            holder.wait()
