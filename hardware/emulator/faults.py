"""Fault injection, per servo and scriptable in time (chain-clock seconds).

Reply faults act on the status packets a servo sends while the fault is active; hardware faults set their
Hardware Error Status bit while active (the bit stays latched until Reboot, as on a real servo, and
torque drops if the bit is enabled in Shutdown); ``disconnect`` removes the servo from the bus (no power,
no replies) and reconnects it powered up afresh when the fault ends.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from servoface.hardware.emulator.errors import EmulatorConfigError
from servoface.hardware.emulator.models import (
    HW_ELECTRICAL_SHOCK,
    HW_ENCODER,
    HW_INPUT_VOLTAGE,
    HW_OVERHEATING,
    HW_OVERLOAD,
)

REPLY_KINDS = frozenset({"no_reply", "late_reply", "corrupt_crc", "dropped_bytes"})
HARDWARE_KINDS: dict[str, int] = {
    "overload": HW_OVERLOAD,
    "overheating": HW_OVERHEATING,
    "electrical_shock": HW_ELECTRICAL_SHOCK,
    "encoder": HW_ENCODER,
    "input_voltage": HW_INPUT_VOLTAGE,
}
KINDS = REPLY_KINDS | frozenset(HARDWARE_KINDS) | {"disconnect"}


@dataclass(slots=True)
class Fault:
    """One injected fault on servo ``servo_id`` active over ``[start_s, end_s)`` of chain time."""

    servo_id: int
    kind: str
    start_s: float
    end_s: float = math.inf
    delay_s: float = 0.0  # late_reply: extra delay before the status packet
    drop_bytes: int = 3  # dropped_bytes: how many bytes vanish from the middle of each reply
    replies: int | None = None  # a reply fault: spoil only this many status packets, then end

    def active(self, t_s: float) -> bool:
        return self.start_s <= t_s < self.end_s

    def overlaps(self, t0_s: float, t1_s: float) -> bool:
        return self.start_s <= t1_s and self.end_s > t0_s


@dataclass(frozen=True, slots=True)
class ReplyFaults:
    """What happens to one status packet: the combined effect of the reply faults active at its time."""

    silent: bool = False
    extra_delay_s: float = 0.0
    corrupt_crc: bool = False
    drop_bytes: int = 0

    def apply(self, packet: bytes) -> bytes:
        if self.corrupt_crc:
            packet = packet[:-2] + bytes((packet[-2] ^ 0xFF, packet[-1] ^ 0x5A))
        if self.drop_bytes:
            mid = len(packet) // 2
            packet = packet[:mid] + packet[mid + self.drop_bytes :]
        return packet


NO_REPLY_FAULTS = ReplyFaults()


class FaultSchedule:
    """The faults of one chain. ``servo_id`` is the id a servo had when the chain was created."""

    def __init__(self, clock: Callable[[], float], known_ids: Callable[[], set[int]]) -> None:
        self._clock = clock
        self._known_ids = known_ids
        self._faults: dict[int, list[Fault]] = {}
        self.any = False  # fast check on the hot path: has any fault ever been injected?

    def inject(
        self,
        servo_id: int,
        kind: str,
        *,
        start_s: float | None = None,
        duration_s: float | None = None,
        delay_s: float = 0.010,
        drop_bytes: int = 3,
        replies: int | None = None,
    ) -> Fault:
        """Schedule ``kind`` on ``servo_id`` from ``start_s`` for ``duration_s`` (None = forever); a reply fault
        with ``replies=N`` spoils only the next N status packets of that servo (one lost reply, exactly)."""
        if kind not in KINDS:
            raise EmulatorConfigError(f"fault kind {kind!r}: expected one of {sorted(KINDS)}")
        if servo_id not in self._known_ids():
            raise EmulatorConfigError(
                f"fault on servo {servo_id}: no such servo in the chain {sorted(self._known_ids())}"
            )
        if duration_s is not None and duration_s < 0:
            raise EmulatorConfigError(f"fault duration_s {duration_s}: expected >= 0")
        if delay_s < 0 or drop_bytes < 0:
            raise EmulatorConfigError(f"fault delay_s {delay_s} / drop_bytes {drop_bytes}: expected >= 0")
        if replies is not None and (kind not in REPLY_KINDS or int(replies) < 1):
            raise EmulatorConfigError(f"fault replies {replies}: expected >= 1, on a reply fault {sorted(REPLY_KINDS)}")
        start = self._clock() if start_s is None else float(start_s)
        end = math.inf if duration_s is None else start + float(duration_s)
        fault = Fault(
            servo_id, kind, start, end, float(delay_s), int(drop_bytes), None if replies is None else int(replies)
        )
        self._faults.setdefault(servo_id, []).append(fault)
        self.any = True
        return fault

    def inject_now(self, servo_id: int, kind: str, **options: float) -> Fault:
        """Start ``kind`` on ``servo_id`` immediately, until cleared (or for ``duration_s``)."""
        return self.inject(servo_id, kind, **options)  # type: ignore[arg-type]

    def clear(self, servo_id: int | None = None, kind: str | None = None) -> None:
        """End matching faults now (future ones are dropped); hardware bits already latched stay latched."""
        now = self._clock()
        for sid, faults in list(self._faults.items()):
            if servo_id is not None and sid != servo_id:
                continue
            kept = []
            for f in faults:
                if kind is not None and f.kind != kind:
                    kept.append(f)
                elif f.start_s < now:
                    f.end_s = min(f.end_s, now)
                    kept.append(f)
            self._faults[sid] = kept

    def all(self) -> list[Fault]:
        return [f for faults in self._faults.values() for f in faults]

    def has_any(self, servo_id: int) -> bool:
        return self.any and bool(self._faults.get(servo_id))

    def active(self, servo_id: int, kind: str, t_s: float) -> Fault | None:
        for f in self._faults.get(servo_id, ()):
            if f.kind == kind and f.active(t_s):
                return f
        return None

    def overlapping(self, servo_id: int, t0_s: float, t1_s: float) -> list[Fault]:
        return [f for f in self._faults.get(servo_id, ()) if f.overlaps(t0_s, t1_s)]

    def reply_faults(self, servo_id: int, t_s: float) -> ReplyFaults:
        faults = self._faults.get(servo_id)
        if not faults:
            return NO_REPLY_FAULTS
        silent = corrupt = False
        delay = 0.0
        drop = 0
        for f in faults:
            if not f.active(t_s):
                continue
            if f.replies is not None:  # counted: this packet is one of them; the last one ends the fault
                f.replies -= 1
                if f.replies <= 0:
                    f.end_s = t_s
            if f.kind in ("no_reply", "disconnect"):
                silent = True
            elif f.kind == "late_reply":
                delay += f.delay_s
            elif f.kind == "corrupt_crc":
                corrupt = True
            elif f.kind == "dropped_bytes":
                drop += f.drop_bytes
        return ReplyFaults(silent, delay, corrupt, drop)
