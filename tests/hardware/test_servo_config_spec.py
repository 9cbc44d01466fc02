"""Servo descriptions: invalid ones are refused with the servo id and the field named."""

from __future__ import annotations

import pytest
from servoface.hardware.errors import ServoDescriptionError
from servoface.hardware.registers import HardwareErrorBits, OperatingMode, Register
from servoface.hardware.servo_config import ServoSpec, check_specs


def test_valid_spec_gives_register_values() -> None:
    spec = ServoSpec(
        3,
        "XL330-M288",
        role="jaw",
        min_position_tick=1500,
        max_position_tick=2600,
        profile_velocity=100,
        return_delay_us=4,
        temperature_limit_c=65,
    )
    eeprom = spec.eeprom_values()
    assert eeprom[Register.MIN_POSITION_LIMIT] == 1500 and eeprom[Register.MAX_POSITION_LIMIT] == 2600
    assert eeprom[Register.RETURN_DELAY_TIME] == 2  # 2 us units
    assert eeprom[Register.SHUTDOWN] == 0x35  # XL330 default incl. input voltage
    assert eeprom[Register.TEMPERATURE_LIMIT] == 65
    assert spec.ram_values()[Register.PROFILE_VELOCITY] == 100


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"min_position_tick": 3000, "max_position_tick": 1000}, "min_position_tick/max_position_tick"),
        ({"max_position_tick": 5000}, "min_position_tick/max_position_tick"),
        ({"model": "AX-12"}, "model"),
        ({"return_delay_us": 3}, "return_delay_us"),
        ({"operating_mode": OperatingMode.CURRENT}, "operating_mode"),  # XL430 has no current mode
        ({"profile_velocity": -1}, "profile_velocity"),
        ({"temperature_limit_c": 150}, "temperature_limit_c"),
        ({"current_limit": 100}, "current_limit"),  # XL430 reports load, has no current limit
        ({"min_voltage_v": 12.0, "max_voltage_v": 7.0}, "min_voltage_v"),
        ({"min_position_tick": 1.5}, "min_position_tick"),
    ],
)
def test_invalid_spec_names_servo_and_field(kwargs: dict[str, object], field: str) -> None:
    args: dict[str, object] = {"servo_id": 7, "model": "XL430-W250", "role": "brow_l"}
    args.update(kwargs)
    with pytest.raises(ServoDescriptionError) as err:
        ServoSpec(**args)  # type: ignore[arg-type]
    assert err.value.servo_id == 7 and err.value.field == field
    assert "servo 7 (brow_l)" in str(err.value) and field.split("/")[0] in str(err.value)


def test_from_mapping_reports_the_key_path() -> None:
    spec = ServoSpec.from_mapping(
        {
            "servo_id": 2,
            "model": "XM430-W350",
            "operating_mode": "current_based_position",
            "shutdown": 0x24,
            "min_position_tick": -4096,
            "max_position_tick": 8191,
        }
    )
    assert spec.operating_mode is OperatingMode.CURRENT_BASED_POSITION
    assert spec.shutdown == HardwareErrorBits.OVERLOAD | HardwareErrorBits.OVERHEATING
    assert Register.MIN_POSITION_LIMIT not in spec.eeprom_values()  # ignored by the servo in that mode
    with pytest.raises(ServoDescriptionError, match=r"servos\[1\]: unknown field\(s\) \['speed'\]"):
        ServoSpec.from_mapping({"servo_id": 2, "model": "XL330-M288", "speed": 3}, "servos[1]")
    with pytest.raises(ServoDescriptionError, match=r"servos\[0\].*missing required field 'model'"):
        ServoSpec.from_mapping({"servo_id": 2}, "servos[0]")


def test_duplicate_ids_and_roles_are_refused() -> None:
    a = ServoSpec(1, "XL330-M288", role="jaw")
    with pytest.raises(ServoDescriptionError, match="id used twice"):
        check_specs([a, ServoSpec(1, "XL330-M288", role="lid")])
    with pytest.raises(ServoDescriptionError, match="role 'jaw' already used by servo 1"):
        check_specs([a, ServoSpec(2, "XL330-M288", role="jaw")])
