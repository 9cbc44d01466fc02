"""The other process of a pty chain: ``python -m servoface.testing.served '<json description>'``.

Creates a `RecordingChain` from the description (servos as ``[[id, model], ...]``, baud, clock, wire time,
goal limit, start positions), serves it on a pseudo-terminal and writes one JSON line ``{"port": path,
"pid": n}`` to stdout. Then it answers JSON-line commands on stdin (record, inject, clear, advance, time,
move_by_hand, set_obstacle, set_input_voltage, read_register, write_register, quit), one JSON line each
(``{"ok": true, ...}`` or ``{"ok": false, "error": ...}``). End of stdin (the test process died) ends it.
"""

from __future__ import annotations

import fcntl
import json
import sys
import termios
import time
from typing import Any

from servoface.testing.recording_chain import RecordingChain

QUIET_S = 0.03  # the log is taken once the pty has had no unread input and no new packet for this long
QUIET_MAX_S = 2.0


def build(desc: dict[str, Any]) -> RecordingChain:
    servos = [(int(sid), str(model)) for sid, model in desc["servos"]]
    chain = RecordingChain.create(
        servos,
        baud=int(desc.get("baud", 1_000_000)),
        wire_time=bool(desc.get("wire_time", True)),
        clock=str(desc.get("clock", "real")),
        goal_limit=str(desc.get("goal_limit", "reject")),
    )
    for sid, tick in (desc.get("positions") or {}).items():
        chain.servo(int(sid)).move_by_hand(float(tick))
    return chain


def _pending_input(chain: RecordingChain) -> int:
    """Bytes the client wrote that the pty thread has not read yet (0 if unknown)."""
    server = getattr(chain, "_pty", None)
    master = getattr(server, "_master", None)
    if master is None:
        return 0
    try:
        buf = fcntl.ioctl(master, termios.FIONREAD, b"\0\0\0\0")
    except OSError:
        return 0
    return int.from_bytes(buf, sys.byteorder)


def settle(chain: RecordingChain) -> None:
    """Wait until what the client wrote has been handled (the record is asked for on another channel)."""
    deadline = time.monotonic() + QUIET_MAX_S
    seen = -1
    while time.monotonic() < deadline:
        n = len(chain.log)
        if n == seen and _pending_input(chain) == 0:
            return
        seen = n
        time.sleep(QUIET_S)


def handle(chain: RecordingChain, port: str, cmd: dict[str, Any]) -> dict[str, Any]:
    op = cmd.get("op")
    if op == "record":
        settle(chain)
        return {"record": chain.record(f"emulator over pty {port} (pid {_pid()})").to_json()}
    if op == "inject":
        chain.faults.inject(
            int(cmd["servo_id"]),
            str(cmd["kind"]),
            start_s=cmd.get("start_s"),
            duration_s=cmd.get("duration_s"),
            **{k: cmd[k] for k in ("delay_s", "drop_bytes") if k in cmd},
        )
        return {}
    if op == "clear":
        chain.faults.clear(cmd.get("servo_id"), cmd.get("kind"))
        return {}
    if op == "advance":
        chain.advance(float(cmd["dt_s"]))
        return {"t_s": chain.time_s}
    if op == "time":
        return {"t_s": chain.time_s}
    if op == "move_by_hand":
        chain.servo(int(cmd["servo_id"])).move_by_hand(float(cmd["tick"]))
        return {}
    if op == "set_obstacle":
        chain.set_obstacle(int(cmd["servo_id"]), cmd.get("tick"))
        return {}
    if op == "set_input_voltage":
        chain.set_input_voltage(cmd.get("servo_id"), float(cmd["volts"]))
        return {}
    if op == "read_register":
        return {"value": chain.servo(int(cmd["servo_id"])).read_register(cmd["name"])}
    if op == "write_register":
        chain.servo(int(cmd["servo_id"])).write_register(cmd["name"], int(cmd["value"]))
        return {}
    raise ValueError(f"unknown command {op!r}")


def _pid() -> int:
    import os

    return os.getpid()


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        sys.stderr.write("usage: python -m servoface.testing.served '<json chain description>'\n")
        return 2
    chain = build(json.loads(argv[0]))
    port = chain.serve_pty()
    out = sys.stdout
    out.write(json.dumps({"port": port, "pid": _pid()}) + "\n")
    out.flush()
    try:
        for line in sys.stdin:
            if not line.strip():
                continue
            cmd = json.loads(line)
            if cmd.get("op") == "quit":
                break
            try:
                reply: dict[str, Any] = {"ok": True, **handle(chain, port, cmd)}
            except Exception as err:  # noqa: BLE001 - every error goes back to the test process, typed
                reply = {"ok": False, "error": str(err), "type": type(err).__name__}
            out.write(json.dumps(reply) + "\n")
            out.flush()
    finally:
        chain.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
