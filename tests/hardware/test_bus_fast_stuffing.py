"""`TableCrcPacketHandler.addStuffing` / ``removeStuffing`` (a ``bytes.find`` check, then the packet as it is,
or the SDK's own method) leave every packet exactly as dynamixel-sdk's ``Protocol2PacketHandler`` does: the
same list contents, the same return value (the same object, or an equal new list), the same exception, on
seeded random packets — with and without ``FF FF FD`` / ``FF FF FD FD`` runs anywhere (length bytes
included), empty parameters, the longest packet, lengths that disagree with the list, odd elements. And whole
``txPacket`` / ``rxPacket`` calls put the same bytes on the wire and return the same packets and results."""

from __future__ import annotations

import copy
import random
from typing import Any

import pytest
from servoface.hardware.dynamixel_bus import TableCrcPacketHandler, sdk
from servoface.hardware.stuffing import add_stuffing_is_identity, remove_stuffing_is_identity

STOCK = sdk.Protocol2PacketHandler()
OURS = TableCrcPacketHandler()
TX_MAX = sdk.protocol2_packet_handler.TXPACKET_MAX_LEN
RUNS = (b"\xff\xff\xfd", b"\xff\xff\xfd\xfd", b"\xff\xff\xfd\xfd\xfd", b"\xff\xff", b"\xfd\xfd", b"\xff\xfd")


def _body(rng: random.Random, n: int) -> list[int]:
    """``n`` bytes, some of them runs that stuffing is about (spliced in at random places)."""
    out = [rng.choice((0x00, 0xFF, 0xFD, rng.randint(0, 255))) for _ in range(n)]
    for _ in range(rng.choice((0, 0, 1, 2, 5))):
        run = rng.choice(RUNS)
        at = rng.randint(0, max(0, n - len(run)))
        out[at : at + len(run)] = list(run)
    return out[:n]


def _packet(rng: random.Random) -> list[Any]:
    """``FF FF FD 00 ID LEN_L LEN_H`` + ``L`` bytes (INST .. CRC), mostly consistent, sometimes not."""
    kind = rng.random()
    if kind < 0.05:
        length = rng.choice((0, 1, 2, 3))
    elif kind < 0.1:
        length = rng.choice((TX_MAX - 8, TX_MAX - 7, TX_MAX - 6))  # the longest packets the buffer takes, and past
    else:
        length = rng.choice((3, 5, 6, 7, 8, 11, 12, 20, 127, rng.randint(2, 300)))
    body = _body(rng, length)
    if rng.random() < 0.3:  # the status packet shape: INST 0x55, ERR, params, CRC
        body[:1] = [0x55]
    packet: list[Any] = [0xFF, 0xFF, 0xFD, 0x00, rng.randint(0, 0xFE), length & 0xFF, length >> 8, *body]
    odd = rng.random()
    if odd < 0.04:
        del packet[rng.randint(7, len(packet)) :]  # shorter than its length says
    elif odd < 0.08:
        packet += _body(rng, rng.randint(1, 6))  # longer (the SDK's own txpacket lists are, after stuffing)
    elif odd < 0.1:
        packet[5], packet[6] = rng.choice(((0xFF, 0xFF), (0xFF, 0x00), (0xFD, 0x00), (0x01, 0xFF)))
    elif odd < 0.12 and len(packet) > 7:
        packet[rng.randrange(5, len(packet))] = rng.choice((256, -1, 0x1FD, 253.0, True))
    return packet


def _outcome(method: Any, packet: list[Any]) -> tuple[Any, ...]:
    """(exception type | None, the list after the call, the return value, whether it is the list passed)."""
    try:
        ret = method(packet)
    except Exception as err:  # the SDK indexing past the end: the same exception, at the same point
        return type(err), packet, None, None
    return None, packet, ret, ret is packet


def _same(name: str, packet: list[Any]) -> None:
    theirs = _outcome(getattr(STOCK, name), copy.copy(packet))
    ours = _outcome(getattr(OURS, name), copy.copy(packet))
    assert ours == theirs, (name, packet)
    for a, b in zip(ours[1], theirs[1], strict=True):  # the same elements, not only equal ones
        assert type(a) is type(b), (name, packet)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("name", ["addStuffing", "removeStuffing"])
def test_stuffing_is_the_sdks_on_random_packets(seed: int, name: str) -> None:
    rng = random.Random(seed * 7919 + len(name))
    for _ in range(3000):
        _same(name, _packet(rng))


@pytest.mark.parametrize("name", ["addStuffing", "removeStuffing"])
def test_stuffing_is_the_sdks_on_the_edges(name: str) -> None:
    for length in range(0, 12):
        for fill in (0x00, 0xFF, 0xFD):
            body = [fill] * length
            _same(name, [0xFF, 0xFF, 0xFD, 0x00, 1, length, 0, *body])
            _same(name, [0xFF, 0xFF, 0xFD, 0x00, 1, length, 0, *body, 0xFD, 0xFD])
    for length in (TX_MAX - 8, TX_MAX - 7, TX_MAX - 6):
        body = [0x12] * length
        _same(name, [0xFF, 0xFF, 0xFD, 0x00, 1, length & 0xFF, length >> 8, *body])
        body[-3:-2] = [0xFF]
        _same(name, [0xFF, 0xFF, 0xFD, 0x00, 1, length & 0xFF, length >> 8, *body])
    _same(name, [])
    _same(name, [0xFF, 0xFF, 0xFD, 0x00, 1, 3])
    _same(name, [0xFF, 0xFF, 0xFD, 0x00, 0xFF, 0xFF, 0xFD, 0x55, 0, 0, 0])  # a run across ID / LEN_L / LEN_H / INST
    _same(name, [0xFF, 0xFF, 0xFD, 0x00, 1, 4, 0, 0xFF, 0xFF, 0xFD, 0xFD])  # a run reaching into the CRC


def test_the_fast_checks_say_yes_where_they_should() -> None:
    """The point of it: the usual packets (no run) take the fast path; ones with a run do not."""
    plain = [0xFF, 0xFF, 0xFD, 0x00, 1, 8, 0, 0x55, 0, 0x10, 0x08, 0, 0, 0xAB, 0xCD]
    assert add_stuffing_is_identity(plain, TX_MAX) and remove_stuffing_is_identity(plain)
    triple = [0xFF, 0xFF, 0xFD, 0x00, 1, 8, 0, 0x55, 0, 0xFF, 0xFF, 0xFD, 0, 0xAB, 0xCD]
    assert not add_stuffing_is_identity(triple, TX_MAX) and remove_stuffing_is_identity(triple)
    quad = [0xFF, 0xFF, 0xFD, 0x00, 1, 8, 0, 0x55, 0, 0xFF, 0xFF, 0xFD, 0xFD, 0xAB, 0xCD]
    assert not add_stuffing_is_identity(quad, TX_MAX) and not remove_stuffing_is_identity(quad)


class _Port:
    """Just what ``txPacket`` / ``rxPacket`` use of a port: a byte queue in, a log out, no clock."""

    def __init__(self, incoming: bytes = b"") -> None:
        self.incoming = bytearray(incoming)
        self.written: list[bytes] = []
        self.is_using = False

    def clearPort(self) -> None:  # noqa: N802 - SDK name
        pass

    def writePort(self, packet: Any) -> int:  # noqa: N802 - SDK name
        self.written.append(bytes(packet))
        return len(packet)

    def readPort(self, length: int) -> bytes:  # noqa: N802 - SDK name
        out = bytes(self.incoming[:length])
        del self.incoming[:length]
        return out

    def isPacketTimeout(self) -> bool:  # noqa: N802 - SDK name
        return not self.incoming


def _status(rng: random.Random, sid: int, params: list[int], stuff: bool) -> bytes:
    """A status packet as a servo sends it (stuffed by the SDK's own addStuffing when ``stuff``)."""
    body = [0x55, rng.choice((0, 0, 0x80, 0x01)), *params]
    packet = [0xFF, 0xFF, 0xFD, 0x00, sid, (len(body) + 2) & 0xFF, (len(body) + 2) >> 8, *body, 0, 0]
    if stuff:
        packet = STOCK.addStuffing(packet)
    n = len(packet)
    crc = STOCK.updateCRC(0, packet, n - 2)
    packet[n - 2], packet[n - 1] = crc & 0xFF, crc >> 8
    return bytes(packet)


@pytest.mark.parametrize("seed", range(4))
def test_tx_and_rx_packets_are_the_sdks(seed: int) -> None:
    """Whole SDK calls that stuff and unstuff: the same bytes written, the same packets and results read
    (``rxPacket`` removes the stuffing of each status packet, ``txPacket`` calls ``addStuffing``)."""
    rng = random.Random(seed)
    for _ in range(400):
        n = rng.choice((0, 1, 4, rng.randint(0, 200)))
        params = _body(rng, n)
        tx = [0xFF, 0xFF, 0xFD, 0x00, rng.randint(0, 0xFE), (n + 3) & 0xFF, (n + 3) >> 8, 0x03, *params, 0, 0]
        ports = (_Port(), _Port())
        results = [h.txPacket(p, copy.copy(tx)) for h, p in zip((STOCK, OURS), ports, strict=True)]
        assert results[0] == results[1] and ports[0].written == ports[1].written, tx
        stream = b"".join(_status(rng, rng.randint(0, 0xFC), _body(rng, rng.randint(0, 60)), True) for _ in range(3))
        if rng.random() < 0.2:
            stream = bytes(_body(rng, rng.randint(1, 5))) + stream  # noise before the first header
        if rng.random() < 0.1:
            stream = stream[: rng.randint(0, len(stream))]  # cut short
        ports = (_Port(stream), _Port(stream))
        for _ in range(4):
            fast = rng.random() < 0.1  # the Fast Sync Read reply: no unstuffing
            theirs = STOCK.rxPacket(ports[0], fast)
            ours = OURS.rxPacket(ports[1], fast)
            assert ours == theirs, stream
