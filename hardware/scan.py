"""Find the servos on a chain: ping ids (or broadcast ping) -> id, model, firmware."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from hardware.bus import ServoBus
from hardware.errors import BusCorruptError, BusTimeoutError, ServoStatusError
from hardware.registers import Register, model_name


@dataclass(frozen=True)
class ScanResult:
    servo_id: int
    model_number: int
    model_name: str
    firmware_version: int
    hardware_error: int | None = None  # Hardware Error Status, when it could be read


def scan(
    bus: ServoBus, servo_ids: Iterable[int] | None = None, *, read_errors: bool = True
) -> list[ScanResult]:
    """Ping each of ``servo_ids``, or broadcast-ping when None (waits ~0.8 s at 1 Mbps)."""
    found = []
    if servo_ids is None:
        replies = list(bus.broadcast_ping().values())
    else:
        replies = []
        for sid in servo_ids:
            try:
                replies.append(bus.ping(sid))
            except (BusTimeoutError, BusCorruptError):
                continue
    for reply in replies:
        hw: int | None = None
        if read_errors:
            try:
                hw = bus.read(reply.servo_id, Register.HARDWARE_ERROR_STATUS)
            except (BusTimeoutError, BusCorruptError, ServoStatusError):
                hw = None
        firmware = reply.firmware_version
        found.append(
            ScanResult(reply.servo_id, reply.model_number, model_name(reply.model_number), firmware, hw)
        )
    return sorted(found, key=lambda r: r.servo_id)
