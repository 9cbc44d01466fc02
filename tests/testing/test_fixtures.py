"""The test kit's fixtures on the emulator: chains of an explicit list or a head, in-process or served by
another process, manual and real clock, faults, and the wire checks failing with the servo's name."""

from __future__ import annotations

import os

import pytest
from servoface.hardware.emulator import ServoChain
from servoface.hardware.registers import Register
from servoface.testing import LocalChain, ServedChain, WireRecord


def test_default_chain_is_four_xl330_in_process(servo_chain, servo_specs, dxl_bus) -> None:  # type: ignore[no-untyped-def]
    assert isinstance(servo_chain, LocalChain) and isinstance(servo_chain.chain, ServoChain)
    assert servo_chain.ids == [1, 2, 3, 4] == [s.servo_id for s in servo_specs]
    assert {s.min_position_tick for s in servo_specs} == {1024} and {s.max_position_tick for s in servo_specs} == {3072}
    assert dxl_bus.ping(3).model_number == 1200


def test_a_driver_that_behaves_passes_every_wire_check(driver, servo_wire) -> None:  # type: ignore[no-untyped-def]
    driver.torque_on()
    start = driver.read_state().positions_tick()
    for k in range(1, 11):  # a slow ramp, well inside the caps
        driver.cycle({sid: tick + 5 * k for sid, tick in start.items()})
    record = servo_wire.assert_safe()
    assert len(record.goals) >= 40
    servo_wire.assert_torque_on()
    servo_wire.assert_final_positions({sid: tick + 50 for sid, tick in start.items()}, within_s=2.0)
    driver.torque_off()
    servo_wire.assert_torque_off()


def test_a_goal_outside_the_limits_fails_naming_the_servo(dxl_bus, servo_wire) -> None:  # type: ignore[no-untyped-def]
    dxl_bus.write(2, Register.TORQUE_ENABLE, 1)
    present = dxl_bus.read(2, Register.PRESENT_POSITION)
    dxl_bus.write(2, Register.GOAL_POSITION, 3500)  # no limits written on the servo: it takes it
    with pytest.raises(
        AssertionError, match=r"servo 2 'servo_2': goal 3500 tick outside its servo specs limits 1024\.\.3072"
    ):
        servo_wire.assert_goals_within_limits()
    with pytest.raises(
        AssertionError,
        match=rf"servo 2 'servo_2': goal 3500 tick is a step of {3500 - present} tick from where it stood",
    ):
        servo_wire.assert_goal_steps_within_caps()
    with pytest.raises(AssertionError, match=r"torque left on at the end, expected off"):
        servo_wire.assert_torque_off([2])
    servo_wire.assert_torque_off([1, 3, 4])


def test_a_goal_while_torque_is_off_fails_unless_it_pins(dxl_bus, servo_wire) -> None:  # type: ignore[no-untyped-def]
    present = dxl_bus.read(4, Register.PRESENT_POSITION)
    dxl_bus.write(4, Register.GOAL_POSITION, present)  # the pin before torque-on: fine
    servo_wire.assert_no_goal_while_torque_off()
    dxl_bus.write(4, Register.GOAL_POSITION, present + 300)
    with pytest.raises(
        AssertionError, match=rf"servo 4 'servo_4': goal {present + 300} tick written while its torque was off"
    ):
        servo_wire.assert_no_goal_while_torque_off()


def test_speeding_up_too_fast_fails(dxl_bus, servo_wire) -> None:  # type: ignore[no-untyped-def]
    dxl_bus.write(1, Register.TORQUE_ENABLE, 1)
    present = dxl_bus.read(1, Register.PRESENT_POSITION)
    cap, speedup = servo_wire.limits.caps(1)
    dxl_bus.write(1, Register.GOAL_POSITION, present + speedup)  # from rest: at most one speed-up step
    assert 2 * speedup + 1 <= cap
    dxl_bus.write(1, Register.GOAL_POSITION, present + 3 * speedup + 1)  # speeds up by one tick/frame^2 too many
    with pytest.raises(AssertionError, match=r"servo 1 'servo_1': step .* speeds up beyond"):
        servo_wire.assert_goal_steps_within_caps()


def test_no_goal_at_all_is_not_a_pass(servo_wire, servo_chain) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(AssertionError, match="only 0 goal write"):
        servo_wire.assert_safe()


@pytest.mark.servoface(head="dog", transport="pty")
def test_a_heads_mixed_models_served_by_another_process(servo_chain, servo_port, dxl_bus, calibration) -> None:  # type: ignore[no-untyped-def]
    assert isinstance(servo_chain, ServedChain) and servo_chain.pid != os.getpid()
    assert servo_port == servo_chain.path and servo_port.startswith("/dev/")
    models = {sid: dxl_bus.ping(sid).model_number for sid in servo_chain.ids}
    assert set(models.values()) == {1200, 1060, 1020}  # XL330-M288, XL430-W250, XM430-W350
    jaw = calibration.id_of("jaw")
    assert (
        calibration.head == "dog"
        and servo_chain.read_register(jaw, "Present Position") == calibration["jaw"].neutral_tick
    )
    record = servo_chain.record()
    assert isinstance(record, WireRecord) and record.goals == () and "pty" in record.source


@pytest.mark.servoface(servos="1:XL330-M288,7:XM430-W350", transport="pty", clock="manual")
def test_manual_clock_over_the_pty_moves_only_when_advanced(servo_chain, dxl_bus) -> None:  # type: ignore[no-untyped-def]
    start = dxl_bus.read(7, Register.PRESENT_POSITION)
    dxl_bus.write(7, Register.TORQUE_ENABLE, 1)
    dxl_bus.write(7, Register.GOAL_POSITION, start + 200)
    assert dxl_bus.read(7, Register.PRESENT_POSITION) == start
    servo_chain.advance(2.0)
    assert dxl_bus.read(7, Register.PRESENT_POSITION) == start + 200
    assert servo_chain.time_s == pytest.approx(2.0)


@pytest.mark.parametrize("transport", ["inprocess", "pty"])
def test_faults_scripted_in_chain_time(make_servo_chain, transport: str) -> None:  # type: ignore[no-untyped-def]
    from servoface.hardware.bus import open_bus
    from servoface.hardware.errors import BusTimeoutError

    chain = make_servo_chain(servos=[1, 2], transport=transport, clock="manual", wire_time=False)
    chain.inject(2, "no_reply", after_s=1.0, duration_s=0.5)
    bus = open_bus("dynamixel", port=chain.port, baud=1_000_000)
    try:
        assert bus.ping(2).servo_id == 2
        chain.advance(1.2)
        with pytest.raises(BusTimeoutError):
            bus.ping(2)
        assert bus.ping(1).servo_id == 1
        chain.advance(0.5)
        assert bus.ping(2).servo_id == 2
    finally:
        bus.close()


@pytest.mark.servoface(faults=[(3, "overload", 0.0)])
def test_faults_from_the_marker(servo_chain, dxl_bus) -> None:  # type: ignore[no-untyped-def]
    assert dxl_bus.read(3, Register.HARDWARE_ERROR_STATUS) & 0x20
    assert dxl_bus.read(1, Register.HARDWARE_ERROR_STATUS) == 0


def test_the_record_survives_json(servo_chain, dxl_bus) -> None:  # type: ignore[no-untyped-def]
    dxl_bus.write(1, Register.GOAL_POSITION, 2000)
    dxl_bus.write(1, Register.TORQUE_ENABLE, 1)
    record = servo_chain.record()
    assert WireRecord.from_json(record.to_json()) == record
    assert [(g.servo_id, g.goal_tick, g.torque_on) for g in record.goals] == [(1, 2000, False)]
    assert [(w.servo_id, w.value) for w in record.torque_writes] == [(1, 1)]
    assert record.end[1].torque_on and not record.end[2].torque_on


@pytest.mark.servoface(head="human")
def test_a_face_on_the_chain_matches_its_twin(face, servo_wire, servo_chain) -> None:  # type: ignore[no-untyped-def]
    face.set_aus({"AU12": 0.5, "AU6": 0.3}, transition_s=0.3, hold_s=0.4)
    servo_wire.assert_safe()
    servo_wire.assert_torque_on()
    servo_wire.assert_matches_twin(face, tolerance_tick=1, within_s=2.0)


def test_a_servo_standing_outside_its_limits_may_be_pinned_towards_them(servo_chain, dxl_bus, servo_wire) -> None:  # type: ignore[no-untyped-def]
    servo_chain.move_by_hand(3, 3200)  # outside 1024..3072, torque off
    for goal in (3200, 3100, 3072):  # where it stands, or anywhere towards the nearest limit
        dxl_bus.write(3, Register.GOAL_POSITION, goal)
    servo_wire.assert_no_goal_while_torque_off()
    dxl_bus.write(3, Register.GOAL_POSITION, 2048)  # a jump of 1152 tick at torque-on
    with pytest.raises(AssertionError, match=r"servo 3 'servo_3': goal 2048 tick written while its torque was off"):
        servo_wire.assert_no_goal_while_torque_off()


@pytest.mark.servoface(head="human")
def test_a_servo_away_from_the_twin_is_named_with_its_targets(face, servo_chain, servo_wire, calibration) -> None:  # type: ignore[no-untyped-def]
    face.set_aus({"AU26": 0.5}, transition_s=0.2, hold_s=0.2)
    jaw = calibration.id_of("jaw")
    servo_wire.assert_matches_twin(face, within_s=2.0)
    there = face.pipeline.last_goals_tick[jaw]
    servo_chain.write_register(jaw, "Torque Enable", 0)  # lost torque and pushed: not where the twin has it
    servo_chain.move_by_hand(jaw, there + 40)
    with pytest.raises(
        AssertionError, match=rf"servo {jaw} 'jaw': stands at \d+ tick, the twin has it at {there} tick"
    ) as err:
        servo_wire.assert_matches_twin(face, within_s=1.0)
    assert "'jaw': stands at" in str(err.value) and "the twin's target" in str(err.value)
