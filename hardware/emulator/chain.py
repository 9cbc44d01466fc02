"""``ServoChain``: the servos on one bus, the chain clock, wire timing, the packet log and fault injection.

Wire time: an instruction of L bytes written at baud B reaches the servos L·10/B after the line is free;
each status packet starts after that servo's Return Delay Time (and after the previous reply on the line)
and its bytes become readable one by one at the servo's byte time. ``wire_time=False`` makes replies
readable at once (fast unit tests).
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any

from servoface.hardware.emulator.clock import ManualClock, RealClock
from servoface.hardware.emulator.errors import EmulatorConfigError
from servoface.hardware.emulator.faults import FaultSchedule
from servoface.hardware.emulator.instructions import dispatch
from servoface.hardware.emulator.models import ModelSpec, baud_code_for, get_model
from servoface.hardware.emulator.packet import MAX_ID, Packet, PacketReceiver
from servoface.hardware.emulator.packet_log import LogEntry, PacketLog, register_writes
from servoface.hardware.emulator.realism import Realism
from servoface.hardware.emulator.servo import EmulatedServo

if TYPE_CHECKING:
    from servoface.hardware.emulator.serial_port import EmulatedSerial

REBOOT_SILENCE_S = 0.1  # a rebooting servo hears nothing for this long
# How far the host may write ahead of the wire before write() blocks: the transmit buffer of an FT232H-class
# USB adapter (the U2D2 family) is 1 KB (FTDI FT232H datasheet); a Linux usb-serial port adds up to a page
# (4 KB) of kernel fifo on top, and a pty adds its own kernel buffer (about 18 KB measured here).
TX_BUFFER_BYTES = 1024
GOAL_ADDRESS = 116
# The packet log of a chain made for a run (`Face.open(emulate=True)`, `servoface ... --emulate`,
# `servoface emulate`): the newest 100 000 packets (~24 MB; ~13 minutes of a 30-servo head at 50 Hz), so a
# run of hours stays bounded. A chain made directly keeps up to 1 000 000 (tests read whole logs).
RUN_LOG_LIMIT = 100_000


class ServoChain:
    """A chain of emulated servos on one bus. Create with :meth:`create`; see the package docstring."""

    def __init__(
        self,
        specs: Iterable[tuple[int, ModelSpec]],
        *,
        baud: int = 1_000_000,
        wire_time: bool = True,
        clock: Callable[[], float] | str | None = None,
        log_limit: int | None = 1_000_000,
        delivery: str = "byte",
        goal_limit: str = "reject",
        tx_buffer_bytes: int = TX_BUFFER_BYTES,
        realism: Realism | bool | dict[str, Any] | None = None,
    ) -> None:
        self.realism = Realism.coerce(realism)
        if int(tx_buffer_bytes) < 0:
            raise EmulatorConfigError(f"tx_buffer_bytes {tx_buffer_bytes}: expected >= 0")
        self.tx_buffer_bytes = int(tx_buffer_bytes)
        if clock is None or clock == "real":
            self._clock: Callable[[], float] = RealClock()
        elif clock == "manual":
            self._clock = ManualClock()
        elif callable(clock):
            self._clock = clock
        else:
            raise EmulatorConfigError(
                f"clock {clock!r}: expected None/'real', 'manual' or a callable returning seconds"
            )
        self.lock = threading.RLock()
        self.wire_time = bool(wire_time)
        if delivery not in ("byte", "packet"):
            raise EmulatorConfigError(f"delivery {delivery!r}: expected 'byte' or 'packet'")
        # "byte": reply bytes readable one by one as they arrive; "packet": each status packet (or fast-read
        # block) readable whole once its last byte has arrived, like a USB adapter handing over a frame
        self.delivery = delivery
        if goal_limit not in ("reject", "clamp"):
            raise EmulatorConfigError(f"goal_limit {goal_limit!r}: expected 'reject' or 'clamp'")
        self.baud = int(baud)
        self.reboot_silence_s = REBOOT_SILENCE_S
        self.log = PacketLog(log_limit)  # bounded ring, absolute indexes (see PacketLog)
        self._log_limit = log_limit
        self.faults = FaultSchedule(self._clock, lambda: {s.uid for s in self.servos})
        self.servos: list[EmulatedServo] = []
        seen: set[int] = set()
        for sid, spec in specs:
            if not 0 <= sid <= MAX_ID:
                raise EmulatorConfigError(f"servo id {sid}: expected 0..{MAX_ID}")
            if sid in seen:
                raise EmulatorConfigError(f"servo id {sid} appears twice in the chain description")
            seen.add(sid)
            code = baud_code_for(self.baud, spec)
            self.servos.append(
                EmulatedServo(
                    sid,
                    spec,
                    baud_code=code,
                    clock=self._clock,
                    faults=self.faults,
                    lock=self.lock,
                    realism=self.realism,
                )
            )
        self._by_id: dict[int, list[EmulatedServo]] = {}
        self._silence_until_s = -1.0
        for servo in self.servos:
            servo.on_change = self._servo_changed
            servo.clamp_goals = goal_limit == "clamp"
        self._reindex()
        self._receiver = PacketReceiver()
        self._tx_free_s = 0.0  # host -> servos line busy until
        self._rx_free_s = 0.0  # servos -> host line busy until
        # pending reply bytes: [data, start_s, byte_s, bytes already read, readable only whole]
        self._rx: deque[list[Any]] = deque()
        self._pty: object | None = None
        self._closed = False

    @classmethod
    def create(
        cls,
        ids: Iterable[int] | Iterable[tuple[int, str | ModelSpec]] = range(1, 25),
        model: str | ModelSpec = "XL330-M288",
        baud: int = 1_000_000,
        wire_time: bool = True,
        clock: Callable[[], float] | str | None = None,
        *,
        log_limit: int | None = 1_000_000,
        delivery: str = "byte",
        goal_limit: str = "reject",
        tx_buffer_bytes: int = TX_BUFFER_BYTES,
        realism: Realism | bool | dict[str, Any] | None = None,
    ) -> ServoChain:
        """A chain of servos: ``ids`` are ints (all of ``model``) or ``(id, model)`` pairs.

        ``clock``: None/"real" (monotonic, the SDK's timeouts behave), "manual" (moves only with
        :meth:`advance`) or any callable returning seconds. ``delivery``: "byte" (reply bytes readable as
        each arrives) or "packet" (each status packet readable whole when its last byte arrives).
        ``goal_limit``: a Goal Position outside Min/Max Position Limit (position mode) gets a Data Limit
        Error and is not stored ("reject"), or is accepted and the motion clamped to the limit ("clamp");
        the e-manual leaves this open, so tests can check a driver against both. ``tx_buffer_bytes``: how
        far the host may write ahead of the wire before the in-process port's ``write()`` blocks (the pty
        stops reading instead, so the client blocks once the kernel's pty buffer is full too). ``realism``:
        off (None, default), True (the documented default magnitudes), a dict of overrides (e.g.
        ``{"seed": 3, "backlash_tick": 6}``) or a :class:`Realism`: non-ideal servos (backlash, load- and
        speed-dependent settling error and lag, encoder noise, temperature-dependent current).
        """
        specs: list[tuple[int, ModelSpec]] = []
        for item in ids:
            if isinstance(item, tuple):
                sid, m = item
                specs.append((int(sid), get_model(m)))
            else:
                specs.append((int(item), get_model(model)))
        return cls(
            specs,
            baud=baud,
            wire_time=wire_time,
            clock=clock,
            log_limit=log_limit,
            delivery=delivery,
            goal_limit=goal_limit,
            tx_buffer_bytes=tx_buffer_bytes,
            realism=realism,
        )

    # ----------------------------------------------------------------- clock and servos
    @property
    def time_s(self) -> float:
        return self._clock()

    @property
    def clock(self) -> Callable[[], float]:
        return self._clock

    def advance(self, dt_s: float) -> None:
        """Move a manual clock forward by ``dt_s`` and bring every servo's physics up to it."""
        advance = getattr(self._clock, "advance", None)
        if advance is None:
            raise EmulatorConfigError("chain.advance() needs a manual clock: create the chain with clock='manual'")
        with self.lock:
            advance(dt_s)
            for servo in self.servos:
                servo.advance()

    def servo(self, servo_id: int) -> EmulatedServo:
        """The servo created with id ``servo_id`` (its id register may have changed since)."""
        for s in self.servos:
            if s.uid == servo_id:
                return s
        raise EmulatorConfigError(f"no servo {servo_id} in the chain: have {[s.uid for s in self.servos]}")

    @property
    def ids(self) -> list[int]:
        return [s.uid for s in self.servos]

    def set_obstacle(self, servo_id: int, at_tick: float | None) -> None:
        """A rigid stop at Present Position ``at_tick`` for ``servo_id`` (None removes it)."""
        with self.lock:
            self.servo(servo_id).set_obstacle(at_tick)

    def set_input_voltage(self, servo_id: int | None, volts: float) -> None:
        """Supply voltage of one servo (or of all with ``servo_id=None``)."""
        with self.lock:
            for s in self.servos if servo_id is None else [self.servo(servo_id)]:
                s.set_input_voltage(volts)

    def _servo_changed(self, servo: EmulatedServo) -> None:
        self._silence_until_s = max(self._silence_until_s, servo.silent_until_s)
        self._reindex()

    def _reindex(self) -> None:
        self._listener_cache: dict[int, list[EmulatedServo]] = {}
        by_id: dict[int, list[EmulatedServo]] = {}
        for s in self.servos:
            by_id.setdefault(s.id, []).append(s)
        self._by_id = by_id

    # ----------------------------------------------------------------- the wire
    def host_write(self, data: bytes | bytearray, host_baud: int) -> int:
        """Host bytes onto the bus at ``host_baud``; runs complete packets. Returns len(data)."""
        with self.lock:
            now = self._clock()
            n = len(data)
            byte_s = 10.0 / host_baud if self.wire_time and host_baud > 0 else 0.0
            start = max(now, self._tx_free_s)
            t_rx = start + n * byte_s
            self._tx_free_s = t_rx
            for packet in self._receiver.feed(data, start, t_rx):
                self._handle(packet, t_rx, host_baud)
            return n

    def tx_backlog_s(self) -> float:
        """How long the host -> servos line stays busy with bytes already written (0 when idle)."""
        with self.lock:
            return max(0.0, self._tx_free_s - self._clock())

    def tx_room_bytes(self, host_baud: int) -> int | None:
        """How many more bytes fit ahead of the wire before writing must wait (None: no wire time)."""
        if not self.wire_time or host_baud <= 0:
            return None
        backlog_bytes = self.tx_backlog_s() * host_baud / 10.0
        return max(0, int(self.tx_buffer_bytes - backlog_bytes))

    def wait_tx(self, host_baud: int, *, drain: bool = False) -> None:
        """Block until the bytes ahead of the wire fit the transmit buffer (``drain``: until all are sent),
        as a real port's ``write()`` (``flush()``) does. A manual clock is moved on instead of sleeping;
        another callable clock cannot be waited on and does not block."""
        if not self.wire_time or host_baud <= 0:
            return
        limit_s = 0.0 if drain else self.tx_buffer_bytes * 10.0 / host_baud
        while True:
            wait_s = self.tx_backlog_s() - limit_s
            if wait_s <= 0:
                return
            if isinstance(self._clock, ManualClock):
                self.advance(wait_s)
                return
            if not isinstance(self._clock, RealClock):
                return
            time.sleep(wait_s)

    def _listeners(self, t_s: float, host_baud: int) -> list[EmulatedServo]:
        faults = self.faults
        quiet = not faults.any and t_s >= self._silence_until_s
        if quiet:
            cached = self._listener_cache.get(host_baud)
            if cached is not None:
                return cached
        out = []
        for s in self.servos:
            if s.baud_bps != host_baud or t_s < s.silent_until_s:
                continue
            if faults.has_any(s.uid):
                s.advance(t_s)
                if not s.powered or faults.active(s.uid, "disconnect", t_s):
                    continue
            out.append(s)
        if quiet:
            self._listener_cache[host_baud] = out
        return out

    def _handle(self, packet: Packet, t_rx: float, host_baud: int) -> None:
        if packet.crc_ok:
            self.log.append(LogEntry(t_rx, packet.id, packet.instruction, packet.params))
        listeners = self._listeners(t_rx, host_baud)
        if not listeners:
            return
        by_id = self._by_id if len(listeners) == len(self.servos) else _index(listeners)
        outcome = dispatch(packet, listeners, by_id, t_rx)
        if outcome.replies:
            self._schedule(outcome.replies, t_rx, host_baud)
        for servo in outcome.reboot:
            servo.silent_until_s = t_rx + self.reboot_silence_s
            servo.reboot(self.reboot_silence_s)
            servo.silent_until_s = max(servo.silent_until_s, t_rx + self.reboot_silence_s)
            self._servo_changed(servo)
        for servo, option in outcome.reset:
            servo.factory_reset(option)
        if outcome.ids_changed or outcome.reset or outcome.reboot:
            self._reindex()

    def _schedule(self, replies: list, t_rx: float, host_baud: int) -> None:  # type: ignore[type-arg]
        wire = self.wire_time
        byte_s = 10.0 / host_baud if wire and host_baud > 0 else 0.0
        line = max(self._rx_free_s, t_rx)
        faults = self.faults
        for reply in replies:
            servo = reply.servo
            data = reply.data
            delay = servo.return_delay_s if wire and not reply.continues else 0.0
            if faults.has_any(servo.uid):
                rf = faults.reply_faults(servo.uid, t_rx)
                if rf.silent:
                    continue
                data = rf.apply(data)
                delay += rf.extra_delay_s
            start = line + delay
            self._rx.append([data, start, byte_s, 0, self.delivery == "packet"])
            line = start + len(data) * byte_s
        self._rx_free_s = line

    def host_in_waiting(self) -> int:
        """How many reply bytes have arrived and not been read."""
        with self.lock:
            now = self._clock()
            total = 0
            for data, start, byte_s, done, whole in self._rx:
                arrived = _arrived(len(data), start, byte_s, now, whole)
                total += arrived - done
                if arrived < len(data):
                    break
            return total

    def host_read(self, size: int) -> bytes:
        """Up to ``size`` reply bytes that have arrived (never blocks)."""
        with self.lock:
            rx = self._rx
            if not rx or size <= 0:
                return b""
            now = self._clock()
            out = b""
            while rx and size > 0:
                seg = rx[0]
                data, start, byte_s, done, whole = seg
                arrived = _arrived(len(data), start, byte_s, now, whole)
                take = min(arrived - done, size)
                if take <= 0:
                    break
                out += data[done : done + take]
                size -= take
                done += take
                if done == len(data):
                    rx.popleft()
                else:
                    seg[3] = done
                    break
            return out

    def host_reset_input(self) -> None:
        """Drop reply bytes that have arrived (bytes still on the wire arrive later, as on a real UART)."""
        with self.lock:
            now = self._clock()
            rx = self._rx
            while rx:
                seg = rx[0]
                arrived = _arrived(len(seg[0]), seg[1], seg[2], now, seg[4])
                if arrived == len(seg[0]):
                    rx.popleft()
                else:
                    seg[3] = max(seg[3], arrived)
                    break

    def rx_burst_times_s(self) -> tuple[float, float] | None:
        """(when the next unread reply byte arrives, when the last pending one has arrived), or None."""
        with self.lock:
            if not self._rx:
                return None
            data, start, byte_s, done, whole = self._rx[0]
            first = float(start + (len(data) if whole else done + 1) * byte_s)
            data, start, byte_s, _, _ = self._rx[-1]
            return first, float(start + len(data) * byte_s)

    def next_reply_time_s(self) -> float | None:
        """When the next unread reply byte arrives (None if nothing is pending)."""
        with self.lock:
            if not self._rx:
                return None
            data, start, byte_s, done, whole = self._rx[0]
            return float(start + (len(data) if whole else done + 1) * byte_s)

    # ----------------------------------------------------------------- transports
    def open_serial(self, port: str = "emulated://servo-chain") -> EmulatedSerial:
        """An in-process endpoint with the pyserial subset dynamixel_sdk's PortHandler uses."""
        from servoface.hardware.emulator.serial_port import EmulatedSerial

        return EmulatedSerial(self, port=port)

    def serve_pty(self, *, realtime: bool = True) -> str:
        """Serve the chain on a pseudo-terminal from a background thread; returns the slave device path.

        ``realtime``: ask for real-time scheduling of the serving thread where the system allows it (replies
        then keep to the SDK's reply window on a loaded machine); :attr:`pty_priority` says what it got."""
        from servoface.hardware.emulator.pty_transport import PtyServer

        with self.lock:
            if self._pty is None:
                server = PtyServer(self, realtime=realtime)
                server.start()
                self._pty = server
            return self._pty.path  # type: ignore[attr-defined,no-any-return]

    @property
    def pty_stats(self) -> str | None:
        """The pty thread's punctuality so far (bursts, late ones, latest), or None without a pty."""
        server = self._pty
        return None if server is None else str(server.stats())  # type: ignore[attr-defined]

    @property
    def pty_priority(self) -> str | None:
        """The pty thread's scheduling ("real-time (SCHED_RR 10)" or "normal (...)"); None without a pty."""
        server = self._pty
        return None if server is None else str(server.priority)  # type: ignore[attr-defined]

    def close(self) -> None:
        """Stop the pty thread (if any). The in-process endpoints stop working."""
        server = self._pty
        self._pty = None
        if server is not None:
            server.stop()  # type: ignore[attr-defined]
        self._closed = True

    @property
    def closed(self) -> bool:
        return self._closed

    def __enter__(self) -> ServoChain:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ----------------------------------------------------------------- log helpers
    def instructions(self, instruction: int | None = None) -> list[LogEntry]:
        """Logged packets, optionally only those of one instruction code."""
        return [e for e in self.log.kept() if instruction is None or e.instruction == instruction]

    def register_writes(self, address: int, size: int, *, signed: bool = True) -> list[tuple[float, int, int]]:
        """(t_s, servo_id, value) for every write of the whole register at ``address`` (Write, Reg Write,
        Sync Write, Bulk Write), decoded from the log. Broadcast Write is reported with id 254."""
        return register_writes(self.log.kept(), address, size, signed=signed)

    def goal_writes(self) -> list[tuple[float, int, int]]:
        """(t_s, servo_id, goal_tick) for every Goal Position (116, 4 bytes) sent on the wire."""
        return self.register_writes(GOAL_ADDRESS, 4)


def _arrived(n: int, start: float, byte_s: float, now: float, whole: bool) -> int:
    if byte_s <= 0.0:
        return n if now >= start else 0
    if now < start:
        return 0
    if whole:
        return n if now + 1e-12 >= start + n * byte_s else 0
    k = int((now - start) / byte_s + 1e-9)
    return n if k > n else k


def _index(servos: list[EmulatedServo]) -> dict[int, list[EmulatedServo]]:
    by_id: dict[int, list[EmulatedServo]] = {}
    for s in servos:
        by_id.setdefault(s.id, []).append(s)
    return by_id
