"""The optional non-ideal servo (``realism=``): off by default; on, servos land near, not exactly on, goal.

Magnitudes and their sources are in ``servoface.hardware.emulator.realism`` (MX-28(2.0) e-manual backlash
20 arcmin, the XL330 page's 12-bit AS5601 encoder, ferrite magnet tempco)."""

from __future__ import annotations

import statistics

import pytest
from servoface.hardware.emulator import EmulatorConfigError, Instruction, Realism, ServoChain

from tests.hardware.emulator.helpers import le, transact


def _chain(realism: object = None) -> tuple[ServoChain, object]:
    chain = ServoChain.create(ids=[1], wire_time=False, clock="manual", realism=realism)  # type: ignore[arg-type]
    ser = chain.open_serial()
    for addr, value, size in ((64, 1, 1), (116, 3000, 4)):
        assert transact(ser, 1, Instruction.WRITE, le(addr, 2) + le(value, size))[0].error == 0
    return chain, ser


def _present(ser: object) -> int:
    (st,) = transact(ser, 1, Instruction.READ, le(132, 2) + le(4, 2))  # type: ignore[arg-type]
    return int.from_bytes(st.data, "little", signed=True)


def test_off_by_default_lands_exactly() -> None:
    chain, ser = _chain()
    chain.advance(2.0)
    assert {_present(ser) for _ in range(20)} == {3000}
    assert chain.realism is None


def test_on_lands_near_goal_with_a_settling_error_and_encoder_noise() -> None:
    """Settling error of a few ticks (backlash half-play + holding error), readings spread by +-1 tick."""
    chain, ser = _chain(True)
    chain.advance(2.0)
    readings = [_present(ser) for _ in range(200)]
    assert len(set(readings)) > 1  # encoder noise
    assert max(readings) - min(readings) <= 2
    error = statistics.mean(readings) - 3000
    assert -8 < error < -1  # approached from below: short of the goal
    assert chain.servo(1).position_tick != 3000


def test_lag_grows_with_speed() -> None:
    """Mid-move the physical output trails the ideal profile (load error and lag), more when faster."""
    trail = []
    for profile_velocity in (50, 200):
        chain = ServoChain.create(ids=[1], wire_time=False, clock="manual", realism=True)
        servo = chain.servo(1)
        servo.write_register("Profile Velocity", profile_velocity)
        servo.write_register("Torque Enable", 1)
        servo.write_register("Goal Position", 4000)
        chain.advance(0.3)
        trail.append(servo.motor.pos - servo.physical_tick)
    assert 0 < trail[0] < trail[1]


def test_reproducible_by_seed_and_current_rises_with_temperature() -> None:
    a, sa = _chain({"seed": 5})
    b, sb = _chain({"seed": 5})
    a.advance(1.0)
    b.advance(1.0)
    assert [_present(sa) for _ in range(30)] == [_present(sb) for _ in range(30)]
    cold = a.servo(1).read_register("Present Current")
    a.servo(1).temperature_c = 65.0
    hot = a.servo(1).read_register("Present Current")
    assert hot > cold > 0


def test_bad_realism_is_a_typed_error() -> None:
    with pytest.raises(EmulatorConfigError, match="backlash_tick"):
        ServoChain.create(ids=[1], realism={"backlash_tick": -1})
    with pytest.raises(EmulatorConfigError, match="unknown"):
        ServoChain.create(ids=[1], realism={"wobble": 1})
    assert Realism().backlash_tick == pytest.approx(20 / 60 * 4096 / 360, abs=0.05)
