"""In-process serial endpoint: the pyserial subset dynamixel_sdk's ``PortHandler`` uses, wired to a chain.

Hand it to the SDK with ``port_handler.ser = chain.open_serial(); port_handler.is_open = True`` (and set
``port_handler.tx_time_per_byte``), or subclass ``PortHandler`` so ``setupPort`` returns it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from servoface.hardware.emulator.errors import EmulatorConfigError, PortClosedError

if TYPE_CHECKING:
    from servoface.hardware.emulator.chain import ServoChain


class EmulatedSerial:
    """``write``/``read`` (non-blocking)/``in_waiting``/``reset_*``/``flush``/``close``; ``baudrate`` settable
    (a baud the servos are not set to means they hear garbage and stay silent)."""

    def __init__(self, chain: ServoChain, *, port: str = "emulated://servo-chain", baudrate: int | None = None) -> None:
        self._chain = chain
        self.port = port
        self.name = port
        self._baudrate = int(baudrate if baudrate is not None else chain.baud)
        self.timeout: float | None = 0
        self.write_timeout: float | None = None
        self.bytesize = 8
        self.parity = "N"
        self.stopbits = 1
        self.is_open = True

    @property
    def chain(self) -> ServoChain:
        return self._chain

    @property
    def baudrate(self) -> int:
        return self._baudrate

    @baudrate.setter
    def baudrate(self, value: int) -> None:
        if int(value) <= 0:
            raise EmulatorConfigError(f"baudrate {value}: expected a positive number of bits per second")
        self._baudrate = int(value)

    def _check(self) -> None:
        if not self.is_open:
            raise PortClosedError(f"serial endpoint {self.port} is closed")
        if self._chain.closed:
            raise PortClosedError(f"serial endpoint {self.port}: its servo chain was closed")

    def write(self, data: bytes | bytearray | list[int]) -> int:
        self._check()
        if not isinstance(data, bytes | bytearray):
            data = bytes(data)
        n = self._chain.host_write(data, self._baudrate)
        self._chain.wait_tx(self._baudrate)  # back-pressure: a real port blocks at the wire rate
        return n

    def read(self, size: int = 1) -> bytes:
        self._check()
        return self._chain.host_read(size)

    @property
    def in_waiting(self) -> int:
        self._check()
        return self._chain.host_in_waiting()

    def inWaiting(self) -> int:  # noqa: N802 - pyserial 2 spelling
        return self.in_waiting

    def reset_input_buffer(self) -> None:
        self._check()
        self._chain.host_reset_input()

    def flushInput(self) -> None:  # noqa: N802 - pyserial 2 spelling
        self.reset_input_buffer()

    def reset_output_buffer(self) -> None:
        self._check()

    def flush(self) -> None:
        """Wait until every written byte is on the wire (pyserial: tcdrain)."""
        self._check()
        self._chain.wait_tx(self._baudrate, drain=True)

    def open(self) -> None:
        self.is_open = True

    def close(self) -> None:
        self.is_open = False

    def __enter__(self) -> EmulatedSerial:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
