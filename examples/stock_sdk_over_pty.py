#!/usr/bin/env python3
"""Drive servos with ONLY the stock dynamixel-sdk (no servoface imports): ping, read, write, sync write,
sync read and fast sync read. Works on a real port or on the pty printed by `servoface emulate`:

    servoface emulate --ids 1-4 &          # first line of output: /dev/pts/N
    python examples/stock_sdk_over_pty.py /dev/pts/N --ids 1,2,3,4

Exit status 0 when every step succeeded and every servo reached its goal.
"""

from __future__ import annotations

# ruff: noqa: T201  (a command-line example: it prints)
import argparse
import sys
import time
from collections.abc import Callable
from typing import Any

from dynamixel_sdk import (
    COMM_SUCCESS,
    GroupSyncRead,
    GroupSyncWrite,
    PacketHandler,
    PortHandler,
)

ADDR_TORQUE_ENABLE = 64
ADDR_PROFILE_VELOCITY = 112
ADDR_GOAL_POSITION = 116
ADDR_PRESENT_POSITION = 132
LEN_POSITION = 4


def signed32(value: int) -> int:
    return value - (1 << 32) if value & 0x80000000 else value


def check(ph: PacketHandler, what: str, comm: int, err: int = 0) -> None:
    if comm != COMM_SUCCESS:
        raise RuntimeError(f"{what}: {ph.getTxRxResult(comm)}")
    if err & 0x7F:
        raise RuntimeError(f"{what}: {ph.getRxPacketError(err)}")


TRIES = 3  # a reply that does not come is asked for again: a real bus loses one now and then, and the SDK's
# reply window is tight (a few ms past the packet's wire time), so a loaded computer can miss one too


def transact(ph: PacketHandler, what: str, call: Callable[..., Any], *args: Any) -> tuple[Any, ...]:
    """``call(*args)`` (an SDK transaction: its result ends in ``comm`` or ``(comm, error)``), sent again up to
    ``TRIES`` times while the communication fails; a servo's error byte is not retried. Raises if it still
    fails; returns the result as a tuple."""
    for attempt in range(TRIES):
        result = call(*args)
        values = result if isinstance(result, tuple) else (result,)
        comm, err = (values[-2], values[-1]) if len(values) >= 2 else (values[0], 0)
        if comm == COMM_SUCCESS or attempt == TRIES - 1:
            check(ph, what, comm, err)
            return values
    raise AssertionError("unreachable")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("port")
    parser.add_argument("--baud", type=int, default=1_000_000)
    parser.add_argument("--ids", default="1,2,3,4", help="comma-separated servo ids")
    parser.add_argument("--offset", type=int, default=300, help="ticks to move each servo from where it is")
    args = parser.parse_args(argv)
    ids = [int(x) for x in args.ids.split(",")]

    port = PortHandler(args.port)
    ph = PacketHandler(2.0)
    if not port.openPort() or not port.setBaudRate(args.baud):
        print(f"cannot open {args.port} at {args.baud}", file=sys.stderr)
        return 1
    try:
        # ping + single read + single writes
        start: dict[int, int] = {}
        for sid in ids:
            model = transact(ph, f"ping {sid}", ph.ping, port, sid)[0]
            pos = transact(ph, f"read position {sid}", ph.read4ByteTxRx, port, sid, ADDR_PRESENT_POSITION)[0]
            start[sid] = signed32(pos)
            transact(ph, f"profile velocity {sid}", ph.write4ByteTxRx, port, sid, ADDR_PROFILE_VELOCITY, 0)
            transact(ph, f"goal := present {sid}", ph.write4ByteTxRx, port, sid, ADDR_GOAL_POSITION, start[sid])
            transact(ph, f"torque on {sid}", ph.write1ByteTxRx, port, sid, ADDR_TORQUE_ENABLE, 1)
            print(f"ping {sid}: model {model}, present position {start[sid]}")

        # one sync write of all goals
        goals = {sid: start[sid] + (args.offset if start[sid] < 2048 else -args.offset) for sid in ids}
        writer = GroupSyncWrite(port, ph, ADDR_GOAL_POSITION, LEN_POSITION)
        for sid, goal in goals.items():
            writer.addParam(sid, list(goal.to_bytes(4, "little", signed=True)))
        check(ph, "sync write goals", writer.txPacket())

        # sync read until every servo is there (or 3 s)
        reader = GroupSyncRead(port, ph, ADDR_PRESENT_POSITION, LEN_POSITION)
        for sid in ids:
            reader.addParam(sid)
        deadline = time.monotonic() + 3.0
        present: dict[int, int] = {}
        while time.monotonic() < deadline:
            transact(ph, "sync read", reader.txRxPacket)
            present = {sid: signed32(reader.getData(sid, ADDR_PRESENT_POSITION, LEN_POSITION)) for sid in ids}
            if present == goals:
                break
            time.sleep(0.01)
        print(f"sync read: {present}")

        # fast sync read must agree
        transact(ph, "fast sync read", reader.fastSyncRead)
        fast = {sid: signed32(reader.getData(sid, ADDR_PRESENT_POSITION, LEN_POSITION)) for sid in ids}
        print(f"fast sync read: {fast}")
        if present != goals or fast != goals:
            print(f"servos did not reach their goals {goals}", file=sys.stderr)
            return 1
        print(f"moved: {', '.join(f'{sid}: {start[sid]} -> {goals[sid]}' for sid in ids)}")
        return 0
    except RuntimeError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    finally:
        port.closePort()


if __name__ == "__main__":
    sys.exit(main())
