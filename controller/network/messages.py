"""The envelope of every message to a head: ``{"schema": 1, "seq": N, ...body}``.

- ``schema``: the version of this message format; a node refuses (and counts) any other.
- ``seq``: the sender's message counter, per sender (the Zenoh source id) and key. A node refuses a message
  whose ``seq`` is not newer than the last it took from that sender on that key (stale or out of order),
  unless the jump back is large (> 1000: a restarted sender), and counts it.
- the body: AU frames are the stream schema of ``servoface stream`` (``{"t": ..., "aus": {...}}``);
  commands have their own fields (``cmd/express``: name, intensity, transition_s, hold_s; ...).

Every message is parsed with bounded size (64 KiB) and depth (``parse_json`` of the inputs package) and
every value validated by the head service, as everywhere else.
"""

from __future__ import annotations

import json
import threading
from collections import Counter
from collections.abc import Hashable
from dataclasses import dataclass, field
from typing import Any

from servoface.controller.network.errors import MessageError

SCHEMA_VERSION = 1
MAX_MESSAGE_BYTES = 64 * 1024
RESTART_JUMP = 1000


def envelope(body: dict[str, Any], seq: int) -> bytes:
    """Serialise ``body`` with the envelope fields."""
    return json.dumps({"schema": SCHEMA_VERSION, "seq": int(seq), **body}, separators=(",", ":")).encode()


def open_envelope(raw: bytes) -> tuple[int, dict[str, Any]]:
    """(seq, body) of a raw message; MessageError for a bad size, JSON, schema version or seq."""
    from servoface.controller.errors import FrameError
    from servoface.controller.inputs.messages import parse_json

    if len(raw) > MAX_MESSAGE_BYTES:
        raise MessageError(f"message of {len(raw)} bytes: at most {MAX_MESSAGE_BYTES}")
    try:
        obj = parse_json(raw, where="message")
    except FrameError as err:
        raise MessageError(str(err)) from err
    if not isinstance(obj, dict):
        raise MessageError("message: expected a JSON object")
    version = obj.pop("schema", None)
    if version != SCHEMA_VERSION or isinstance(version, bool):
        raise MessageError(f"schema: expected {SCHEMA_VERSION}, got {version!r:.40}")
    seq = obj.pop("seq", None)
    if isinstance(seq, bool) or not isinstance(seq, int) or not 0 <= seq < 2**63:
        raise MessageError(f"seq: expected an integer >= 0, got {seq!r:.40}")
    return seq, obj


@dataclass
class SequenceGuard:
    """Per (sender, key): the last sequence number taken; counts what it refuses."""

    last: dict[tuple[Hashable, str], int] = field(default_factory=dict)
    refused: Counter[str] = field(default_factory=Counter)
    accepted: int = 0
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def take(self, sender: Hashable, key: str, seq: int) -> bool:
        with self._lock:
            prev = self.last.get((sender, key))
            if prev is not None and seq <= prev and prev - seq <= RESTART_JUMP:
                self.refused["stale or out of order"] += 1
                return False
            self.last[(sender, key)] = seq
            self.accepted += 1
            return True

    def refuse(self, reason: str) -> None:
        with self._lock:
            self.refused[reason] += 1

    def counters(self) -> dict[str, Any]:
        with self._lock:
            return {"accepted": self.accepted, "refused": dict(self.refused)}
