"""What the servos on the bus do with one received instruction packet, and who answers (in what order).

Answer rules: Ping is always answered; reads need Status Return Level >= 1, everything else level 2;
broadcast Read/Write/Reg Write/Action/Reboot are never answered; absent ids are silent; Sync/Bulk Read
replies come in parameter order. The error byte carries the Alert bit (0x80) while Hardware Error Status
is non-zero.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from servoface.hardware.emulator.answers import Outcome, Reply, answers, error_byte, servos_with, status
from servoface.hardware.emulator.fast_read import fast_bulk_read, fast_sync_read
from servoface.hardware.emulator.packet import BROADCAST_ID, ErrorNumber, Instruction, Packet, build_status
from servoface.hardware.emulator.servo import EmulatedServo

CLEAR_MULTI_TURN = b"\x01\x44\x58\x4c\x22"
BACKUP_KEY = b"CTRL"  # 0x43 0x54 0x52 0x4C after P1 of Control Table Backup


def dispatch(
    packet: Packet, listeners: Sequence[EmulatedServo], by_id: dict[int, list[EmulatedServo]], t_s: float
) -> Outcome:
    """Run ``packet`` on the servos that heard it (``listeners``; ``by_id`` indexes them by id)."""
    out = Outcome([], [], [])
    for servo in listeners:
        servo.heard(t_s)
    if packet.id != BROADCAST_ID or packet.instruction in _STATE_BROADCASTS:
        # every instruction acts on the servo as it is when the packet arrives: physics first
        for servo in listeners if packet.id == BROADCAST_ID else by_id.get(packet.id, ()):
            if servo._t < t_s:  # else already there (`heard` advanced it): advance would do nothing
                servo.advance(t_s)
    inst = packet.instruction
    pid = packet.id
    params = packet.params
    targets = by_id.get(pid, []) if pid != BROADCAST_ID else []
    if not packet.crc_ok:
        for servo in targets:
            if answers(servo, inst):
                out.replies.append(Reply(servo, build_status(servo.id, error_byte(servo, ErrorNumber.CRC))))
        return out
    handler = _HANDLERS.get(inst)
    if handler is None:
        for servo in targets:
            if answers(servo, inst):
                out.replies.append(Reply(servo, build_status(servo.id, error_byte(servo, ErrorNumber.INSTRUCTION))))
        return out
    handler(out, pid, params, listeners, by_id, targets)
    return out


def _ping(
    out: Outcome,
    pid: int,
    params: bytes,
    listeners: Sequence[EmulatedServo],
    by_id: dict[int, list[EmulatedServo]],
    targets: list[EmulatedServo],
) -> None:
    servos = sorted(listeners, key=lambda s: s.id) if pid == BROADCAST_ID else targets
    for servo in servos:
        info = servo.mem[0:2] + servo.mem[6:7]
        status(out, servo, Instruction.PING, 0, bytes(info))


def _read(
    out: Outcome,
    pid: int,
    params: bytes,
    listeners: Sequence[EmulatedServo],
    by_id: dict[int, list[EmulatedServo]],
    targets: list[EmulatedServo],
) -> None:
    for servo in targets:
        if len(params) != 4:
            status(out, servo, Instruction.READ, ErrorNumber.DATA_LENGTH)
            continue
        addr = params[0] | params[1] << 8
        length = params[2] | params[3] << 8
        err, data = servo.read_bytes(addr, length)
        status(out, servo, Instruction.READ, err, data)


def _write(
    out: Outcome,
    pid: int,
    params: bytes,
    listeners: Sequence[EmulatedServo],
    by_id: dict[int, list[EmulatedServo]],
    targets: list[EmulatedServo],
) -> None:
    servos = listeners if pid == BROADCAST_ID else targets
    for servo in servos:
        old_id = servo.id
        answer = answers(servo, Instruction.WRITE)  # the reply follows the level before this write
        if len(params) < 3:
            err = int(ErrorNumber.DATA_LENGTH)
        else:
            addr = params[0] | params[1] << 8
            err = servo.wire_write(addr, params[2:])
            if addr <= 8 < addr + len(params) - 2 or addr <= 7 < addr + len(params) - 2:
                out.ids_changed = True
        if pid != BROADCAST_ID:
            status(out, servo, Instruction.WRITE, err, sid=old_id, answer=answer)


def _reg_write(
    out: Outcome,
    pid: int,
    params: bytes,
    listeners: Sequence[EmulatedServo],
    by_id: dict[int, list[EmulatedServo]],
    targets: list[EmulatedServo],
) -> None:
    servos = listeners if pid == BROADCAST_ID else targets
    for servo in servos:
        if len(params) < 3:
            err = int(ErrorNumber.DATA_LENGTH)
        else:
            addr = params[0] | params[1] << 8
            err = servo.check_write(addr, params[2:])
            if not err:
                servo.registered = (addr, bytes(params[2:]))
                servo.mem[69] = 1
        if pid != BROADCAST_ID:
            status(out, servo, Instruction.REG_WRITE, err)


def _action(
    out: Outcome,
    pid: int,
    params: bytes,
    listeners: Sequence[EmulatedServo],
    by_id: dict[int, list[EmulatedServo]],
    targets: list[EmulatedServo],
) -> None:
    servos = listeners if pid == BROADCAST_ID else targets
    for servo in servos:
        pending = servo.registered
        if pending is None:
            err = int(ErrorNumber.INSTRUCTION)
        else:
            servo.registered = None
            servo.mem[69] = 0
            err = servo.wire_write(*pending)
            if pending[0] <= 8 and pending[0] + len(pending[1]) > 7:
                out.ids_changed = True
        if pid != BROADCAST_ID:
            status(out, servo, Instruction.ACTION, err)


def _factory_reset(
    out: Outcome,
    pid: int,
    params: bytes,
    listeners: Sequence[EmulatedServo],
    by_id: dict[int, list[EmulatedServo]],
    targets: list[EmulatedServo],
) -> None:
    option = params[0] if len(params) == 1 else -1
    if pid == BROADCAST_ID:
        if option in (0x01, 0x02):  # broadcast 0xFF is ignored (X / MX(2.0) firmware >= 42)
            out.reset.extend((s, option) for s in listeners)
            out.ids_changed = True
        return
    for servo in targets:
        if option not in (0xFF, 0x01, 0x02):
            status(out, servo, Instruction.FACTORY_RESET, ErrorNumber.DATA_RANGE)
            continue
        status(out, servo, Instruction.FACTORY_RESET, 0)
        out.reset.append((servo, option))
        out.ids_changed = True


def _reboot(
    out: Outcome,
    pid: int,
    params: bytes,
    listeners: Sequence[EmulatedServo],
    by_id: dict[int, list[EmulatedServo]],
    targets: list[EmulatedServo],
) -> None:
    servos = listeners if pid == BROADCAST_ID else targets
    for servo in servos:
        if pid != BROADCAST_ID:
            status(out, servo, Instruction.REBOOT, 0)
        out.reboot.append(servo)


def _clear(
    out: Outcome,
    pid: int,
    params: bytes,
    listeners: Sequence[EmulatedServo],
    by_id: dict[int, list[EmulatedServo]],
    targets: list[EmulatedServo],
) -> None:
    servos = listeners if pid == BROADCAST_ID else targets
    for servo in servos:
        if bytes(params) != CLEAR_MULTI_TURN:
            err = int(ErrorNumber.DATA_RANGE)
        elif servo.motor.vel != 0.0:
            err = int(ErrorNumber.RESULT_FAIL)
        else:
            err = 0
            servo.clear_multi_turn()
        if pid != BROADCAST_ID:
            status(out, servo, Instruction.CLEAR, err)


def _backup(
    out: Outcome,
    pid: int,
    params: bytes,
    listeners: Sequence[EmulatedServo],
    by_id: dict[int, list[EmulatedServo]],
    targets: list[EmulatedServo],
) -> None:
    option = params[0] if len(params) == 5 and bytes(params[1:]) == BACKUP_KEY else -1
    for servo in targets:
        if option not in (0x01, 0x02):
            err = int(ErrorNumber.DATA_RANGE)
        elif servo.torque_on:  # "works properly only if Torque Enable is 0"
            err = int(ErrorNumber.ACCESS)
        elif option == 0x01:
            servo.backup_control_table()
            err = 0
        elif servo.backup is None:
            err = int(ErrorNumber.RESULT_FAIL)  # nothing stored to restore from
        else:
            servo.restore_eeprom()
            out.reboot.append(servo)  # "after processing packets, DYNAMIXEL reboots itself"
            out.ids_changed = True
            err = 0
        status(out, servo, Instruction.CONTROL_TABLE_BACKUP, err)


def _sync_read(
    out: Outcome,
    pid: int,
    params: bytes,
    listeners: Sequence[EmulatedServo],
    by_id: dict[int, list[EmulatedServo]],
    targets: list[EmulatedServo],
) -> None:
    if pid != BROADCAST_ID or len(params) < 5:
        return
    addr = params[0] | params[1] << 8
    length = params[2] | params[3] << 8
    for sid in params[4:]:
        for servo in servos_with(by_id, sid):
            err, data = servo.read_bytes(addr, length)
            status(out, servo, Instruction.SYNC_READ, err, data)


def _bulk_read(
    out: Outcome,
    pid: int,
    params: bytes,
    listeners: Sequence[EmulatedServo],
    by_id: dict[int, list[EmulatedServo]],
    targets: list[EmulatedServo],
) -> None:
    if pid != BROADCAST_ID or len(params) % 5:
        return
    for i in range(0, len(params), 5):
        sid = params[i]
        addr = params[i + 1] | params[i + 2] << 8
        length = params[i + 3] | params[i + 4] << 8
        for servo in servos_with(by_id, sid):
            err, data = servo.read_bytes(addr, length)
            status(out, servo, Instruction.BULK_READ, err, data)


def _sync_write(
    out: Outcome,
    pid: int,
    params: bytes,
    listeners: Sequence[EmulatedServo],
    by_id: dict[int, list[EmulatedServo]],
    targets: list[EmulatedServo],
) -> None:
    if pid != BROADCAST_ID or len(params) < 4:
        return
    addr = params[0] | params[1] << 8
    length = params[2] | params[3] << 8
    stride = length + 1
    if length == 0 or (len(params) - 4) % stride:
        return
    for i in range(4, len(params), stride):
        for servo in servos_with(by_id, params[i]):
            servo.wire_write(addr, params[i + 1 : i + stride])
            if addr <= 8 and addr + length > 7:
                out.ids_changed = True


def _bulk_write(
    out: Outcome,
    pid: int,
    params: bytes,
    listeners: Sequence[EmulatedServo],
    by_id: dict[int, list[EmulatedServo]],
    targets: list[EmulatedServo],
) -> None:
    if pid != BROADCAST_ID:
        return
    i = 0
    n = len(params)
    while i + 5 <= n:
        sid = params[i]
        addr = params[i + 1] | params[i + 2] << 8
        length = params[i + 3] | params[i + 4] << 8
        data = params[i + 5 : i + 5 + length]
        i += 5 + length
        if len(data) != length:
            return
        for servo in servos_with(by_id, sid):
            servo.wire_write(addr, data)
            if addr <= 8 and addr + length > 7:
                out.ids_changed = True


# broadcast instructions whose handlers look at (or change) live servo state
_STATE_BROADCASTS = frozenset(
    {
        Instruction.WRITE,
        Instruction.REG_WRITE,
        Instruction.ACTION,
        Instruction.CLEAR,
        Instruction.REBOOT,
        Instruction.SYNC_READ,
        Instruction.BULK_READ,
        Instruction.SYNC_WRITE,
        Instruction.BULK_WRITE,
        Instruction.FAST_SYNC_READ,
        Instruction.FAST_BULK_READ,
    }
)

_HANDLERS: dict[int, Callable[..., None]] = {
    Instruction.PING: _ping,
    Instruction.READ: _read,
    Instruction.WRITE: _write,
    Instruction.REG_WRITE: _reg_write,
    Instruction.ACTION: _action,
    Instruction.FACTORY_RESET: _factory_reset,
    Instruction.REBOOT: _reboot,
    Instruction.CLEAR: _clear,
    Instruction.CONTROL_TABLE_BACKUP: _backup,
    Instruction.SYNC_READ: _sync_read,
    Instruction.SYNC_WRITE: _sync_write,
    Instruction.FAST_SYNC_READ: fast_sync_read,
    Instruction.BULK_READ: _bulk_read,
    Instruction.BULK_WRITE: _bulk_write,
    Instruction.FAST_BULK_READ: fast_bulk_read,
}
