"""Driving heads from elsewhere: list them (presence + status), send commands, stream AU frames, and cue
several heads to start together.

**Cue timing**: each head runs its own service clock. For a cue the client measures, per head, the offset
between its own monotonic clock and the head's service clock NTP-style (``clock`` queryable, 5 exchanges,
the one with the shortest round trip; offset = head time - midpoint of the exchange, error <= half that
round trip) and sends each head the start time *on that head's clock*. Each head reports back the offset it
was given (``state/cue``).
"""

from __future__ import annotations

import json
import threading
import time
import uuid
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from servoface.controller.network.errors import NetworkError
from servoface.controller.network.keys import PRESENCE_ROOT, VERBS, HeadKeys, head_keys, parse_head_key, pattern_keys
from servoface.controller.network.messages import envelope, open_envelope

CLOCK_EXCHANGES = 5


@dataclass(frozen=True)
class HeadInfo:
    site: str
    name: str
    status: dict[str, Any]


@dataclass(frozen=True)
class ClockOffset:
    """head service time = local monotonic + ``offset_s`` (within +- ``error_s``)."""

    offset_s: float
    error_s: float


class HeadsClient:
    """A client session (``session`` from :func:`.zconfig.open_session`, with ``connect`` endpoints)."""

    def __init__(self, session: Any, *, live: bool = False) -> None:
        """``live=True``: this client holds live control — a head it commands eases to neutral when the
        link to it drops (AU frames are always live)."""
        self.session = session
        self.sender = str(session.zid())  # the node maps it to the link it arrives on
        self.live = bool(live)
        self._seq = 0
        self._lock = threading.Lock()

    def _body(self, body: dict[str, Any]) -> bytes:
        with self._lock:
            self._seq += 1
            seq = self._seq
        return envelope({"from": self.sender, **({"live": True} if self.live else {}), **body}, seq)

    # -- presence -----------------------------------------------------------------------------------
    def heads(self, pattern: str = "*/*", timeout_s: float = 1.0) -> list[HeadInfo]:
        """The heads present (liveliness tokens) matching ``SITE/NAME``, with their status."""
        keys = pattern_keys(pattern)
        found = []
        for reply in self.session.liveliness().get(f"{PRESENCE_ROOT}/{keys.site}/{keys.name}", timeout=timeout_s):
            ok = getattr(reply, "ok", None)
            if ok is None:
                continue
            parsed = parse_head_key(str(ok.key_expr))
            if parsed is not None:
                found.append(parsed)
        out = []
        for site, name in sorted(set(found)):
            out.append(HeadInfo(site, name, self.status(head_keys(site, name), timeout_s=timeout_s)))
        return out

    def status(self, keys: HeadKeys, timeout_s: float = 1.0) -> dict[str, Any]:
        for reply in self.session.get(keys.status, timeout=timeout_s):
            ok = getattr(reply, "ok", None)
            if ok is not None:
                return dict(json.loads(ok.payload.to_bytes()))
        return {}

    # -- commands -----------------------------------------------------------------------------------
    def send(self, keys: HeadKeys, verb: str, **body: Any) -> None:
        if verb not in VERBS:
            raise NetworkError(f"command {verb!r}: expected one of {list(VERBS)}")
        self.session.put(keys.cmd(verb), self._body(body))

    def send_aus(
        self, keys: HeadKeys, aus: dict[str, float], *, t_s: float | None = None, track: str = "stream"
    ) -> None:
        """One AU frame on ``track`` (the stream schema: ``{"t", "aus"}``)."""
        frame = {"t": time.monotonic() if t_s is None else t_s, "aus": aus}
        self.session.put(keys.aus(track), self._body(frame))

    def estop(self, pattern: str = "*/*", reason: str = "e-stop") -> None:
        keys = pattern_keys(pattern)
        self.session.put(f"{keys.base}/cmd/estop", self._body({"reason": reason}))

    def clear_estop(self, pattern: str = "*/*") -> None:
        """Unlatch the e-stop of every head matching ``pattern`` (torque stays off until asked for)."""
        keys = pattern_keys(pattern)
        self.session.put(f"{keys.base}/cmd/clear_estop", self._body({}))

    # -- clocks and cues ----------------------------------------------------------------------------
    def clock_offset(self, keys: HeadKeys, exchanges: int = CLOCK_EXCHANGES, timeout_s: float = 1.0) -> ClockOffset:
        best: tuple[float, float] | None = None  # (round trip, offset)
        for _ in range(exchanges):
            t0 = time.monotonic()
            for reply in self.session.get(keys.clock, timeout=timeout_s):
                t1 = time.monotonic()
                ok = getattr(reply, "ok", None)
                if ok is None:
                    continue
                head_s = float(json.loads(ok.payload.to_bytes())["service_s"])
                rtt, offset = t1 - t0, head_s - (t0 + t1) / 2
                if best is None or rtt < best[0]:
                    best = (rtt, offset)
        if best is None:
            raise NetworkError(f"{keys.base}: no answer from its clock (is the head there? servoface heads)")
        return ClockOffset(best[1], best[0] / 2)

    def cue(
        self,
        pattern: str,
        what: dict[str, Any],
        *,
        in_s: float = 0.5,
        timeout_s: float = 1.0,
        answers_within_s: float | None = None,
    ) -> dict[str, Any]:
        """Start ``what`` ({"verb": "express", "name": ...}) on every head matching ``pattern`` at one time,
        ``in_s`` from now. Returns {"cue", "at_monotonic_s", "heads": {site/name: offset}}; with
        ``answers_within_s``, also "answers": {site/name: "accepted" | "refused: why" | "no answer"}: each
        head's own word on the cue (it publishes ``state/cue`` when it takes one, ``state/refused`` when it
        refuses: an unknown name, a value out of range, an e-stop latched), waited for that long at most."""
        if answers_within_s is None:
            return self._cue(pattern, what, in_s=in_s, timeout_s=timeout_s)
        keys = pattern_keys(pattern)
        heard: list[tuple[str, str, dict[str, Any]]] = []  # (site/name, state kind, body)
        lock = threading.Lock()

        def on_state(sample: Any) -> None:
            key = str(sample.key_expr)
            parsed = parse_head_key(key)
            try:
                _, body = open_envelope(sample.payload.to_bytes())
            except Exception:  # noqa: BLE001 - not a message of ours: ignored
                return
            if parsed is not None:
                with lock:
                    heard.append((f"{parsed[0]}/{parsed[1]}", key.rsplit("/", 1)[-1], body))

        subscribers = [self.session.declare_subscriber(keys.state(kind), on_state) for kind in ("cue", "refused")]
        try:
            result = self._cue(pattern, what, in_s=in_s, timeout_s=timeout_s)
            answers: dict[str, str] = {}
            deadline = time.monotonic() + answers_within_s
            while True:
                with lock:
                    for head, kind, body in heard:
                        if body.get("cue") == result["cue"] and head in result["heads"]:
                            answers.setdefault(head, "accepted" if kind == "cue" else f"refused: {body.get('error')}")
                if len(answers) == len(result["heads"]) or time.monotonic() >= deadline:
                    break
                time.sleep(0.02)
            result["answers"] = {head: answers.get(head, "no answer") for head in result["heads"]}
            return result
        finally:
            for sub in subscribers:
                sub.undeclare()

    def _cue(self, pattern: str, what: dict[str, Any], *, in_s: float, timeout_s: float) -> dict[str, Any]:
        if not isinstance(in_s, int | float) or not 0.05 <= in_s <= 60:
            raise NetworkError(f"cue: --at must be +0.05 s .. +60 s from now, got {in_s!r}")
        heads = self.heads(pattern, timeout_s=timeout_s)
        if not heads:
            raise NetworkError(
                f"cue: no head matches {pattern!r} (servoface heads lists what is there; check --connect)"
            )
        offsets = {(h.site, h.name): self.clock_offset(head_keys(h.site, h.name)) for h in heads}
        at_local = time.monotonic() + in_s
        cue_id = uuid.uuid4().hex[:8]
        for (site, name), off in offsets.items():
            body = {"what": what, "at_s": at_local + off.offset_s, "offset_s": round(off.offset_s, 6), "cue": cue_id}
            self.session.put(head_keys(site, name).cmd("cue"), self._body(body))
        return {
            "cue": cue_id,
            "at_monotonic_s": at_local,
            "heads": {f"{s}/{n}": {"offset_s": o.offset_s, "error_s": o.error_s} for (s, n), o in offsets.items()},
        }


def parse_at(text: str) -> float:
    """``+0.5s`` / ``+500ms`` / ``0.5`` -> seconds from now."""
    t = text.strip().lstrip("+")
    try:
        if t.endswith("ms"):
            return float(t[:-2]) / 1e3
        return float(t[:-1]) if t.endswith("s") else float(t)
    except ValueError:
        raise NetworkError(f"--at {text!r}: expected a delay such as +0.5s or +500ms") from None


def split_heads(patterns: Sequence[str]) -> list[str]:
    return [p for text in patterns for p in text.split(",") if p]
