"""The key space. Everything of one head lives under ``servoface/<site>/<name>/``:

| key | direction | what |
|---|---|---|
| ``.../aus/<track>`` | to the head | AU frames (the stream schema + envelope), followed on ``<track>`` with dropout |
| ``.../cmd/<verb>`` | to the head | express, play, look_at, neutral, stop, estop, clear_estop, say, cue |
| ``.../state/frame`` | from the head | frame summaries (verdict, reasons, timings), at most 10 Hz |
| ``.../state/telemetry`` | from the head | servo telemetry snapshots, at most 5 Hz |
| ``.../state/fault`` | from the head | fault events, as they happen |
| ``.../state/counters`` | from the head | messages accepted and refused (by reason), 1 Hz |
| ``.../status`` | queryable | status and capabilities (AUs, expressions, servos, tracks) |
| ``.../clock`` | queryable | the head's service clock now (for cue offsets) |
| ``@servoface/<site>/<name>`` | liveliness | presence |

Site and name are plain tokens (``[a-z0-9_-]``, 1..40): no ``/``, ``*``, ``$`` or ``?`` can widen a key. A
ROS 2 bridge maps ``servoface/<site>/<name>/aus/face`` to a ``hri_msgs/FacialActionUnits`` topic (see the
README section "ROS 2").
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from servoface.controller.network.errors import NetworkError

ROOT = "servoface"
PRESENCE_ROOT = "@servoface"
_TOKEN = re.compile(r"^[a-z0-9][a-z0-9_-]{0,39}$")
VERBS = ("express", "play", "look_at", "neutral", "stop", "estop", "clear_estop", "say", "cue")
TRACK_NAMES = ("stream", "face", "gaze", "studio", "gesture", "head", "speech")


def check_token(value: str, *, field: str) -> str:
    if not isinstance(value, str) or not _TOKEN.match(value):
        raise NetworkError(
            f"{field}: expected 1..40 characters of a-z, 0-9, '_' or '-' (starting with a letter "
            f"or digit), got {value!r:.60}"
        )
    return value


def check_pattern(value: str, *, field: str) -> str:
    """A site/name pattern for clients: tokens or ``*`` (``lobby/*``, ``*/*``)."""
    parts = value.split("/") if isinstance(value, str) else []
    if len(parts) != 2 or not all(p == "*" or _TOKEN.match(p) for p in parts):
        raise NetworkError(f"{field}: expected SITE/NAME with tokens or '*', e.g. 'lobby/*', got {value!r:.60}")
    return value


@dataclass(frozen=True)
class HeadKeys:
    """The keys of one head (or, for a client, of a pattern of heads)."""

    site: str
    name: str

    @property
    def base(self) -> str:
        return f"{ROOT}/{self.site}/{self.name}"

    def aus(self, track: str = "stream") -> str:
        return f"{self.base}/aus/{track}"

    @property
    def aus_any(self) -> str:
        return f"{self.base}/aus/*"

    def cmd(self, verb: str) -> str:
        return f"{self.base}/cmd/{verb}"

    @property
    def cmd_any(self) -> str:
        return f"{self.base}/cmd/*"

    def state(self, what: str) -> str:
        return f"{self.base}/state/{what}"

    @property
    def status(self) -> str:
        return f"{self.base}/status"

    @property
    def clock(self) -> str:
        return f"{self.base}/clock"

    @property
    def presence(self) -> str:
        return f"{PRESENCE_ROOT}/{self.site}/{self.name}"


def head_keys(site: str, name: str) -> HeadKeys:
    return HeadKeys(check_token(site, field="site"), check_token(name, field="name"))


def pattern_keys(pattern: str) -> HeadKeys:
    """Keys for ``SITE/NAME`` where either part may be ``*`` (a Zenoh wildcard chunk)."""
    site, name = check_pattern(pattern, field="heads").split("/")
    return HeadKeys(site, name)


def parse_head_key(key: str) -> tuple[str, str] | None:
    """(site, name) of a key under ``servoface/`` or ``@servoface/``, else None."""
    parts = key.split("/")
    if len(parts) >= 3 and parts[0] in (ROOT, PRESENCE_ROOT) and _TOKEN.match(parts[1]) and _TOKEN.match(parts[2]):
        return parts[1], parts[2]
    return None
