"""The driver on an emulated chain: configuration, torque-on pinning, one sync write per frame, telemetry."""

from __future__ import annotations

import dataclasses
import threading

import numpy as np
import pytest
from servoface.hardware.driver import Driver
from servoface.hardware.driver_thread import DriverThread
from servoface.hardware.errors import DriverThreadError, GoalRejectedError, ServoConfigMismatch
from servoface.hardware.servo_config import ServoSpec, configure_servo

from tests.hardware.driver_helpers import assert_goals_within_limits, make_driver, run

SYNC_WRITE, SYNC_READ, WRITE, FAST_SYNC_READ = 0x83, 0x82, 0x03, 0x8A


def test_configure_writes_eeprom_with_torque_off_and_verifies() -> None:
    chain, driver = make_driver(torque=False, return_delay_us=0, profile_velocity=120)
    servo = chain.servo(2)
    assert servo.read_register("MIN_POSITION_LIMIT") == 1500 and servo.read_register("MAX_POSITION_LIMIT") == 2600
    assert servo.read_register("RETURN_DELAY_TIME") == 0 and servo.read_register("PROFILE_VELOCITY") == 120
    # a servo left with torque on is switched off before EEPROM is touched; unchanged EEPROM is not rewritten
    servo.write_register("TORQUE_ENABLE", 1)
    report = configure_servo(
        driver.bus,
        ServoSpec(2, "XL330-M288", min_position_tick=1500, max_position_tick=2600, profile_velocity=120),
    )
    assert servo.read_register("TORQUE_ENABLE") == 0
    assert not [w for w in report.written if w in ("MIN_POSITION_LIMIT", "MAX_POSITION_LIMIT", "RETURN_DELAY_TIME")]


def test_wrong_model_is_a_typed_error_naming_the_servo() -> None:
    chain, driver = make_driver(torque=False)
    with pytest.raises(ServoConfigMismatch) as err:
        configure_servo(driver.bus, ServoSpec(3, "XM430-W350"))
    assert err.value.servo_id == 3 and err.value.field == "model_number"
    assert "servo 3" in str(err.value)


def test_torque_on_pins_goal_to_present_first() -> None:
    chain, driver = make_driver(torque=False)
    chain.servo(1).move_by_hand(1700)
    chain.servo(3).move_by_hand(500)  # outside its limits: pinned to the nearest limit
    driver.torque_on()
    goals = {sid: goal for _, sid, goal in chain.goal_writes()}
    assert goals[1] == 1700 and goals[3] == 1024
    assert chain.servo(1).torque_on and chain.servo(1).position_tick == 1700
    # the goal write came before the torque-enable write
    log = [(e.id, e.params[:2]) for e in chain.instructions(WRITE) if e.id == 1]
    assert log.index((1, bytes([116, 0]))) < log.index((1, bytes([64, 0])))


def test_one_sync_write_per_frame_and_servos_follow() -> None:
    chain, driver = make_driver()
    before = len(chain.instructions(SYNC_WRITE))
    snaps = run(chain, driver, {1: 2500, 2: 1600, 3: 1100, 4: 2050}, seconds=1.0)
    assert len(chain.instructions(SYNC_WRITE)) - before == len(snaps)
    last = snaps[-1]
    assert last.positions_tick() == {1: 2500, 2: 1600, 3: 1100, 4: 2050}
    assert last[1].goal_tick == 2500 and last[1].torque_on and last[1].ok
    assert assert_goals_within_limits(chain, driver) >= 4 * len(snaps)


@pytest.mark.parametrize(
    ("goals", "match"),
    [
        ({1: 2000, 2: 2700}, "outside its limits 1500..2600"),
        ({1: 2000.5}, "not an integer"),
        ({1: float("nan")}, "not finite"),
        ({1: float("inf")}, "not finite"),
        ({1: True}, "bool"),
        ({9: 2000}, "unknown servo id 9"),
        ({"jaw": 2000}, "unknown servo id 'jaw'"),
    ],
)
def test_bad_goals_refuse_the_whole_frame(goals: dict, match: str) -> None:  # type: ignore[type-arg]
    chain, driver = make_driver()
    sent = len(chain.goal_writes())
    n_sync = len(chain.instructions(SYNC_WRITE))
    with pytest.raises(GoalRejectedError, match=match):
        driver.cycle(goals)
    assert len(chain.goal_writes()) == sent and len(chain.instructions(SYNC_WRITE)) == n_sync


def test_numpy_integer_goals_are_accepted() -> None:
    chain, driver = make_driver()
    driver.cycle({1: np.int64(2222)})
    assert chain.goal_writes()[-1][1:] == (1, 2222)


def test_only_the_owner_thread_may_cycle() -> None:
    chain, driver = make_driver()
    errors: list[BaseException] = []

    def other() -> None:
        try:
            driver.cycle({})
        except BaseException as err:  # noqa: BLE001
            errors.append(err)

    t = threading.Thread(target=other)
    t.start()
    t.join()
    assert len(errors) == 1 and isinstance(errors[0], DriverThreadError)
    driver.cycle({})  # the owner still can


def test_snapshot_is_frozen() -> None:
    chain, driver = make_driver()
    snap = driver.cycle({})
    with pytest.raises(dataclasses.FrozenInstanceError):
        snap[1].position_tick = 5  # type: ignore[misc]
    with pytest.raises(TypeError):
        snap.servos[1] = snap[1]  # type: ignore[index]
    with pytest.raises(dataclasses.FrozenInstanceError):
        snap.stats.timeouts = 0  # type: ignore[misc]
    assert driver.snapshot() is snap


@pytest.mark.parametrize("fast", ["auto", False])  # auto: Fast Sync Read on this chain (0x8A), else 0x82
def test_slow_telemetry_is_round_robin_and_keeps_cycles_short(fast: bool | str) -> None:
    chain, driver = make_driver(fast_sync_read=fast)  # type: ignore[arg-type]
    read = FAST_SYNC_READ if driver.fast_sync_read else SYNC_READ
    assert driver.fast_sync_read == (fast == "auto")
    n_before = len(chain.instructions(read))
    snaps = run(chain, driver, {}, seconds=2.0)
    reads = chain.instructions(read)[n_before:]
    by_cycle: dict[float, list[tuple[int, int]]] = {}
    for e in reads:  # (start address, end address) of each Sync Read's block
        start = e.params[0] | e.params[1] << 8
        by_cycle.setdefault(round(e.t_s, 6), []).append((start, start + (e.params[2] | e.params[3] << 8)))
    assert max(len(v) for v in by_cycle.values()) <= 2  # positions + at most one slow group
    blocks = [b for v in by_cycle.values() for b in v]

    def covering(address: int) -> int:
        return sum(lo <= address < hi for lo, hi in blocks)

    # positions every cycle: through the sentinel (3 bytes at 224) in a plain cycle; a cycle that folds motion /
    # thermal in reads the direct block as without the sentinel (122..135 / 132..146)
    assert driver.sentinel_info.startswith("positions read through Indirect Data at 224")
    assert covering(224) + covering(132) == len(snaps) and (224, 227) in blocks
    assert 2 * 2 - 1 <= covering(144) <= 2 * 2 + 1  # thermal at 2 Hz
    assert 10 * 2 - 2 <= covering(122) <= 10 * 2 + 1  # motion at 10 Hz
    assert 10 * 2 - 2 <= covering(64) <= 10 * 2 + 1  # status at 10 Hz (the bus is idle between cycles)
    assert (122, 136) in blocks and (132, 147) in blocks  # folded into the position read's transaction
    last = snaps[-1][1]
    assert last.temperature_c == 25 and last.voltage_v == pytest.approx(5.0) and last.current_ma is not None


def test_fast_sync_read_option() -> None:
    chain, driver = make_driver()
    driver.fast_sync_read = True
    snaps = run(chain, driver, {1: 2600}, seconds=0.5)
    assert chain.instructions(0x8A) and snaps[-1][1].position_tick == 2600


def test_driver_thread_runs_cycles_in_the_background() -> None:
    chain = None
    from servoface.hardware.bus import open_bus
    from servoface.hardware.emulator import ServoChain

    chain = ServoChain.create(ids=[1, 2], model="XL330-M288", baud=1_000_000, wire_time=False)
    bus = open_bus("emulator", chain=chain)
    driver = Driver(
        bus,
        [
            ServoSpec(1, "XL330-M288", min_position_tick=1000, max_position_tick=3000),
            ServoSpec(2, "XL330-M288"),
        ],
    )
    driver.configure()
    with DriverThread(driver, rate_hz=200) as runner:
        runner.torque_on()
        with pytest.raises(GoalRejectedError):
            runner.submit_goals({1: 3500})
        first = runner.wait_snapshot()
        for _ in range(200):
            runner.submit_goals({1: 2900, 2: 100})
            snap = runner.wait_snapshot(after_cycle=first.cycle)
            first = snap
            if snap[1].position_tick == 2900 and snap[2].position_tick == 100:
                break
        assert snap[1].position_tick == 2900 and snap[2].position_tick == 100
        with pytest.raises(DriverThreadError):
            driver.cycle({})  # the test thread does not own the bus while the runner does
    assert not runner.running
    assert all(1000 <= g <= 3000 for _, sid, g in chain.goal_writes() if sid == 1)
    chain.close()


def test_driver_thread_reports_errors_to_callers() -> None:
    import time

    from servoface.hardware.bus import open_bus
    from servoface.hardware.emulator import ServoChain
    from servoface.hardware.errors import HardwareError

    chain = ServoChain.create(ids=[1], model="XL330-M288", baud=1_000_000, wire_time=False)
    driver = Driver(open_bus("emulator", chain=chain), [ServoSpec(1, "XL330-M288")])
    driver.configure()
    runner = DriverThread(driver, rate_hz=500).start()
    try:
        with pytest.raises(KeyError):
            runner.call(lambda d: d.clear_fault(99))  # the error of a queued call reaches its caller
        runner.call(lambda d: d.bus.close())  # a contract violation inside the loop stops the thread
        deadline = time.monotonic() + 5
        while runner.running and time.monotonic() < deadline:
            time.sleep(0.01)
        assert not runner.running and runner.error is not None
        with pytest.raises(HardwareError, match="driver thread stopped"):
            runner.submit_goals({1: 2000})
    finally:
        runner.stop()
        chain.close()


def test_fast_sync_read_falls_back_when_the_firmware_lacks_it(monkeypatch: pytest.MonkeyPatch) -> None:
    """A chain that stops answering Fast Sync Read after the start-up probe (forced on here), imitated at the
    bus: every Fast Sync Read fails, while everything else goes over the emulated wire. (A servo whose
    firmware lacks it from the start: tests/hardware/test_fast_read_auto.py.)"""
    from servoface.hardware.errors import BusTimeoutError

    chain, driver = make_driver()
    driver.fast_sync_read = True
    real_sync_read = driver.bus.sync_read

    def old_firmware(ids, registers, *, fast=False):  # type: ignore[no-untyped-def]
        if fast:
            raise BusTimeoutError("fast sync read: no reply", tuple(ids))
        return real_sync_read(ids, registers, fast=fast)

    real_start = driver.bus.sync_read_start

    def old_firmware_start(ids, registers, *, fast=False):  # type: ignore[no-untyped-def]
        if fast:  # the instruction goes out; the silence shows as a timeout, here at once
            raise BusTimeoutError("fast sync read: no reply", tuple(ids))
        return real_start(ids, registers, fast=fast)

    monkeypatch.setattr(driver.bus, "sync_read", old_firmware)
    monkeypatch.setattr(driver.bus, "sync_read_start", old_firmware_start)
    snaps = run(chain, driver, {1: 2600}, 0.5)
    assert not driver.fast_sync_read and snaps[-1][1].position_tick == 2600
    assert not any(s.missing or s.stale for s in snaps[-1])
    assert any("Fast Sync Read failed" in e.reaction for e in driver.events)


def test_model_mismatch_says_which_id_answered_as_which_model() -> None:
    """A wrong servo on an id reads as that, not as a failed write (issue 19)."""
    from servoface.hardware.errors import ServoModelMismatch

    chain, driver = make_driver(torque=False)
    with pytest.raises(ServoModelMismatch) as err:
        configure_servo(driver.bus, ServoSpec(3, "XL430-W250"))
    text = str(err.value)
    assert "servo 3" in text and "XL330-M288" in text and "1200" in text and "XL430-W250" in text and "1060" in text
    assert "after writing" not in text
