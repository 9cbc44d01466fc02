"""Each fault kind the emulator can inject, and the driver's documented reaction (README "Faults").

Every test also audits the wire: no Goal Position outside a servo's configured limits was ever sent.
"""

from __future__ import annotations

import pytest
from servoface.hardware.fault_policy import FaultPolicy
from servoface.hardware.registers import Register
from servoface.hardware.snapshot import FaultKind

from tests.hardware.driver_helpers import assert_goals_within_limits, events_of, make_driver, run

SYNC_READ, REBOOT = 0x82, 0x08
GOALS = {1: 2500, 2: 1600, 3: 1100, 4: 2050}


def _sync_read_ids(chain, since: int = 0) -> list[list[int]]:  # type: ignore[no-untyped-def]
    return [list(e.params[4:]) for e in chain.instructions(SYNC_READ)[since:]]


def test_missing_servo_is_marked_others_continue_and_it_is_reconnected() -> None:
    chain, driver = make_driver()
    run(chain, driver, GOALS, 0.2)
    chain.faults.inject(3, "no_reply", duration_s=1.0)
    snaps = run(chain, driver, {**GOALS, 1: 2000}, 0.5)
    assert snaps[-1][3].missing and not snaps[-1][1].missing
    assert snaps[-1][1].position_tick == 2000  # the others kept moving
    assert len(events_of(driver, FaultKind.MISSING, 3)) == 1
    n = len(chain.instructions(SYNC_READ))
    run(chain, driver, GOALS, 0.2)
    assert all(3 not in ids for ids in _sync_read_ids(chain, n))  # excluded from group reads
    assert all(sid != 3 for t, sid, _ in chain.goal_writes() if t > chain.time_s - 0.15)  # and from goal frames
    snaps = run(chain, driver, GOALS, 1.0)
    assert not snaps[-1][3].missing and snaps[-1][3].torque_on
    assert events_of(driver, FaultKind.RECONNECTED, 3)
    assert snaps[-1][3].position_tick == 1100
    assert_goals_within_limits(chain, driver)


@pytest.mark.parametrize("kind", ["no_reply", "corrupt_crc", "dropped_bytes"])
def test_transient_reply_faults_are_retried_and_counted_not_fatal(kind: str) -> None:
    chain, driver = make_driver()
    run(chain, driver, GOALS, 0.1)
    chain.faults.inject(2, kind, duration_s=0.005)  # one cycle's worth (the manual clock stands still within it)
    snap = driver.cycle(GOALS)
    assert snap[2].stale and not snap[2].missing
    assert not snap[1].stale and snap[1].position_tick == 2500  # read individually after the group failed
    failures = snap.stats.timeouts + snap.stats.corrupt
    assert failures >= 2  # the group read and its retry at least
    chain.advance(0.01)
    snaps = run(chain, driver, GOALS, 0.2)
    assert not snaps[-1][2].stale and not snaps[-1][2].missing
    assert not events_of(driver, FaultKind.MISSING)
    assert_goals_within_limits(chain, driver)


def test_late_reply_is_not_mistaken_for_the_next_answer() -> None:
    chain, driver = make_driver()
    run(chain, driver, GOALS, 0.2)
    chain.faults.inject(4, "late_reply", duration_s=0.005, delay_s=0.012)
    driver.cycle({**GOALS, 1: 1500})
    snaps = run(chain, driver, {**GOALS, 1: 1500}, 0.4)
    for s in snaps[2:]:
        assert s[4].position_tick == 2050 and s[1].position_tick is not None
    assert snaps[-1][1].position_tick == 1500 and not snaps[-1][4].missing
    assert_goals_within_limits(chain, driver)


def test_overload_torque_off_cool_down_reboot_and_repin() -> None:
    chain, driver = make_driver()
    run(chain, driver, GOALS, 0.2)
    chain.faults.inject(2, "overload", duration_s=0.05)
    snaps = run(chain, driver, {**GOALS, 2: 2500}, 0.3)
    assert FaultKind.OVERLOAD in snaps[-1][2].faults and not snaps[-1][2].torque_on
    assert not chain.servo(2).torque_on
    t_fault = events_of(driver, FaultKind.OVERLOAD, 2)[0].t_s
    # while it is down, no goals go to it
    assert not [g for t, sid, g in chain.goal_writes() if sid == 2 and t > t_fault + 0.02]
    snaps = run(chain, driver, {**GOALS, 2: 2500}, 2.5)
    reboot = events_of(driver, FaultKind.REBOOTED, 2)
    assert len(reboot) == 1 and reboot[0].t_s >= t_fault + driver.policy.overload_cooldown_s - 1e-9
    assert [e for e in chain.instructions(REBOOT) if e.id == 2]
    recovered = events_of(driver, FaultKind.RECOVERED, 2)
    assert recovered and snaps[-1][2].torque_on and snaps[-1][2].ok
    first_goal_after = next(g for t, sid, g in chain.goal_writes() if sid == 2 and t >= recovered[0].t_s)
    assert first_goal_after == chain.servo(2).position_tick or 1500 <= first_goal_after <= 2600  # re-pinned
    assert assert_goals_within_limits(chain, driver)


def test_persistent_overload_latches_after_max_reboots() -> None:
    chain, driver = make_driver()
    chain.faults.inject(1, "overload")  # never ends: the bit comes back after every reboot
    snaps = run(chain, driver, GOALS, 12.0, dt_s=0.05)
    assert len(events_of(driver, FaultKind.REBOOTED, 1)) == driver.policy.max_reboots
    assert events_of(driver, FaultKind.LATCHED, 1)
    assert FaultKind.LATCHED in snaps[-1][1].faults and not snaps[-1][1].torque_on
    assert snaps[-1][2].ok  # the rest of the chain is unaffected
    driver.clear_fault(1)
    chain.faults.clear(1)
    snaps = run(chain, driver, GOALS, 0.5)
    assert snaps[-1][1].torque_on and FaultKind.LATCHED not in snaps[-1][1].faults
    assert_goals_within_limits(chain, driver)


def test_high_load_eases_goals_toward_present() -> None:
    chain, driver = make_driver()
    run(chain, driver, {1: 2000}, 0.3)
    chain.set_obstacle(1, 2200)
    snaps = run(chain, driver, {1: 2900}, 1.0)
    assert events_of(driver, FaultKind.LOAD_BACKOFF, 1)
    last_goal = [g for _, sid, g in chain.goal_writes() if sid == 1][-1]
    assert 2200 <= last_goal < 2900 - 300  # eased toward the obstacle, far below the requested goal
    assert abs(chain.servo(1).load_fraction) < 0.9  # below the servo's overload threshold: no trip
    assert not chain.servo(1).hardware_error
    chain.set_obstacle(1, None)
    snaps = run(chain, driver, {1: 2900}, 2.0)
    assert snaps[-1][1].position_tick == 2900 and FaultKind.LOAD_BACKOFF not in snaps[-1][1].faults
    assert_goals_within_limits(chain, driver)


def test_rising_temperature_derates_then_torques_off_before_the_limit() -> None:
    chain, driver = make_driver()
    servo = chain.servo(3)
    limit = servo.read_register("TEMPERATURE_LIMIT")
    temperature = 40.0
    derate_at = off_at = None
    for _ in range(1200):  # 0.5 C/s rise, cycles at 20 Hz of chain time
        servo.temperature_c = temperature
        snap = driver.cycle(GOALS)
        if derate_at is None and FaultKind.THERMAL_DERATE in snap[3].faults:
            derate_at = temperature
        if FaultKind.THERMAL_TORQUE_OFF in snap[3].faults:
            off_at = temperature
            break
        chain.advance(0.05)
        temperature += 0.5 * 0.05
    assert derate_at is not None and off_at is not None
    assert derate_at < limit - driver.policy.thermal_margin_c  # acted on the rate, not on the level
    assert off_at < limit - driver.policy.thermal_off_margin_c
    assert not servo.torque_on and not servo.hardware_error  # we got there before the servo's own shutdown
    assert servo.read_register("PROFILE_VELOCITY") == driver.policy.derate_profile_velocity
    assert snap[3].seconds_to_temperature_limit is not None
    # cooling down: back in service, goal re-pinned, profile restored once well below the limit
    servo.temperature_c = limit - driver.policy.thermal_resume_margin_c - 5
    snaps = run(chain, driver, GOALS, 3.0, dt_s=0.05)
    assert snaps[-1][3].torque_on and events_of(driver, FaultKind.RECOVERED, 3)
    assert_goals_within_limits(chain, driver)


def test_overheating_bit_waits_for_cool_down_then_reboots() -> None:
    chain, driver = make_driver()
    servo = chain.servo(1)
    run(chain, driver, GOALS, 0.2)
    servo.temperature_c = 75.0  # above the 70 C limit: the servo trips its overheating bit
    snaps = run(chain, driver, GOALS, 1.0)
    assert FaultKind.OVERHEATING in snaps[-1][1].faults and not servo.torque_on
    assert not events_of(driver, FaultKind.REBOOTED, 1)  # still hot: no reboot yet
    servo.temperature_c = 50.0
    snaps = run(chain, driver, GOALS, 1.5)
    assert events_of(driver, FaultKind.REBOOTED, 1) and snaps[-1][1].torque_on
    assert_goals_within_limits(chain, driver)


def test_low_voltage_derates_and_undervoltage_trip_recovers() -> None:
    chain, driver = make_driver()
    run(chain, driver, GOALS, 0.2)
    chain.set_input_voltage(None, 3.6)  # below the XL330's 3.7 V recommended minimum, above its 3.5 V limit
    snaps = run(chain, driver, GOALS, 1.5)
    assert len(events_of(driver, FaultKind.VOLTAGE_LOW)) == 4 and all(s.derated for s in snaps[-1])
    assert all(s.torque_on for s in snaps[-1])
    chain.set_input_voltage(2, 3.0)  # below the Min Voltage Limit: the servo shuts itself down
    snaps = run(chain, driver, GOALS, 0.5)
    assert not chain.servo(2).torque_on and snaps[-1][2].hardware_error
    chain.set_input_voltage(None, 5.0)
    snaps = run(chain, driver, GOALS, 2.5)
    assert snaps[-1][2].torque_on and events_of(driver, FaultKind.REBOOTED, 2)
    assert not any(s.derated for s in snaps[-1]) and all(s.ok for s in snaps[-1])
    assert_goals_within_limits(chain, driver)


def test_high_voltage_torques_off_until_back_in_range() -> None:
    chain, driver = make_driver()
    run(chain, driver, GOALS, 0.2)
    chain.set_input_voltage(4, 6.5)
    snaps = run(chain, driver, GOALS, 1.5)
    assert FaultKind.VOLTAGE_HIGH in snaps[-1][4].faults and not chain.servo(4).torque_on
    chain.set_input_voltage(4, 5.0)
    snaps = run(chain, driver, GOALS, 1.5)
    assert snaps[-1][4].torque_on and events_of(driver, FaultKind.RECOVERED, 4)
    assert_goals_within_limits(chain, driver)


@pytest.mark.parametrize("kind", ["encoder", "electrical_shock"])
def test_encoder_and_shock_errors_latch_until_cleared(kind: str) -> None:
    chain, driver = make_driver()
    chain.faults.inject(2, kind, duration_s=0.05)
    snaps = run(chain, driver, GOALS, 3.0)
    assert FaultKind.HARDWARE_ERROR in snaps[-1][2].faults and not chain.servo(2).torque_on
    assert not events_of(driver, FaultKind.REBOOTED, 2)
    driver.clear_fault(2)
    snaps = run(chain, driver, GOALS, 0.5)
    assert events_of(driver, FaultKind.REBOOTED, 2) and snaps[-1][2].torque_on and snaps[-1][2].ok
    assert_goals_within_limits(chain, driver)


def test_servo_power_loss_and_return_is_reconfigured_and_repinned() -> None:
    chain, driver = make_driver(profile_velocity=200)
    run(chain, driver, GOALS, 0.2)
    chain.faults.inject(4, "disconnect", duration_s=0.5)
    snaps = run(chain, driver, GOALS, 0.4)
    assert snaps[-1][4].missing
    snaps = run(chain, driver, GOALS, 1.0)
    assert not snaps[-1][4].missing and snaps[-1][4].torque_on
    assert chain.servo(4).read_register("PROFILE_VELOCITY") == 200  # RAM re-configured after the power-up
    assert events_of(driver, FaultKind.RECONNECTED, 4)
    assert_goals_within_limits(chain, driver)


def test_servo_reset_without_error_is_detected() -> None:
    chain, driver = make_driver()
    run(chain, driver, GOALS, 0.2)
    chain.servo(1).reboot(0.0)  # e.g. a brown-out: RAM defaults, torque off
    snaps = run(chain, driver, GOALS, 0.5)
    assert events_of(driver, FaultKind.RECONNECTED, 1) and snaps[-1][1].torque_on and chain.servo(1).torque_on
    assert_goals_within_limits(chain, driver)


def test_port_failure_marks_everything_missing_and_reopens() -> None:
    chain, driver = make_driver()
    run(chain, driver, GOALS, 0.2)
    driver.bus._port.ser.close()  # type: ignore[attr-defined]  # the adapter vanished
    snap = driver.cycle(GOALS)
    assert not snap.bus_connected and all(s.missing for s in snap)
    assert events_of(driver, FaultKind.DISCONNECTED)
    chain.advance(0.01)
    snaps = run(chain, driver, GOALS, 1.0)
    assert snaps[-1].bus_connected and all(s.torque_on and not s.missing for s in snaps[-1])
    assert snaps[-1].positions_tick() == GOALS
    assert_goals_within_limits(chain, driver)


def test_servo_missing_at_start_is_configured_when_it_appears() -> None:
    from servoface.hardware.bus import open_bus
    from servoface.hardware.driver import Driver
    from servoface.hardware.emulator import ServoChain
    from servoface.hardware.errors import BusTimeoutError
    from servoface.hardware.servo_config import ServoSpec

    chain = ServoChain.create(ids=[1, 2], model="XL330-M288", wire_time=False, clock="manual")
    chain.faults.inject(2, "disconnect", duration_s=0.3)
    specs = [
        ServoSpec(i, "XL330-M288", min_position_tick=1000, max_position_tick=3000, profile_velocity=99) for i in (1, 2)
    ]
    strict = Driver(open_bus("emulator", chain=chain), specs, clock=chain.clock)
    with pytest.raises(BusTimeoutError):
        strict.configure()
    driver = Driver(open_bus("emulator", chain=chain), specs, clock=chain.clock)
    driver.configure(allow_missing=True)
    driver.torque_on()
    snaps = run(chain, driver, {1: 2900, 2: 1100}, 0.2)
    assert snaps[-1][2].missing and snaps[-1][1].position_tick > 2048  # the other one is on its way
    snaps = run(chain, driver, {1: 2900, 2: 1100}, 2.0)
    assert snaps[-1][2].torque_on and snaps[-1][2].position_tick == 1100 and snaps[-1][1].position_tick == 2900
    assert chain.servo(2).read_register("PROFILE_VELOCITY") == 99 and chain.servo(2).read_register(52) == 1000
    assert_goals_within_limits(chain, driver)


def test_alert_bit_on_a_single_transaction_triggers_an_immediate_status_read() -> None:
    from servoface.hardware.fault_policy import FaultPolicy

    chain, driver = make_driver(policy=FaultPolicy(status_hz=0.1))  # polling alone would take 10 s
    run(chain, driver, GOALS, 0.5)  # the first status read is done; the next is 10 s away
    chain.faults.inject(1, "overload", duration_s=0.01)
    chain.advance(0.02)
    driver.bus.read(1, Register.PRESENT_TEMPERATURE)  # any single transaction: its status has the Alert bit
    assert 1 in driver.bus.alerts
    snap = driver.cycle(GOALS)
    assert FaultKind.OVERLOAD in snap[1].faults and any(e.kind is FaultKind.OVERLOAD for e in snap.events)
    assert not driver.bus.alerts


@pytest.mark.parametrize("kind", ["no_reply", "corrupt_crc", "dropped_bytes"])
def test_a_reply_lost_during_configure_is_retried_not_fatal(kind: str) -> None:
    from servoface.hardware.bus import open_bus
    from servoface.hardware.driver import Driver
    from servoface.hardware.emulator import ServoChain
    from servoface.hardware.errors import BusError
    from servoface.hardware.servo_config import ServoSpec

    def chain_and_specs() -> tuple[ServoChain, list[ServoSpec]]:
        chain = ServoChain.create(ids=[1, 2, 3], model="XL330-M288", wire_time=False, clock="manual")
        specs = [ServoSpec(i, "XL330-M288", min_position_tick=1000, max_position_tick=3000) for i in (1, 2, 3)]
        return chain, specs

    chain, specs = chain_and_specs()
    chain.faults.inject(2, kind, replies=2)  # exactly two of servo 2's replies are lost or garbled
    driver = Driver(open_bus("emulator", chain=chain), specs, clock=chain.clock)
    reports = driver.configure()
    assert sorted(reports) == [1, 2, 3] and reports[2].limits[Register.MAX_POSITION_LIMIT] == 3000
    assert chain.servo(2).read_register("MAX_POSITION_LIMIT") == 3000
    assert not events_of(driver, FaultKind.MISSING)

    chain, specs = chain_and_specs()  # with one attempt only (the old behaviour), the same loss is fatal
    chain.faults.inject(2, kind, replies=1)
    strict = Driver(
        open_bus("emulator", chain=chain), specs, policy=FaultPolicy(configure_attempts=1), clock=chain.clock
    )
    with pytest.raises(BusError):
        strict.configure()
