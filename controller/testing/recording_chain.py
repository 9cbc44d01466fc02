"""`RecordingChain`: an emulated chain that also notes, for every goal write, the servo's torque state and
present position at the moment the packet arrived (the packet log alone cannot say whether a goal reached a
servo with its torque off, or how far it was from where the servo stood)."""

from __future__ import annotations

from typing import Any

from servoface.hardware.emulator import ServoChain
from servoface.hardware.emulator.packet import Instruction, Packet
from servoface.hardware.emulator.packet_log import LogEntry, register_writes
from servoface.testing.record import GoalWrite, ServoEnd, TorqueWrite, WireRecord

GOAL_ADDRESS, GOAL_SIZE = 116, 4
TORQUE_ADDRESS, TORQUE_SIZE = 64, 1
BROADCAST_ID = 254
_WRITES = frozenset({Instruction.WRITE, Instruction.REG_WRITE, Instruction.SYNC_WRITE, Instruction.BULK_WRITE})


class RecordingChain(ServoChain):
    """A `ServoChain` (same constructor and ``create``) whose goal and torque writes are kept with the
    addressed servo's state before each packet. The packet log is kept whole (no ``log_limit``)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs["log_limit"] = None
        super().__init__(*args, **kwargs)
        self.goal_events: list[GoalWrite] = []
        self.torque_events: list[TorqueWrite] = []
        self._seq = 0

    def _handle(self, packet: Packet, t_rx: float, host_baud: int) -> None:
        if not packet.crc_ok or packet.instruction not in _WRITES:
            super()._handle(packet, t_rx, host_baud)
            return
        entry = [LogEntry(t_rx, packet.id, packet.instruction, packet.params)]
        goals = register_writes(entry, GOAL_ADDRESS, GOAL_SIZE)
        torques = register_writes(entry, TORQUE_ADDRESS, TORQUE_SIZE, signed=False)
        before = {}
        for _, wire_id, tick in goals:
            for servo in self._addressed(wire_id):
                before[servo.uid] = (servo.torque_on, servo.position_tick, tick)
        super()._handle(packet, t_rx, host_baud)
        self._seq += 1
        for uid, (torque_on, present, tick) in before.items():
            self.goal_events.append(GoalWrite(self._seq, t_rx, uid, tick, torque_on, present))
        for _, wire_id, value in torques:
            for servo in self._addressed(wire_id):
                self.torque_events.append(TorqueWrite(self._seq, t_rx, servo.uid, value))

    def _addressed(self, wire_id: int) -> list[Any]:
        """The servos a write to ``wire_id`` (the id register now, or broadcast) reaches."""
        if wire_id == BROADCAST_ID:
            return list(self.servos)
        return [s for s in self.servos if s.id == wire_id]

    def end_states(self) -> dict[int, ServoEnd]:
        """Every servo's torque, Present and Goal Position and Hardware Error Status now (by creation id)."""
        with self.lock:
            return {
                s.uid: ServoEnd(
                    s.uid,
                    s.torque_on,
                    s.position_tick,
                    int(s.read_register("Goal Position")),
                    s.hardware_error,
                    s.spec.name,
                )
                for s in self.servos
            }

    def record(self, source: str) -> WireRecord:
        """Everything so far, as a `WireRecord`."""
        with self.lock:
            return WireRecord(
                source=source,
                end=self.end_states(),
                goals=tuple(self.goal_events),
                torque_writes=tuple(self.torque_events),
                time_s=self.time_s,
            )
