"""The driver's control-table transcription, checked against e-manual facts (not against the emulator)."""

from __future__ import annotations

import pytest
from servoface.hardware.registers import (
    BAUD_CODES,
    MODELS,
    Area,
    HardwareErrorBits,
    Register,
    model_by_name,
    slice_value,
    span,
)


@pytest.mark.parametrize(
    ("reg", "address", "size"),
    [
        (Register.MODEL_NUMBER, 0, 2),
        (Register.ID, 7, 1),
        (Register.BAUD_RATE, 8, 1),
        (Register.RETURN_DELAY_TIME, 9, 1),
        (Register.OPERATING_MODE, 11, 1),
        (Register.TEMPERATURE_LIMIT, 31, 1),
        (Register.MAX_POSITION_LIMIT, 48, 4),
        (Register.MIN_POSITION_LIMIT, 52, 4),
        (Register.SHUTDOWN, 63, 1),
        (Register.TORQUE_ENABLE, 64, 1),
        (Register.HARDWARE_ERROR_STATUS, 70, 1),
        (Register.PROFILE_VELOCITY, 112, 4),
        (Register.GOAL_POSITION, 116, 4),
        (Register.PRESENT_CURRENT, 126, 2),
        (Register.PRESENT_VELOCITY, 128, 4),
        (Register.PRESENT_POSITION, 132, 4),
        (Register.PRESENT_INPUT_VOLTAGE, 144, 2),
        (Register.PRESENT_TEMPERATURE, 146, 1),
    ],
)
def test_addresses_match_the_e_manual(reg: Register, address: int, size: int) -> None:
    assert (reg.address, reg.size) == (address, size)


def test_no_two_registers_overlap() -> None:
    regs = sorted(Register, key=lambda r: r.address)
    short = {Register.INDIRECT_SENTINEL, Register.INDIRECT_SENTINEL_SHORT}  # one field, two read lengths
    for a, b in zip(regs, regs[1:], strict=False):
        assert a.end <= b.address or {a, b} == short, f"{a.name} overlaps {b.name}"


def test_eeprom_is_below_64_and_ram_above() -> None:
    for reg in Register:
        if reg.area is Area.EEPROM:
            assert reg.address < 64, reg.name
        if reg.area is Area.RAM:
            assert reg.address >= 64, reg.name


def test_signed_fields_decode_twos_complement() -> None:
    assert Register.PRESENT_VELOCITY.decode(bytes([0xFF, 0xFF, 0xFF, 0xFF])) == -1
    assert Register.PRESENT_CURRENT.decode(0xFFFE) == -2
    assert Register.PRESENT_POSITION.decode(Register.PRESENT_POSITION.encode(-5)) == -5
    assert Register.PRESENT_TEMPERATURE.decode(bytes([200])) == 200


def test_encode_refuses_values_that_do_not_fit() -> None:
    with pytest.raises(ValueError, match="TORQUE_ENABLE"):
        Register.TORQUE_ENABLE.encode(256)
    with pytest.raises(ValueError, match="expected an int"):
        Register.GOAL_POSITION.encode(1.5)  # type: ignore[arg-type]


def test_span_and_slice_read_a_block() -> None:
    regs = (Register.MOVING, Register.PRESENT_CURRENT, Register.PRESENT_VELOCITY)
    start, length = span(regs)
    assert (start, length) == (122, 10)
    block = bytearray(10)
    block[126 - 122 : 128 - 122] = (-3).to_bytes(2, "little", signed=True)
    block[0] = 1
    assert slice_value(Register.PRESENT_CURRENT, start, block) == -3
    assert slice_value(Register.MOVING, start, block) == 1


def test_models_and_bauds() -> None:
    assert MODELS[1200].name == "XL330-M288" and MODELS[1200].reports_current
    assert not model_by_name("XL430-W250-T").reports_current
    assert model_by_name("xl330-m288").default_shutdown == 0x35
    assert BAUD_CODES[3] == 1_000_000 and BAUD_CODES[6] == 4_000_000
    assert HardwareErrorBits.OVERLOAD == 0x20
    with pytest.raises(KeyError, match="unknown servo model"):
        model_by_name("AX-12")
