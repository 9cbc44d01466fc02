"""When the SDK's Protocol 2.0 byte stuffing would leave a packet as it is: a check in C-speed ``bytes.find``
instead of the SDK's per-byte Python loops (``addStuffing`` also builds a 1024-element list for every packet
sent). `TableCrcPacketHandler` calls the SDK's own method whenever these say no (or cannot say): the packets
that do need stuffing go through the SDK's code, unchanged.

The conditions are read off dynamixel-sdk 4.1's ``Protocol2PacketHandler`` (offsets: ``LEN_L`` = 5,
``LEN_H`` = 6, ``INST`` = 7; length ``L`` = ``LEN_L | LEN_H << 8``, counted from ``INST`` to the CRC):

- ``addStuffing`` inserts an ``FD`` after every ``FF FF FD`` whose ``FD`` is at 7 .. 7 + L - 3 (it looks two
  bytes back, so a triple starting at 5 .. L + 2: within ``packet[5 : L + 5]``, length bytes included).
  With none, it writes every byte of ``packet[0 : 7 + L]`` back in place and the length bytes as they were.
- ``removeStuffing`` drops the second ``FD`` of every ``FF FF FD FD`` starting at 5 .. L + 2 (within
  ``packet[5 : L + 6]``; its writes before the first such run are in place, so the first is found on the
  packet as received). With none, the same: every byte back in place.

Both shuffle bytes for ``L < 2``, index past the list's end when it is shorter than ``7 + L`` (IndexError)
and ``addStuffing`` past its 1024-element buffer when ``7 + L > 1024``: all of these are left to the SDK, as
is a list with any element ``bytes()`` does not take (over 255, not an integer). Byte for byte the same list and
return value: tests/hardware/test_bus_fast_stuffing.py.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

_LEN_L = 5
_LEN_H = 6
_INST = 7
_STUFF_TRIPLE = b"\xff\xff\xfd"
_STUFFED_QUAD = b"\xff\xff\xfd\xfd"


def _packet_span(packet: Sequence[Any]) -> tuple[bytes, int] | None:
    """``(bytes(packet), 7 + L)`` when the list holds every byte its length counts and ``L >= 2``; None when
    it does not or ``bytes()`` refuses an element (the cases both checks leave to the SDK)."""
    try:
        raw = bytes(packet)
    except (TypeError, ValueError):
        return None
    if len(raw) < _INST:
        return None
    total = _INST + (raw[_LEN_L] | raw[_LEN_H] << 8)
    if not _INST + 2 <= total <= len(raw):
        return None
    return raw, total


def add_stuffing_is_identity(packet: Sequence[Any], tx_max_len: int) -> bool:
    """True when the SDK's ``addStuffing(packet)`` would change nothing in ``packet`` and return it."""
    span = _packet_span(packet)
    if span is None:
        return False
    raw, total = span
    return total <= tx_max_len and raw.find(_STUFF_TRIPLE, _LEN_L, total - 2) < 0


def remove_stuffing_is_identity(packet: Sequence[Any]) -> bool:
    """True when the SDK's ``removeStuffing(packet)`` would change nothing in ``packet`` and return it."""
    span = _packet_span(packet)
    if span is None:
        return False
    raw, total = span
    return raw.find(_STUFFED_QUAD, _LEN_L, total - 1) < 0
