"""Find the servos on a chain: ping ids (or broadcast ping) -> id, model, firmware."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from servoface.hardware.bus import PingReply, ServoBus
from servoface.hardware.errors import BusCorruptError, BusTimeoutError, ServoStatusError
from servoface.hardware.registers import Register, model_name


@dataclass(frozen=True)
class ScanResult:
    servo_id: int
    model_number: int
    model_name: str
    firmware_version: int
    hardware_error: int | None = None  # Hardware Error Status, when it could be read


DEFAULT_RETRIES = 2


def scan(
    bus: ServoBus,
    servo_ids: Iterable[int] | None = None,
    *,
    read_errors: bool = True,
    retries: int = DEFAULT_RETRIES,
) -> list[ScanResult]:
    """Ping each of ``servo_ids``, or broadcast-ping when None (each broadcast waits for every id's reply
    slot: ~0.9 s at 1 Mbps, ~1.4 s at 57600 bps; asked twice, three times while nothing answers).

    A reply lost on a busy or noisy line must not hide a servo: a silent id is pinged again up to
    ``retries`` more times; a broadcast ping is repeated ``retries`` more times while it finds nothing
    (and once more after a find, to pick up a servo whose reply collided or was lost).
    """
    if retries < 0:
        raise ValueError(f"retries must be >= 0, got {retries}")
    found = []
    if servo_ids is None:
        seen: dict[int, PingReply] = {}
        for attempt in range(retries + 1):
            try:
                seen.update(bus.broadcast_ping())
            except (BusTimeoutError, BusCorruptError):
                pass
            if seen and attempt >= 1:
                break
        replies = list(seen.values())
    else:
        replies = []
        for sid in servo_ids:
            for _ in range(retries + 1):
                try:
                    replies.append(bus.ping(sid))
                    break
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
        found.append(ScanResult(reply.servo_id, reply.model_number, model_name(reply.model_number), firmware, hw))
    return sorted(found, key=lambda r: r.servo_id)
