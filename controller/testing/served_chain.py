"""`ServedChain`: an emulated chain served on a pty by another Python process (`servoface.testing.served`),
for code under test that opens its port by path, as a user's own program does (its own ``PortHandler``,
its own process model). The test drives faults, the clock and reads the record over the child's stdin and
stdout."""

from __future__ import annotations

import json
import os
import select
import subprocess
import sys
import tempfile
from typing import IO, Any

from servoface.testing.chains import ChainSpec, fault_start_s
from servoface.testing.errors import ServedChainError
from servoface.testing.record import WireRecord

START_TIMEOUT_S = 60.0  # a loaded machine: the child imports numpy before it prints its path
REPLY_TIMEOUT_S = 30.0


class ServedChain:
    """The same interface as `LocalChain`; ``port`` (= ``path``) is the pty device, e.g. ``/dev/pts/7``."""

    transport = "pty"

    def __init__(self, spec: ChainSpec, *, python: str | None = None) -> None:
        self.spec = spec
        self._stderr = tempfile.TemporaryFile("w+")  # a file, not a pipe: a chatty child never blocks on it
        self._proc = subprocess.Popen(
            [python or sys.executable, "-m", "servoface.testing.served", json.dumps(spec.describe())],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self._stderr,
            text=True,
            env=dict(os.environ),
        )
        self._in: IO[str] = _stream(self._proc.stdin)
        self._out: IO[str] = _stream(self._proc.stdout)
        try:
            hello = self._line(START_TIMEOUT_S, "start")
        except BaseException:
            self._kill()
            raise
        self.path: str = hello["port"]
        self.pid: int = int(hello["pid"])

    # -- the child's pipe ---------------------------------------------------------------------------------
    def _failure(self, what: str) -> ServedChainError:
        self._kill()
        self._stderr.seek(0)
        err = self._stderr.read()
        return ServedChainError(f"emulator process (pid {self._proc.pid}) {what}; its stderr:\n{err[-4000:]}")

    def _line(self, timeout_s: float, what: str) -> dict[str, Any]:
        out = self._out
        ready, _, _ = select.select([out], [], [], timeout_s)
        if not ready:
            raise self._failure(f"gave no answer to {what!r} within {timeout_s:.0f} s")
        line = out.readline()
        if not line:
            raise self._failure(f"exited (code {self._proc.poll()}) before answering {what!r}")
        return json.loads(line)  # type: ignore[no-any-return]

    def _call(self, op: str, **args: Any) -> dict[str, Any]:
        if self._proc.poll() is not None:
            raise self._failure(f"is gone (exit code {self._proc.returncode})")
        stdin = self._in
        try:
            stdin.write(json.dumps({"op": op, **args}) + "\n")
            stdin.flush()
        except BrokenPipeError as err:
            raise self._failure(f"closed its pipe on {op!r}") from err
        reply = self._line(REPLY_TIMEOUT_S, op)
        if not reply.get("ok"):
            raise ServedChainError(f"emulator process: {op}: {reply.get('type')}: {reply.get('error')}")
        return reply

    def _kill(self) -> None:
        if self._proc.poll() is None:
            self._proc.kill()
            self._proc.wait(timeout=10)

    # -- the chain interface ------------------------------------------------------------------------------
    @property
    def port(self) -> str:
        return self.path

    @property
    def ids(self) -> list[int]:
        return [sid for sid, _ in self.spec.servos]

    @property
    def time_s(self) -> float:
        return float(self._call("time")["t_s"])

    def advance(self, dt_s: float) -> None:
        self._call("advance", dt_s=float(dt_s))

    def inject(
        self,
        servo_id: int,
        kind: str,
        *,
        at_s: float | None = None,
        after_s: float | None = None,
        duration_s: float | None = None,
        **options: float,
    ) -> None:
        """As `LocalChain.inject`; chain time is the served process's."""
        start = fault_start_s(self.time_s if after_s is not None else 0.0, at_s, after_s)
        self._call("inject", servo_id=servo_id, kind=kind, start_s=start, duration_s=duration_s, **options)

    def clear_faults(self, servo_id: int | None = None, kind: str | None = None) -> None:
        self._call("clear", servo_id=servo_id, kind=kind)

    def move_by_hand(self, servo_id: int, tick: float) -> None:
        self._call("move_by_hand", servo_id=servo_id, tick=float(tick))

    def set_obstacle(self, servo_id: int, tick: float | None) -> None:
        self._call("set_obstacle", servo_id=servo_id, tick=tick)

    def set_input_voltage(self, servo_id: int | None, volts: float) -> None:
        self._call("set_input_voltage", servo_id=servo_id, volts=float(volts))

    def read_register(self, servo_id: int, name: str) -> int:
        return int(self._call("read_register", servo_id=servo_id, name=name)["value"])

    def write_register(self, servo_id: int, name: str, value: int) -> None:
        self._call("write_register", servo_id=servo_id, name=name, value=int(value))

    def record(self) -> WireRecord:
        """What the served chain received so far (waits until the bytes already written were handled)."""
        return WireRecord.from_json(self._call("record")["record"])

    def goal_writes(self) -> list[tuple[float, int, int]]:
        return list(self.record().goal_writes())

    def close(self) -> None:
        """Stop the served process (the pty vanishes); safe to call twice."""
        if self._proc.poll() is None:
            try:
                self._in.write('{"op": "quit"}\n')
                self._in.flush()
                self._proc.wait(timeout=10)
            except (BrokenPipeError, subprocess.TimeoutExpired, OSError):
                self._kill()
        for stream in (self._in, self._out, self._stderr):
            stream.close()

    def __enter__(self) -> ServedChain:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _stream(stream: IO[str] | None) -> IO[str]:
    if stream is None:
        raise ServedChainError("emulator process: no pipe to it (Popen without PIPE)")
    return stream
