"""The emulator's CRC-16: the one definition is `servoface.hardware.crc16` (shared with the bus)."""

from servoface.hardware.crc16 import POLYNOMIAL, crc16, crc16_bitwise, crc16_even, crc16_own_tail

__all__ = ["POLYNOMIAL", "crc16", "crc16_bitwise", "crc16_even", "crc16_own_tail"]
