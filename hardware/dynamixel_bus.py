"""`DynamixelBus`: the one module that imports dynamixel-sdk. Every byte on the wire is the SDK's.

Ports: a device path (``/dev/ttyUSB0``), a pty path (``servoface emulate``), or an emulated chain object
(anything with ``open_serial()``), reached in-process through a `PortHandler` subclass whose ``ser`` is the
chain's pyserial-like object — so the SDK's packet, CRC and timeout code runs in every test.

The SDK's reply window is ``tx_time * bytes + 2 * LATENCY_TIMER + 2 ms`` with a module-global
``LATENCY_TIMER = 16``; our port handlers carry their own ``latency_timer_ms`` instead (set from the OS
latency timer, see `servoface.hardware.latency`), so two buses in one process do not fight over a global.
"""

from __future__ import annotations

import os
import select
import struct
import threading
import time
from collections.abc import Iterable, Mapping, Sequence
from itertools import chain as chain_iterables
from types import TracebackType
from typing import Any, Protocol

import dynamixel_sdk as sdk
import serial
from servoface.hardware.bus import BusStats, PingReply, check_ids
from servoface.hardware.crc16 import crc16
from servoface.hardware.errors import (
    BusClosedError,
    BusCorruptError,
    BusDisconnectedError,
    BusError,
    BusTimeoutError,
    HardwareConfigError,
    ServoStatusError,
)
from servoface.hardware.latency import read_latency_timer, sdk_latency_ms, warn_if_high
from servoface.hardware.port_lock import PortLock
from servoface.hardware.raw_write import write_raw
from servoface.hardware.registers import STATUS_ALERT_BIT, STATUS_ERROR_NAMES, Register, slice_value, span
from servoface.hardware.stuffing import add_stuffing_is_identity, remove_stuffing_is_identity

SDK_BAUDS = (
    9600,
    19200,
    38400,
    57600,
    115200,
    230400,
    460800,
    500000,
    576000,
    921600,
    1000000,
    1152000,
    2000000,
    2500000,
    3000000,
    3500000,
    4000000,
)
IN_PROCESS_LATENCY_MS = 2.0
NAP_MIN_S = 0.0005  # a reply further away than this is slept for rather than polled
NAP_MARGIN_S = 0.0002  # wake this much before it (wake-up latency)
POLL_SLICE_S = 0.001  # a port with a file descriptor blocks in select() this long at most per empty read
READ_AHEAD_BYTES = 4096  # one OS read takes up to this much of what has arrived (see readPort)
PARSE_S_START = 50e-6  # per status packet, until measured
MAX_WINDOW_EXTENSION_MS = 100.0
MAX_STRAY_PACKETS = 8  # late status packets of other ids skipped before a Fast Sync Read's combined reply
_PKT_ID = sdk.protocol2_packet_handler.PKT_ID
_PKT_PARAMETER0 = sdk.protocol2_packet_handler.PKT_PARAMETER0
_TXPACKET_MAX_LEN = sdk.protocol2_packet_handler.TXPACKET_MAX_LEN
try:  # pyserial's tcflush (the SDK's clearPort before every instruction) on a vanished device or pty
    import termios  # raises termios.error (EIO), which is no OSError: a disconnect all the same

    _PORT_ERRORS: tuple[type[Exception], ...] = (OSError, termios.error)
except ImportError:
    _PORT_ERRORS = (OSError,)
try:
    from serial.serialposix import Serial as _posix_serial

    _PosixSerial: type | None = _posix_serial
except ImportError:  # not posix: pyserial's own read (see _WindowedPort._read_raw)
    _PosixSerial = None


class TableCrcPacketHandler(sdk.Protocol2PacketHandler):  # type: ignore[misc]
    """The SDK's Protocol 2.0 packet handler with its CRC taken two bytes per table step (`crc16`) instead
    of one Python step per byte: every packet sent and received is checksummed, so this is ~5 % of a cycle.
    The same value for every input (anything `crc16` does not take, e.g. a value over 255, goes to the
    SDK's own loop): tests/hardware/test_bus_sdk_paths.py."""

    def updateCRC(self, crc_accum: int, data_blk_ptr: Any, data_blk_size: int) -> int:  # noqa: N802 - SDK name
        if 0 <= crc_accum <= 0xFFFF and 0 <= data_blk_size <= len(data_blk_ptr):
            try:
                return crc16(bytes(data_blk_ptr[:data_blk_size]), crc_accum)
            except (TypeError, ValueError):
                pass
        return int(super().updateCRC(crc_accum, data_blk_ptr, data_blk_size))

    def addStuffing(self, packet: Any) -> Any:  # noqa: N802 - SDK name
        """The SDK's, but a packet with no ``FF FF FD`` to stuff (nearly every one) is checked by one
        ``bytes.find`` and returned as it is, as the SDK's loop would leave it (`servoface.hardware.stuffing`)."""
        if add_stuffing_is_identity(packet, _TXPACKET_MAX_LEN):
            return packet
        return super().addStuffing(packet)

    def removeStuffing(self, packet: Any) -> Any:  # noqa: N802 - SDK name
        """The SDK's, but a status packet with no ``FF FF FD FD`` is returned as it is, as its loop would."""
        if remove_stuffing_is_identity(packet):
            return packet
        return super().removeStuffing(packet)


class ChainLike(Protocol):
    """An emulated chain: gives a pyserial-like object (write, read, in_waiting, reset_input_buffer...)."""

    def open_serial(self) -> Any: ...


class _WindowedPort(sdk.PortHandler):  # type: ignore[misc]
    """PortHandler whose reply window uses its own latency constant instead of the SDK's global, and a
    monotonic clock instead of the SDK's ``time.time()`` (wall-clock steps of several ms were observed on
    shared machines; each one ended a reply window early and showed up as a spurious timeout/corrupt)."""

    latency_timer_ms: float = float(sdk.port_handler.LATENCY_TIMER)
    packet_timeout: float
    is_open: bool

    def getCurrentTime(self) -> float:  # noqa: N802 (SDK name); milliseconds, as the SDK expects
        return time.monotonic() * 1000.0

    tx_done_s: float = 0.0  # time.monotonic() when the bytes written so far have left the adapter
    _fd: int | None = -2  # -2: not looked up yet

    def writePort(self, packet: Any) -> int:  # noqa: N802 (SDK name)
        """As the SDK's; also notes when the packet will have left (baud arithmetic): no reply can start
        before, so a reader may sleep until then instead of spinning."""
        now = time.monotonic()
        self.tx_done_s = max(now, self.tx_done_s) + len(packet) * self.tx_time_per_byte * 1e-3
        if self._raw_write and self.ser.is_open:  # pyserial's own posix port: one os.write (`write_raw`)
            return write_raw(self.ser, packet)
        written: int = self.ser.write(packet)
        return written

    _rx_ahead: bytes = b""  # bytes read from the port beyond what the SDK asked for, not yet handed over

    def readPort(self, length: int) -> bytes:  # noqa: N802 (SDK name)
        """As the SDK's (up to ``length`` bytes of what has arrived), with two differences. Read ahead:
        take everything that has arrived in one OS read and hand it over as the SDK asks (its ``rxPacket``
        asks for a header, then the rest, per packet: two or more reads per status packet, ~10 us of
        pyserial each); the bytes and their order are the same. And an empty read does not spin blindly
        (the SDK waits for replies in a busy loop): until the instruction has left and ``length`` bytes
        could have come back, sleep (frees the core); after that, a port with a file descriptor blocks in
        ``select`` until bytes come (pyserial's own port: until the end of the reply window, `_raw_read`;
        another: 1 ms at most); an in-process chain yields the GIL only when other threads run (an
        in-process pty server, the caller's own threads: the busy loop would starve them for the 5 ms
        switch interval per turn). ``sleep(0)`` on every empty read cost ~0.1 ms each under load."""
        ahead = self._rx_ahead
        if len(ahead) >= length:
            self._rx_ahead = ahead[length:]
            return ahead[:length]
        size = max(length - len(ahead), READ_AHEAD_BYTES)
        ser = self.ser
        if self._raw_read and ser.is_open:
            if not ahead:
                got = self._read_raw(ser.fd, size, self._wait_s(length))
                if not got:  # waited; what came meanwhile is in _rx_ahead, for the next read
                    return got
            else:
                got = self._read_raw(ser.fd, size, 0.0)
        else:
            got = ser.read(size)
        data = ahead + got if ahead else got
        self._rx_ahead = data[length:]
        data = data[:length]
        if not data and not (self._raw_read and ser.is_open):
            wait_s = self.tx_done_s + length * self.tx_time_per_byte * 1e-3 - time.monotonic()
            if wait_s > NAP_MIN_S:
                time.sleep(wait_s - NAP_MARGIN_S)
            elif (fd := self._fileno()) is not None:  # a real port or pty: block until bytes come (or 1 ms)
                select.select([fd], [], [], POLL_SLICE_S)
            elif threading.active_count() > 1:
                time.sleep(0)
        return data

    _raw_read: bool = False  # self.ser is pyserial's own posix Serial: read its fd directly (see _read_raw)
    _raw_write: bool = False  # ... and its write not replaced either: write its fd directly (`write_raw`)

    def _wait_s(self, length: int) -> float:
        """How long an empty read of ``length`` bytes waits for bytes: until they could have come back
        (the instruction out, ``length`` bytes in: no reply can be sooner) less the wake-up margin; once
        they could, until the end of the reply window (a reply wakes it the moment it arrives), at
        least ``POLL_SLICE_S`` (how long the window end may be overrun, as before: ``isPacketTimeout``
        keeps it open while bytes are waiting)."""
        now = time.monotonic()
        nap_s: float = self.tx_done_s + length * self.tx_time_per_byte * 1e-3 - now
        if nap_s > NAP_MIN_S:
            return nap_s - NAP_MARGIN_S
        window_s: float = (self.packet_start_time + self.packet_timeout) * 1e-3 - now
        return window_s if window_s > POLL_SLICE_S else POLL_SLICE_S

    def _read_raw(self, fd: int, size: int, wait_s: float) -> bytes:
        """pyserial's ``read(size)`` (the SDK opens the port with ``timeout=0``), then, if it got nothing,
        the empty read's wait, in ``os.read`` / ``select`` on the port's fd instead of pyserial's
        ``select`` (timeout 0) then ``os.read`` and a separate wait: a read that gets bytes is one system
        call, an empty one and its wait two. The same bytes (one read of what has arrived) and the same
        errors: a read of 0 bytes is nothing waiting (pyserial's raw mode, VMIN = VTIME = 0) or the far end
        gone, told apart by ``select`` as pyserial does — readable and still 0 bytes is pyserial's "device
        reports readiness" ``SerialException``; an OSError is its ``read failed`` one; EAGAIN / EINTR
        nothing. Bytes that arrive during the wait are kept for the next read (`_rx_ahead`) and this one
        returns nothing, as the SDK's read before the wait did: its ``rxPacket`` checks the reply window
        between the two as before. Not taken: pyserial's ``cancel_read`` pipe, which nothing here uses
        (tests/hardware/test_bus_fast_read.py)."""
        hung_up = False
        try:
            got = os.read(fd, size)
            if not got:
                if select.select([fd], [], [], wait_s)[0]:
                    got = os.read(fd, size)  # what arrived since the first read, or nothing (hung up)
                    hung_up = not got
                    if got and wait_s > 0.0:  # arrived during the wait: the next read's
                        self._rx_ahead, got = got, b""
        except (BlockingIOError, InterruptedError):
            return b""  # pyserial ignores EAGAIN / EINTR (and returns what it has: nothing)
        except OSError as err:
            raise serial.SerialException(f"read failed: {err}") from err
        if hung_up:
            raise serial.SerialException(
                "device reports readiness to read but returned no data "
                "(device disconnected or multiple access on port?)"
            )
        return got

    def _fileno(self) -> int | None:
        """The serial object's file descriptor (None for an in-process chain), looked up once per open."""
        fd: int | None = getattr(self, "_fd", -2)
        if fd == -2:
            try:
                fd = int(self.ser.fileno())
            except (AttributeError, OSError, ValueError, TypeError):
                fd = None
            self._fd = fd
        return fd

    def setupPort(self, cflag_baud: int) -> bool:  # noqa: N802 (SDK name)
        self._fd = -2
        self._rx_ahead = b""
        self._raw_read = False
        self._raw_write = False
        ok: bool = super().setupPort(cflag_baud)
        ser: Any = self.ser  # the SDK's serial.Serial(..., timeout=0), its read not replaced
        posix = _PosixSerial is not None and type(ser) is _PosixSerial
        self._raw_read = bool(ok and posix and "read" not in vars(ser) and ser.timeout == 0 and ser.is_open)
        self._raw_write = bool(self._raw_read and "write" not in vars(ser) and ser.write_timeout is None)
        return ok

    def clearPort(self) -> None:  # noqa: N802 (SDK name)
        """As the SDK's (drop what has arrived), including what was read ahead."""
        self._rx_ahead = b""
        self.ser.reset_input_buffer()

    def closePort(self) -> None:  # noqa: N802 (SDK name)
        self._rx_ahead = b""
        self._raw_read = False
        self._raw_write = False
        self._fd = -2
        super().closePort()

    def getBytesAvailable(self) -> int:  # noqa: N802 (SDK name)
        """As the SDK's (bytes arrived and not yet read), including what was read ahead."""
        return len(self._rx_ahead) + int(self.ser.in_waiting)

    def nap_until(self, t_s: float) -> None:
        """Sleep until ``t_s`` (time.monotonic) less a margin, if that is worth a sleep."""
        wait_s = t_s - time.monotonic()
        if wait_s > NAP_MIN_S:
            time.sleep(wait_s - NAP_MARGIN_S)

    def isPacketTimeout(self) -> bool:  # noqa: N802 (SDK name)
        """The SDK reads, then checks the clock: a thread descheduled between the two (common on a loaded
        machine) times out with the whole reply already waiting. Close the window only if nothing is —
        and at most ``MAX_WINDOW_EXTENSION_MS`` late, so a chattering line cannot hold it open."""
        since = self.getTimeSinceStart()
        if since > self.packet_timeout:
            late = since - self.packet_timeout < MAX_WINDOW_EXTENSION_MS
            if late and self.is_open and self.getBytesAvailable() > 0:
                return False
            self.packet_timeout = 0
            return True
        return False

    def setPacketTimeout(self, packet_length: int) -> None:  # noqa: N802 (SDK name)
        self.packet_start_time = self.getCurrentTime()
        self.packet_timeout = self.tx_time_per_byte * packet_length + self.latency_timer_ms * 2.0 + 2.0


class _ChainPort(_WindowedPort):
    """In-process port: ``openPort``/``setBaudRate``/``setupPort`` take the chain's serial object."""

    def __init__(self, chain: ChainLike) -> None:
        super().__init__(f"emulator:{type(chain).__name__}@{id(chain):x}")
        self.chain = chain

    def setupPort(self, cflag_baud: int) -> bool:  # noqa: N802 (SDK name)
        if self.is_open:
            self.closePort()
        self._fd = None
        self._rx_ahead = b""
        self.ser = self.chain.open_serial()
        if hasattr(self.ser, "baudrate"):
            self.ser.baudrate = self.baudrate
        self.is_open = True
        self.ser.reset_input_buffer()
        self.tx_time_per_byte = (1000.0 / self.baudrate) * 10.0
        return True


def _is_pty(path: str) -> bool:
    import os

    real = os.path.realpath(path)
    return real.startswith("/dev/pts/") or os.path.basename(real).startswith("pty")


class DynamixelBus:
    """A Protocol 2.0 chain over dynamixel-sdk. Implements `servoface.hardware.bus.ServoBus`.

    ``latency_timer_ms``: the SDK latency constant for this port (default: from the OS timer for a real
    USB adapter, 16 ms for a pty, 2 ms in-process). ``warn_latency``: warn (`UsbLatencyWarning`) when an FTDI
    adapter still has its 16 ms default.
    """

    def __init__(
        self,
        port: str | ChainLike,
        baud: int = 1_000_000,
        *,
        latency_timer_ms: float | None = None,
        warn_latency: bool = True,
    ) -> None:
        if baud not in SDK_BAUDS:
            raise HardwareConfigError(f"baud {baud} cannot be opened by dynamixel-sdk; expected one of {SDK_BAUDS}")
        self.baud = baud
        self.stats = BusStats()
        self.alerts: set[int] = set()
        self._packet = TableCrcPacketHandler()
        self._last_ids: tuple[tuple[int, ...] | None, list[int]] = (None, [])
        self._read_plans: dict[tuple[Register, ...], tuple[int, int, tuple[Any, ...], str]] = {}
        self._lock: PortLock | None = None
        self._pending: tuple[list[int], tuple[Any, ...], int, int, bool, str] | None = None
        self._parse_s = PARSE_S_START  # measured CPU per status packet already waiting (see _nap_for_replies)
        if isinstance(port, str):
            self.port_name = port
            self._lock = PortLock(port)  # one controller per chain: held while the port is open
            self._port: _WindowedPort = _WindowedPort(port)
            timer = read_latency_timer(port)
            if warn_latency:
                warn_if_high(timer)
            self.latency_timer_ms = (
                float(latency_timer_ms) if latency_timer_ms is not None else float(sdk_latency_ms(timer, _is_pty(port)))
            )
        else:
            if not hasattr(port, "open_serial"):
                raise HardwareConfigError(f"port must be a path or an emulated chain with open_serial(), got {port!r}")
            self._port = _ChainPort(port)
            self.port_name = self._port.port_name
            self.latency_timer_ms = IN_PROCESS_LATENCY_MS if latency_timer_ms is None else float(latency_timer_ms)
        self._port.latency_timer_ms = self.latency_timer_ms

    # -- life cycle ---------------------------------------------------------------------------------
    @property
    def is_open(self) -> bool:
        return bool(self._port.is_open)

    def open(self) -> None:
        """Take the port's lock (`PortLockedError` names the holder's pid), then open it."""
        if self.is_open:
            return
        if self._lock is not None:
            self._lock.acquire()
        self._port.baudrate = self.baud
        try:
            ok = self._port.openPort()
        except (OSError, ValueError) as err:
            self._release_lock()
            raise BusDisconnectedError(
                f"cannot open port {self.port_name} at {self.baud} bps: {err}{_open_hint(err)}"
            ) from err
        if not ok:
            self._release_lock()
            raise BusError(f"cannot open port {self.port_name} at {self.baud} bps")

    def _close_port(self) -> None:
        if self._port.is_open:
            try:
                self._port.closePort()
            except OSError:
                self._port.is_open = False
        self._port.is_using = False

    def _release_lock(self) -> None:
        if self._lock is not None:
            self._lock.release()

    def close(self) -> None:
        self._close_port()
        self._release_lock()

    def reopen(self) -> None:
        """Close and open the port again (after a USB re-plug or a dropped pty), keeping its lock."""
        self._close_port()
        self._pending = None
        self.open()

    def drain(self, quiet_s: float = 0.05, max_s: float = 0.3) -> int:
        """Discard what arrives until the line has been quiet for ``quiet_s`` (at most ``max_s``); returns
        the bytes dropped. After a timeout, a late reply still on its way must neither collide with the next
        instruction's reply nor be taken for it."""
        if not self._port.is_open:
            return 0
        dropped = 0
        start = last = time.monotonic()
        try:
            while True:
                now = time.monotonic()
                if now - last >= quiet_s or now - start >= max_s:
                    return dropped
                n = self._port.getBytesAvailable()
                if n:
                    dropped += len(self._port.readPort(n))
                    last = time.monotonic()
                else:
                    time.sleep(0.002)
        except OSError:
            return dropped

    def __enter__(self) -> DynamixelBus:
        self.open()
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"DynamixelBus({self.port_name!r}, baud={self.baud}, latency_timer_ms={self.latency_timer_ms:g})"

    def sdk_handlers(self) -> tuple[Any, Any]:
        """(PortHandler, PacketHandler) of this bus, for code that drives the stock SDK directly on the same
        port (`servoface.hardware.stock_loop`, the benches' reference loop). Do not use the bus meanwhile."""
        return self._port, self._packet

    # -- plumbing -----------------------------------------------------------------------------------
    def _call(self, fn: Any, *args: Any) -> Any:
        if not self._port.is_open:
            raise BusClosedError(f"bus on {self.port_name} is not open")
        try:
            return fn(*args)
        except _PORT_ERRORS as err:  # pyserial's SerialException is an OSError; termios.error is not
            self._port.is_using = False
            raise BusDisconnectedError(f"port {self.port_name} failed: {err}") from err
        except (IndexError, TypeError) as err:  # the SDK indexing a short/odd reply
            self._port.is_using = False
            self.stats.corrupt += 1
            raise BusCorruptError(f"malformed reply on {self.port_name}: {err!r}") from err

    def _check(self, comm: int, err: int, what: str, servo_ids: Sequence[int]) -> None:
        self.stats.transactions += 1
        ids = tuple(servo_ids)
        if comm == sdk.COMM_RX_TIMEOUT:
            self.stats.timeouts += 1
            raise BusTimeoutError(f"{what}: no reply from servo(s) {list(ids)} on {self.port_name}", ids)
        if comm == sdk.COMM_RX_CORRUPT:
            self.stats.corrupt += 1
            raise BusCorruptError(f"{what}: corrupt reply (bad CRC or truncated) from {list(ids)}", ids)
        if comm == sdk.COMM_PORT_BUSY:
            raise BusError(f"{what}: port {self.port_name} is in use by another caller (one thread owns a bus)", ids)
        if comm != sdk.COMM_SUCCESS:
            raise BusError(f"{what}: {self._packet.getTxRxResult(comm)} (code {comm})", ids)
        if err & 0x7F:
            self.stats.status_errors += 1
            name = STATUS_ERROR_NAMES.get(err & 0x7F, f"error {err & 0x7F}")
            raise ServoStatusError(ids[0], err, f"{what}: servo {ids[0]} answered {name}")
        if err & STATUS_ALERT_BIT:
            self.stats.alerts += 1
            self.alerts.update(ids[:1])

    # -- single-servo instructions ------------------------------------------------------------------
    def ping(self, servo_id: int) -> PingReply:
        """Ping one servo: model number and firmware version, from its one status packet.

        (The SDK's ``ping()`` drops the firmware byte, so the same packet goes through ``txRxPacket``.)
        """
        check_ids([servo_id])
        txpacket = [0] * 10
        txpacket[4], txpacket[5], txpacket[6], txpacket[7] = servo_id, 3, 0, sdk.INST_PING
        rx, comm, err = self._call(self._packet.txRxPacket, self._port, txpacket)
        self._check(comm, err, f"ping {servo_id}", (servo_id,))
        if rx is None or len(rx) < 14:
            self.stats.corrupt += 1
            raise BusCorruptError(f"ping {servo_id}: short status packet", (servo_id,))
        return PingReply(servo_id, rx[9] | rx[10] << 8, rx[11])

    def broadcast_ping(self) -> dict[int, PingReply]:
        """Every servo on the chain. Waits the SDK's full fixed window (~0.8 s at 1 Mbps): start-up only."""
        found, comm = self._call(self._packet.broadcastPing, self._port)
        self.stats.transactions += 1
        if comm == sdk.COMM_RX_TIMEOUT:
            return {}
        if comm not in (sdk.COMM_SUCCESS, sdk.COMM_RX_CORRUPT) or (comm == sdk.COMM_RX_CORRUPT and not found):
            self._check(comm, 0, "broadcast ping", ())
        return {int(sid): PingReply(int(sid), int(v[0]), int(v[1])) for sid, v in sorted(found.items())}

    def read(self, servo_id: int, register: Register) -> int:
        return self.read_many(servo_id, (register,))[register]

    def read_many(self, servo_id: int, registers: Sequence[Register]) -> dict[Register, int]:
        """Read a contiguous block covering ``registers`` from one servo; values signed per register."""
        check_ids([servo_id])
        start, length = span(tuple(registers))
        data, comm, err = self._call(self._packet.readTxRx, self._port, servo_id, start, length)
        self._check(comm, err, f"read {[r.name for r in registers]} from servo {servo_id}", (servo_id,))
        if len(data) < length:
            self.stats.corrupt += 1
            raise BusCorruptError(f"servo {servo_id}: {len(data)} bytes read, expected {length}", (servo_id,))
        return {r: slice_value(r, start, data) for r in registers}

    def write(self, servo_id: int, register: Register, value: int) -> None:
        check_ids([servo_id])
        data = list(register.encode(value))
        comm, err = self._call(self._packet.writeTxRx, self._port, servo_id, register.address, register.size, data)
        self.stats.bytes_written += 12 + register.size
        self._check(comm, err, f"write {register.name}={value} to servo {servo_id}", (servo_id,))

    def reboot(self, servo_id: int) -> None:
        check_ids([servo_id])
        comm, err = self._call(self._packet.reboot, self._port, servo_id)
        self._check(comm, err & 0x7F, f"reboot servo {servo_id}", (servo_id,))

    # -- group instructions -------------------------------------------------------------------------
    def sync_write(self, register: Register, values: Mapping[int, int]) -> None:
        """One Sync Write packet setting ``register`` on every servo in ``values`` (no replies).

        The parameters (``id data...`` per servo, in ``values`` order: what ``GroupSyncWrite.makeParam``
        builds) go to the SDK's own ``syncWriteTxOnly``, which frames, stuffs, checksums and sends them;
        the per-frame goal write skips the group object and its per-servo ``addParam``, and packs the
        parameters of a frame of plain in-range ints in one ``struct`` call (the SDK copies them into its
        packet list as ints either way; same bytes: tests/hardware/test_bus_sdk_paths.py)."""
        ids = self._ids(values)
        if not ids:
            return
        size, signed = register.size, register.signed
        lo, hi = register.value_range
        vals = [values[sid] for sid in ids]
        pack = _pairs_struct(len(ids), size, signed)
        param: bytes | list[int]
        if pack is not None and all(type(v) is int for v in vals) and lo <= min(vals) and max(vals) <= hi:
            param = pack.pack(*chain_iterables.from_iterable(zip(ids, vals, strict=True)))  # one C call
        else:
            param = []
            for sid, value in zip(ids, vals, strict=True):  # encode all before sending any
                param.append(sid)
                if type(value) is int and lo <= value <= hi:
                    param += value.to_bytes(size, "little", signed=signed)
                else:
                    param += register.encode(value)  # checks and raises with the register's message
        comm = self._call(self._packet.syncWriteTxOnly, self._port, register.address, size, param, len(param))
        self.stats.bytes_written += 14 + len(param)
        self._check(comm, 0, f"sync write {register.name}", ids)

    def _ids(self, servo_ids: Iterable[int]) -> list[int]:
        """`check_ids`, remembered for the last id tuple (the same servos every cycle)."""
        key = tuple(servo_ids)
        if key == self._last_ids[0]:
            return self._last_ids[1]
        ids = check_ids(key)
        self._last_ids = (key, ids)
        return ids

    def sync_read(
        self, servo_ids: Sequence[int], registers: Sequence[Register], *, fast: bool = False
    ) -> dict[int, dict[Register, int]]:
        """One Sync Read (or Fast Sync Read) of the block covering ``registers`` from ``servo_ids``.

        All-or-nothing (the SDK's contract): any silent servo fails the call for every id. A reply with the
        Alert bit adds its id to `alerts` (the reply's error byte, kept from the SDK's ``readRx``).
        """
        self.sync_read_start(servo_ids, registers, fast=fast)
        return self.sync_read_finish()

    def sync_read_start(self, servo_ids: Sequence[int], registers: Sequence[Register], *, fast: bool = False) -> None:
        """Send the (Fast) Sync Read instruction and return while the replies are on the wire.

        `sync_read_finish` collects them; in between the caller may compute but not use the bus (the SDK
        keeps the port marked busy). The reply window is the SDK's, started when the instruction left.
        """
        ids = self._ids(servo_ids)
        regs = tuple(registers)
        prepared = self._read_plans.get(regs)  # span, message and field offsets: once per register tuple
        if prepared is None:
            start, length = span(regs)
            fields = tuple((r, r.address - start, r.address - start + r.size, r.signed) for r in regs)
            prepared = (start, length, fields, f"sync read {[r.name for r in regs]}")
            self._read_plans[regs] = prepared
        start, length, fields, what = prepared
        if fast:
            what = "fast " + what
        self._pending = (ids, fields, start, length, fast, what)
        if not ids:
            return
        # the SDK's own syncReadTx with the id list `GroupSyncRead.makeParam` builds (same bytes, no group)
        comm = self._call(self._packet.syncReadTx, self._port, start, length, ids, len(ids), fast)
        if comm != sdk.COMM_SUCCESS:
            self._pending = None
            self._check(comm, 0, what, ids)

    def sync_read_finish(self, *, patient: bool = False) -> dict[int, dict[Register, int]]:
        """The replies to the instruction `sync_read_start` sent (see `sync_read` for the contract).

        ``patient``: the caller has time to spare (a paced loop): sleep until every reply should be in, then
        parse them at once (least CPU). Otherwise wake while they arrive so the parse ends with the last one
        (least latency: back-to-back cycles)."""
        pending, self._pending = self._pending, None
        if pending is None:
            raise BusError(f"sync_read_finish on {self.port_name} without a sync_read_start")
        ids, fields, start, length, fast, what = pending
        if not ids:
            return {}
        if fast:
            return self._fast_values(self._fast_reply(ids, length, what), ids, length, fields, what)
        blocks = self._status_blocks(ids, length, what, patient)
        return self._values(blocks, ids, length, fields, what)

    def _values(
        self,
        blocks: Mapping[int, tuple[bytes, int]],
        ids: list[int],
        length: int,
        fields: tuple[tuple[Register, int, int, bool], ...],
        what: str,
    ) -> dict[int, dict[Register, int]]:
        """Per servo: its block's values (``fields``: register, start, end, signed), its Alert bit kept."""
        self._check(sdk.COMM_SUCCESS, 0, what, ids)
        out: dict[int, dict[Register, int]] = {}
        from_bytes = int.from_bytes
        one = fields[0] if len(fields) == 1 else None  # the per-cycle position read: one field
        two = fields if len(fields) == 2 else None  # the status and thermal groups: two (unrolled below)
        for sid in ids:
            raw, err = blocks.get(sid, (b"", 0))
            if len(raw) < length:
                self.stats.corrupt += 1
                raise BusCorruptError(f"{what}: servo {sid} returned {len(raw)} bytes", ids)
            if err & STATUS_ALERT_BIT:
                self.stats.alerts += 1
                self.alerts.add(sid)
            if one is not None:
                out[sid] = {one[0]: from_bytes(raw[one[1] : one[2]], "little", signed=one[3])}
            elif two is not None:
                (r0, a0, b0, s0), (r1, a1, b1, s1) = two
                out[sid] = {
                    r0: from_bytes(raw[a0:b0], "little", signed=s0),
                    r1: from_bytes(raw[a1:b1], "little", signed=s1),
                }
            else:
                out[sid] = {r: from_bytes(raw[a:b], "little", signed=sg) for r, a, b, sg in fields}
        return out

    def _status_blocks(self, ids: list[int], length: int, what: str, patient: bool) -> dict[int, tuple[bytes, int]]:
        """One status packet per servo, read by the SDK's ``readRx`` (as ``GroupSyncRead.rxPacket`` does,
        but keeping each packet's error byte)."""
        blocks: dict[int, tuple[bytes, int]] = {}
        read_rx, port = self._packet.readRx, self._port
        backlog = self._nap_for_replies(len(ids), 11 + length, patient)
        t0 = time.perf_counter()
        for k, sid in enumerate(ids):
            data, comm, err = self._call(read_rx, port, sid, length)
            if comm != sdk.COMM_SUCCESS:
                self._check(comm, 0, what, ids)
            blocks[sid] = (bytes(data), err)
            if k + 1 == backlog:  # the packets that were waiting: their parse cost, for the next nap
                self._parse_s = 0.8 * self._parse_s + 0.2 * (time.perf_counter() - t0) / backlog
        return blocks

    def _nap_for_replies(self, n_packets: int, packet_bytes: int, patient: bool) -> int:
        """Sleep while the first of ``n_packets`` status packets are on the wire, waking when the parse of
        the ones already in (at the measured cost per packet) would end as the last one arrives — or, when
        ``patient``, once all should be in; returns how many should be waiting then (0: no sleep). Return
        Delay Time is not counted: wakes early rather than late."""
        port = self._port
        packet_s = packet_bytes * port.tx_time_per_byte * 1e-3
        backlog = n_packets if patient else int(n_packets * packet_s / (packet_s + self._parse_s))
        if backlog < 2:
            return 0
        wake_s = port.tx_done_s + backlog * packet_s
        if wake_s - time.monotonic() <= NAP_MIN_S or port.getBytesAvailable() > 0:  # already flowing (or no
            return 0  # wire time, as in an emulator's fast tests)
        port.nap_until(wake_s)
        return backlog

    def _fast_reply(self, ids: list[int], length: int, what: str) -> bytes:
        """The one combined Fast Sync Read reply's parameters (the SDK's ``fastSyncReadRx``)."""
        port = self._port  # one packet: sleep until its last bytes, less its parse (~ 2 packets' worth)
        if port.getBytesAvailable() == 0:
            port.nap_until(
                port.tx_done_s + (8 + len(ids) * (length + 4)) * port.tx_time_per_byte * 1e-3 - 2 * self._parse_s
            )
        return self._combined_reply((length + 4) * len(ids), what, ids)

    def _fast_values(
        self,
        raw: bytes,
        ids: list[int],
        length: int,
        fields: tuple[tuple[Register, int, int, bool], ...],
        what: str,
    ) -> dict[int, dict[Register, int]]:
        """`_values` of the combined reply's blocks (`_fast_blocks`). The per-cycle position read (one field,
        every block's id the one asked for at its place: the usual reply) is read in one pass, no blocks
        dict: the same values, alerts, counters and errors (tests/hardware/test_bus_sdk_paths.py)."""
        step = length + 4
        n = len(ids)
        if len(fields) != 1 or len(raw) < n * step - 2 or raw[1::step][:n] != bytes(ids):
            return self._values(self._fast_blocks(raw, ids, length, what), ids, length, fields, what)
        self._check(sdk.COMM_SUCCESS, 0, what, ids)
        register, a, b, signed = fields[0]
        from_bytes = int.from_bytes
        out: dict[int, dict[Register, int]] = {}
        at = 2
        for sid in ids:
            if raw[at - 2] & STATUS_ALERT_BIT:
                self.stats.alerts += 1
                self.alerts.add(sid)
            out[sid] = {register: from_bytes(raw[at + a : at + b], "little", signed=signed)}
            at += step
        return out

    def _fast_blocks(self, raw: bytes, ids: list[int], length: int, what: str) -> dict[int, tuple[bytes, int]]:
        """The combined reply split per servo: ``ERR ID data CRC`` each, as
        ``GroupSyncRead.fastSyncReadRxPacket`` does, but keeping the error bytes."""
        blocks: dict[int, tuple[bytes, int]] = {}
        wanted = set(ids)
        for k in range(len(ids)):
            at = k * (length + 4)
            if at + 2 + length > len(raw) or raw[at + 1] not in wanted:
                self.stats.corrupt += 1
                raise BusCorruptError(f"{what}: combined reply block {k} is malformed", ids)
            blocks[raw[at + 1]] = (raw[at + 2 : at + 2 + length], raw[at])
        return blocks

    def _combined_reply(self, n_bytes: int, what: str, ids: list[int]) -> bytes:
        """The parameters of the combined (broadcast-id) status packet, read as the SDK's ``fastSyncReadRx``
        does (its ``rxPacket``). A status packet of another id first (a servo's late reply to an earlier
        instruction) is skipped, as the SDK's ``readRx`` skips one in a plain Sync Read, within the same
        reply window; ``fastSyncReadRx`` would return no data for it, on which the SDK's own
        ``GroupSyncRead.fastSyncRead`` raises IndexError. What cannot be read is a typed bus error."""
        rx_packet, port = self._packet.rxPacket, self._port
        for _ in range(MAX_STRAY_PACKETS + 1):
            packet, comm = self._call(rx_packet, port, True)
            if comm != sdk.COMM_SUCCESS:
                self._check(comm, 0, what, ids)
            if len(packet) > _PKT_PARAMETER0 and packet[_PKT_ID] == sdk.BROADCAST_ID:
                return bytes(packet[_PKT_PARAMETER0 : _PKT_PARAMETER0 + n_bytes])
            self.stats.stray += 1
        self.stats.corrupt += 1
        raise BusCorruptError(f"{what}: only status packets of other ids came back, no combined reply", ids)

    def bulk_read(
        self, requests: Mapping[int, Sequence[Register]], *, fast: bool = False
    ) -> dict[int, dict[Register, int]]:
        """One Bulk Read (or Fast Bulk Read): a different block per servo. All-or-nothing."""
        ids = check_ids(requests)
        if not ids:
            return {}
        spans = {sid: span(tuple(requests[sid])) for sid in ids}
        group = sdk.GroupBulkRead(self._port, self._packet)
        for sid in ids:
            group.addParam(sid, *spans[sid])
        comm = self._call(group.fastBulkRead if fast else group.txRxPacket)
        self._check(comm, 0, f"{'fast ' if fast else ''}bulk read", ids)
        out: dict[int, dict[Register, int]] = {}
        for sid in ids:
            start, length = spans[sid]
            block = group.data_dict[sid][0]
            if len(block) < length:
                self.stats.corrupt += 1
                raise BusCorruptError(f"bulk read: servo {sid} returned {len(block)} of {length} bytes", ids)
            out[sid] = {r: slice_value(r, start, block) for r in requests[sid]}
        return out

    def bulk_write(self, writes: Mapping[int, Mapping[Register, int]]) -> None:
        """One Bulk Write: per servo, a contiguous run of registers (gaps are refused)."""
        ids = check_ids(writes)
        group = sdk.GroupBulkWrite(self._port, self._packet)
        for sid in ids:
            regs = sorted(writes[sid], key=lambda r: r.address)
            start, length = span(tuple(regs))
            if sum(r.size for r in regs) != length:
                raise HardwareConfigError(f"bulk write to servo {sid}: registers {[r.name for r in regs]} leave gaps")
            data = b"".join(r.encode(writes[sid][r]) for r in regs)
            group.addParam(sid, start, length, list(data))
        if not ids:
            return
        comm = self._call(group.txPacket)
        self._check(comm, 0, "bulk write", ids)


_PAIR_CODES = {(1, False): "B", (1, True): "b", (2, False): "H", (2, True): "h", (4, False): "I", (4, True): "i"}
_PAIR_STRUCTS: dict[tuple[int, int, bool], struct.Struct] = {}


def _pairs_struct(n: int, size: int, signed: bool) -> struct.Struct | None:
    """``<`` then ``n`` times (id byte, value of ``size`` bytes, little-endian): a Sync Write's parameters."""
    key = (n, size, signed)
    packer = _PAIR_STRUCTS.get(key)
    if packer is None:
        code = _PAIR_CODES.get((size, signed))
        if code is None:
            return None
        packer = _PAIR_STRUCTS[key] = struct.Struct("<" + ("B" + code) * n)
    return packer


def _open_hint(err: BaseException) -> str:
    """What to do about a port that would not open (permission, missing device, busy)."""
    text = str(err)
    code = getattr(err, "errno", None)
    if code == 13 or "Errno 13" in text or "Permission denied" in text:
        return (
            "; no permission: on Linux add yourself to the 'dialout' group "
            "(sudo usermod -aG dialout $USER, then log out and in again)"
        )
    if code == 2 or "Errno 2" in text or "No such file" in text:
        return "; no such device: check the cable and the name (ls /dev/ttyUSB* /dev/ttyACM*)"
    if code == 16 or "Errno 16" in text or "busy" in text.lower():
        return "; the port is busy: another program has it open"
    return ""
