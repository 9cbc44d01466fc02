"""Helpers for the emulator tests: a raw-bytes transaction and a stock-SDK port on an in-process chain."""

from __future__ import annotations

from typing import Any

from servoface.hardware.emulator import EmulatedSerial, Packet, ServoChain, build_instruction
from servoface.hardware.emulator.packet import PacketReceiver


def quick_chain(ids: Any = range(1, 4), model: str = "XL330-M288", **kw: Any) -> tuple[ServoChain, EmulatedSerial]:
    """A manual-clock chain without wire time, and its serial endpoint."""
    kw.setdefault("wire_time", False)
    kw.setdefault("clock", "manual")
    chain = ServoChain.create(ids=ids, model=model, **kw)
    return chain, chain.open_serial()


def transact(ser: EmulatedSerial, packet_id: int, instruction: int, params: bytes = b"") -> list[Packet]:
    """Send one instruction; return every status packet readable right after (wire time off)."""
    ser.reset_input_buffer()
    ser.write(build_instruction(packet_id, instruction, params))
    return PacketReceiver().feed(ser.read(1 << 16))


def le(value: int, size: int) -> bytes:
    return (value & ((1 << (8 * size)) - 1)).to_bytes(size, "little")


def sdk_port(chain: ServoChain, baud: int | None = None) -> tuple[Any, Any]:
    """Stock dynamixel_sdk PortHandler + PacketHandler(2.0) talking to ``chain`` in-process."""
    import dynamixel_sdk as sdk

    port = sdk.PortHandler("emulated")
    port.ser = chain.open_serial()
    port.baudrate = baud or chain.baud
    port.ser.baudrate = port.baudrate
    port.is_open = True
    port.tx_time_per_byte = 10_000.0 / port.baudrate
    return port, sdk.PacketHandler(2.0)
