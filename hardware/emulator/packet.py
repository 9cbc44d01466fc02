"""Protocol 2.0 packets: build, parse, byte stuffing (both ways), and a streaming receiver.

Instruction ``FF FF FD 00 ID LEN_L LEN_H INST params CRC_L CRC_H``; status has INST 0x55 then ERR.
LEN counts everything after itself. Stuffing: from INST to the last parameter every ``FF FF FD`` gets an
extra ``FD``; the CRC covers the stuffed bytes.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from functools import lru_cache

from servoface.hardware.emulator.crc import crc16
from servoface.hardware.emulator.errors import PacketError

HEADER = b"\xff\xff\xfd\x00"
BROADCAST_ID = 0xFE
MAX_ID = 0xFC
STATUS_INSTRUCTION = 0x55
MAX_PACKET_BYTES = 1024 * 8  # generous: the SDK builds <= 1024, fast replies may be longer


class Instruction(IntEnum):
    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    FACTORY_RESET = 0x06
    REBOOT = 0x08
    CLEAR = 0x10
    CONTROL_TABLE_BACKUP = 0x20
    STATUS = 0x55
    SYNC_READ = 0x82
    SYNC_WRITE = 0x83
    FAST_SYNC_READ = 0x8A
    BULK_READ = 0x92
    BULK_WRITE = 0x93
    FAST_BULK_READ = 0x9A


class ErrorNumber(IntEnum):
    """Bits 0-6 of a status packet's error byte."""

    NONE = 0
    RESULT_FAIL = 1
    INSTRUCTION = 2
    CRC = 3
    DATA_RANGE = 4
    DATA_LENGTH = 5
    DATA_LIMIT = 6
    ACCESS = 7


ALERT_BIT = 0x80


def stuff(body: bytes) -> bytes:
    """Insert ``FD`` after every ``FF FF FD`` in ``body`` (INST..last parameter).

    The three bytes before ``body`` in a packet are ``ID LEN_L LEN_H``; a pattern spanning that boundary is
    not stuffed (the SDK only looks inside the INST..param range, and so does the e-manual).
    """
    if b"\xff\xff\xfd" not in body:
        return body
    return body.replace(b"\xff\xff\xfd", b"\xff\xff\xfd\xfd")


def unstuff(body: bytes) -> bytes:
    """Remove the ``FD`` that follows every ``FF FF FD`` in ``body`` (inverse of :func:`stuff`)."""
    if b"\xff\xff\xfd\xfd" not in body:
        return body
    return body.replace(b"\xff\xff\xfd\xfd", b"\xff\xff\xfd")


def _frame(packet_id: int, body: bytes) -> bytes:
    """Header + id + length + stuffed body + CRC."""
    stuffed = stuff(body)
    length = len(stuffed) + 2
    head = HEADER + bytes((packet_id, length & 0xFF, length >> 8))
    packet = head + stuffed
    crc = crc16(packet)
    return packet + bytes((crc & 0xFF, crc >> 8))


def build_instruction(packet_id: int, instruction: int, params: bytes = b"") -> bytes:
    """A complete instruction packet (stuffed, with CRC)."""
    if not 0 <= packet_id <= 0xFE or packet_id == 0xFD:
        raise PacketError(f"packet id {packet_id}: expected 0..252 or 254 (broadcast)")
    return _frame(packet_id, bytes((instruction,)) + bytes(params))


def build_status(servo_id: int, error: int, params: bytes = b"") -> bytes:
    """A complete status packet (stuffed, with CRC)."""
    return _cached_status(servo_id, error, bytes(params))


@lru_cache(maxsize=8192)
def _cached_status(servo_id: int, error: int, params: bytes) -> bytes:
    # a servo at rest answers the same read with the same bytes every cycle: build each packet once
    return _frame(servo_id, bytes((STATUS_INSTRUCTION, error)) + params)


@dataclass(frozen=True, slots=True)
class Packet:
    """A decoded (unstuffed) packet; a status packet has ``instruction`` 0x55 and ``params[0]`` = error."""

    id: int
    instruction: int
    params: bytes
    crc_ok: bool = True

    @property
    def error(self) -> int:
        """The error byte of a status packet."""
        if self.instruction != STATUS_INSTRUCTION or not self.params:
            raise PacketError(f"packet from id {self.id} is not a status packet (instruction {self.instruction:#04x})")
        return self.params[0]

    @property
    def data(self) -> bytes:
        """The data bytes of a status packet (after the error byte)."""
        return self.params[1:]


def parse_packet(raw: bytes | bytearray, *, unstuff_body: bool = True) -> Packet:
    """Decode one complete packet; raises :class:`PacketError` on a bad header, length or CRC."""
    raw = bytes(raw)
    if len(raw) < 10 or raw[:4] != HEADER:
        raise PacketError(f"packet {raw[:8].hex(' ')}...: expected header FF FF FD 00 and >= 10 bytes")
    length = raw[5] | raw[6] << 8
    if length < 3 or len(raw) != 7 + length:
        raise PacketError(f"packet length field {length} does not match {len(raw)} bytes (expected 7 + LEN)")
    crc = raw[-2] | raw[-1] << 8
    if crc16(raw[:-2]) != crc:
        raise PacketError(f"packet from id {raw[4]}: CRC {crc:#06x} does not match {crc16(raw[:-2]):#06x}")
    body = raw[7:-2]
    if unstuff_body:
        body = unstuff(body)
    return Packet(raw[4], body[0], body[1:])


class PacketReceiver:
    """Finds packets in a byte stream, as a servo's UART handler does.

    ``feed`` returns complete packets; a packet whose CRC fails is returned with ``crc_ok=False`` (the
    servo answers it with a CRC error if it is addressed). Garbage before a header is discarded. An
    incomplete packet is abandoned when the line has been idle for ``timeout_s`` (give ``feed`` the time)
    or when the next write starts with a complete, CRC-valid packet, so line noise cannot deafen the bus.
    """

    def __init__(self, timeout_s: float = 0.01) -> None:
        self._buf = bytearray()
        self.timeout_s = timeout_s
        self._last_s = -1e300

    def clear(self) -> None:
        self._buf.clear()

    @property
    def pending(self) -> int:
        return len(self._buf)

    def feed(self, data: bytes | bytearray, t_s: float | None = None, end_s: float | None = None) -> list[Packet]:
        """Packets completed by ``data``, which starts arriving at ``t_s`` (and ends at ``end_s``, if the
        caller models the wire: the idle gap is then measured from the end of the previous chunk)."""
        buf = self._buf
        if t_s is not None:
            if buf and t_s - self._last_s > self.timeout_s:
                buf.clear()  # the rest of that packet never came
            self._last_s = t_s if end_s is None else end_s
        whole = len(data) >= 10 and data[:4] == HEADER and len(data) == 7 + (data[5] | data[6] << 8)
        if whole and (not buf or crc16(data[:-2]) == (data[-2] | data[-1] << 8)):
            buf.clear()
            return [self._decode(bytes(data))]  # fast path: exactly one whole packet
        buf += data
        out: list[Packet] = []
        while True:
            start = buf.find(b"\xff\xff\xfd")
            while start >= 0 and start + 3 < len(buf) and buf[start + 3] != 0x00:
                start = buf.find(b"\xff\xff\xfd", start + 1)
            if start < 0:
                keep = 2 if buf.endswith(b"\xff\xff") else 1 if buf.endswith(b"\xff") else 0
                del buf[: len(buf) - keep]
                return out
            if start:
                del buf[:start]
            if len(buf) < 7:
                return out
            length = buf[5] | buf[6] << 8
            if length < 3 or length > MAX_PACKET_BYTES:
                del buf[:3]
                continue
            total = 7 + length
            if len(buf) < total:
                return out
            raw = bytes(buf[:total])
            del buf[:total]
            out.append(self._decode(raw))

    @staticmethod
    def _decode(raw: bytes) -> Packet:
        return _decode_packet(raw)


@lru_cache(maxsize=1024)
def _decode_packet(raw: bytes) -> Packet:
    # hosts repeat identical instructions (the same sync read every cycle): decode and CRC-check each once
    crc_ok = crc16(raw[:-2]) == (raw[-2] | raw[-1] << 8)
    body = unstuff(raw[7:-2])
    return Packet(raw[4], body[0] if body else 0, body[1:], crc_ok)
