"""Moving servo (manual clock): profiles, limits, direction, Moving, Realtime Tick, heat, load, voltage."""

from __future__ import annotations

import pytest
from servoface.hardware.emulator import EmulatorConfigError, ServoChain
from servoface.hardware.emulator.servo_motion import ACC_UNIT_TICK_S2, VEL_UNIT_TICK_S


def one(model: str = "XL330-M288") -> tuple[ServoChain, object]:
    chain = ServoChain.create(ids=[1], model=model, wire_time=False, clock="manual")
    return chain, chain.servo(1)


def test_follows_goal_at_profile_velocity() -> None:
    chain, s = one()
    s.write_register("Profile Velocity", 100)
    s.write_register("Torque Enable", 1)
    s.write_register("Goal Position", 3048)
    chain.advance(0.25)
    expected = 2048 + 100 * VEL_UNIT_TICK_S * 0.25
    assert s.read_register("Present Position") == pytest.approx(expected, abs=1.0)
    assert s.read_register("Present Velocity") == 100
    assert s.read_register("Moving") == 1
    assert s.read_register("Moving Status") & 0x02
    chain.advance(1.0)
    assert s.read_register("Present Position") == 3048
    assert s.read_register("Moving") == 0 and s.read_register("Present Velocity") == 0
    assert s.read_register("Moving Status") & 0x01  # in position


def test_trapezoid_profile_accelerates_then_cruises() -> None:
    chain, s = one()
    s.write_register("Profile Velocity", 200)
    s.write_register("Profile Acceleration", 50)
    s.write_register("Torque Enable", 1)
    s.write_register("Goal Position", 4000)
    v_max = 200 * VEL_UNIT_TICK_S
    ramp_s = v_max / (50 * ACC_UNIT_TICK_S2)
    chain.advance(ramp_s / 2)
    assert s.read_register("Present Velocity") == pytest.approx(100, abs=3)
    chain.advance(ramp_s)
    assert s.read_register("Present Velocity") == 200
    chain.advance(5.0)
    assert s.read_register("Present Position") == 4000


def test_profile_velocity_zero_means_no_load_speed() -> None:
    chain, s = one()
    s.write_register("Torque Enable", 1)
    s.write_register("Goal Position", 4000)
    chain.advance(0.05)
    v_nl = s.spec.no_load_speed_tick_s
    v_lim = 445 * VEL_UNIT_TICK_S  # Velocity Limit is lower than the no-load speed on the XL330
    assert s.read_register("Present Position") == pytest.approx(2048 + min(v_nl, v_lim) * 0.05, abs=1.5)


def test_time_based_profile_arrives_on_time() -> None:
    chain, s = one()
    s.write_register("Drive Mode", 4)
    s.write_register("Profile Velocity", 800)  # ms total
    s.write_register("Profile Acceleration", 200)  # ms ramps
    s.write_register("Torque Enable", 1)
    s.write_register("Goal Position", 2548)
    chain.advance(0.7)
    assert 2048 < s.read_register("Present Position") < 2548
    chain.advance(0.12)
    assert s.read_register("Present Position") == 2548


def test_goal_clamped_to_position_limits() -> None:
    chain, s = one()
    s.write_register("Max Position Limit", 2500)
    s.write_register("Torque Enable", 1)
    s.write_register("Goal Position", 3500)  # test hook bypasses the wire's Data Limit Error
    chain.advance(2.0)
    assert s.read_register("Present Position") == 2500


def test_reverse_drive_mode_turns_the_shaft_the_other_way() -> None:
    chain, s = one()
    s.write_register("Drive Mode", 1)
    start_shaft = s.shaft_tick
    start = s.read_register("Present Position")
    s.write_register("Torque Enable", 1)
    s.write_register("Goal Position", start + 500)
    chain.advance(1.0)
    assert s.read_register("Present Position") == start + 500
    assert s.shaft_tick == pytest.approx(start_shaft - 500)


def test_realtime_tick_advances_in_ms_and_wraps() -> None:
    chain, s = one()
    t0 = s.read_register("Realtime Tick")
    chain.advance(0.123)
    assert s.read_register("Realtime Tick") == t0 + 123
    chain.advance(32.768)
    assert s.read_register("Realtime Tick") == t0 + 123  # wrapped at 32768 ms


def test_torque_off_does_not_drive_but_hand_moves() -> None:
    chain, s = one()
    s.write_register("Goal Position", 3000)
    chain.advance(1.0)
    assert s.read_register("Present Position") == 2048
    s.move_by_hand(1500)
    assert s.read_register("Present Position") == 1500
    s.write_register("Torque Enable", 1)
    with pytest.raises(EmulatorConfigError, match="torque off"):
        s.move_by_hand(1000)


def test_torque_on_goes_to_goal_register() -> None:
    chain, s = one()
    s.move_by_hand(1000)  # Goal Position still holds the power-up position
    s.write_register("Torque Enable", 1)
    chain.advance(1.0)
    assert s.read_register("Present Position") == 2048


def test_temperature_rises_with_load_trips_and_cools() -> None:
    chain, s = one()
    s.write_register("Shutdown", 0x04)  # overheating only, so the overload does not trip first
    chain.set_obstacle(1, at_tick=2100)
    s.write_register("Torque Enable", 1)
    s.write_register("Goal Position", 2600)
    chain.advance(5.0)
    t5 = s.temperature_c
    assert t5 > 30
    assert s.read_register("Hardware Error Status") & 0x20  # overload bit set, torque kept (not in Shutdown)
    assert s.read_register("Torque Enable") == 1
    for _ in range(120):  # stall on until the overheating trip
        chain.advance(0.5)
        if s.read_register("Hardware Error Status") & 0x04:
            break
    assert s.read_register("Hardware Error Status") & 0x04
    assert s.read_register("Torque Enable") == 0
    hot = s.temperature_c
    assert 69.0 <= hot < 72.0  # tripped at the 70 degC limit
    chain.advance(120.0)
    assert s.temperature_c < hot - 20
    assert s.read_register("Present Temperature") == round(s.temperature_c)


def test_obstacle_raises_load_and_trips_overload_after_a_sustained_period() -> None:
    chain, s = one("XL430-W250")
    chain.set_obstacle(1, at_tick=2100)
    s.write_register("Torque Enable", 1)
    s.write_register("Goal Position", 2600)
    chain.advance(0.5)
    assert s.read_register("Present Position") == 2100
    assert s.read_register("Present Load") == 1000  # 100 % of stall, 0.1 % units
    assert s.read_register("Hardware Error Status") == 0
    chain.advance(1.0)
    assert s.read_register("Hardware Error Status") & 0x20
    assert s.read_register("Torque Enable") == 0
    assert s.read_register("Present Load") == 0


def test_present_current_on_current_models() -> None:
    chain, s = one("XM430-W350")
    chain.set_obstacle(1, at_tick=2000)
    s.write_register("Goal Position", 1500)
    s.write_register("Torque Enable", 1)
    chain.advance(0.3)
    assert s.read_register("Present Current") == round(-2300 / 2.69)


def test_input_voltage_outside_limits_sets_bit() -> None:
    chain, s = one("XL330-M288")
    s.write_register("Torque Enable", 1)
    chain.set_input_voltage(1, 3.0)
    assert s.read_register("Present Input Voltage") == 30
    assert s.read_register("Hardware Error Status") & 0x01
    assert s.read_register("Torque Enable") == 0  # XL330 Shutdown 53 includes input voltage
    chain2, s2 = one("XL430-W250")
    s2.write_register("Torque Enable", 1)
    chain2.set_input_voltage(1, 15.0)
    assert s2.read_register("Hardware Error Status") & 0x01
    assert s2.read_register("Torque Enable") == 1  # XL430 Shutdown 52 does not


def test_reboot_keeps_errors_whose_cause_persists() -> None:
    chain, s = one("XL330-M288")
    chain.set_input_voltage(1, 3.0)
    s.reboot(0.0)
    assert s.read_register("Hardware Error Status") == 0x01
    chain.set_input_voltage(1, 5.0)
    s.reboot(0.0)
    assert s.read_register("Hardware Error Status") == 0


def test_torque_cannot_come_back_before_reboot() -> None:
    from tests.hardware.emulator.helpers import le, transact

    chain = ServoChain.create(ids=[1], wire_time=False, clock="manual")
    ser = chain.open_serial()
    chain.faults.inject(1, "overload", duration_s=0.001)
    chain.advance(0.01)
    (st,) = transact(ser, 1, 0x03, le(64, 2) + b"\x01")
    assert st.error == 0x80 | 1 and chain.servo(1).read_register("Torque Enable") == 0


def test_velocity_mode_turns_continuously() -> None:
    chain, s = one()
    s.write_register("Operating Mode", 1)
    s.write_register("Torque Enable", 1)
    s.write_register("Goal Velocity", 100)
    chain.advance(1.0)
    assert s.read_register("Present Position") == pytest.approx(2048 + 100 * VEL_UNIT_TICK_S, abs=1)


def test_bus_watchdog_stops_and_rejects_goals() -> None:
    from tests.hardware.emulator.helpers import le, transact

    chain = ServoChain.create(ids=[1], wire_time=False, clock="manual")
    ser = chain.open_serial()
    s = chain.servo(1)
    s.write_register("Torque Enable", 1)
    assert transact(ser, 1, 0x03, le(98, 2) + b"\x05")[0].error == 0  # 100 ms
    chain.advance(0.05)
    assert transact(ser, 1, 0x03, le(116, 2) + le(3000, 4))[0].error == 0
    chain.advance(0.2)
    assert s.read_register("Bus Watchdog") == -1
    assert transact(ser, 1, 0x03, le(116, 2) + le(2500, 4))[0].error == 4  # Data Range
    assert transact(ser, 1, 0x03, le(98, 2) + b"\x00")[0].error == 0
    assert transact(ser, 1, 0x03, le(116, 2) + le(2500, 4))[0].error == 0


def test_live_registers_saturate_instead_of_crashing() -> None:
    chain, s = one()
    s.write_register("Operating Mode", 4)
    s.move_by_hand(3e9)
    assert s.read_register("Present Position") == (1 << 31) - 1
    s.move_by_hand(-1500)
    assert s.read_register("Present Position") == -1500


def test_moving_threshold_and_in_position_bits_after_arrival() -> None:
    chain, s = one("XM430-W350")
    s.write_register("Torque Enable", 1)
    s.write_register("Goal Position", 2100)
    chain.advance(0.001)
    assert s.read_register("Moving") == 1 and not s.read_register("Moving Status") & 0x01
    chain.advance(1.0)
    assert s.read_register("Moving") == 0 and s.read_register("Moving Status") & 0x01
    assert s.read_register("Position Trajectory") == 2100


def test_homing_offset_shifts_present_and_goal_frames() -> None:
    chain, s = one()
    s.write_register("Homing Offset", 1000)
    assert s.read_register("Present Position") == 3048
    s.write_register("Torque Enable", 1)
    s.write_register("Goal Position", 3100)
    chain.advance(1.0)
    assert s.read_register("Present Position") == 3100
    assert s.shaft_tick == pytest.approx(2100)
