"""Software emulator of a Dynamixel Protocol 2.0 servo chain: the far end of the wire.

Deliberately independent of dynamixel-sdk and of servoface's driver code: its packet code and register
maps are a second transcription of the e-manual, so one wrong address cannot pass its own test.

    chain = ServoChain.create(ids=range(1, 25), model="XL330-M288", baud=1_000_000)
    ser = chain.open_serial()      # in-process pyserial-like endpoint
    path = chain.serve_pty()       # or a pseudo-terminal any program can open
"""

from hardware.emulator.chain import ServoChain
from hardware.emulator.clock import ManualClock, RealClock
from hardware.emulator.control_table import ControlTable, Register
from hardware.emulator.errors import (
    EmulatorConfigError,
    EmulatorError,
    PacketError,
    PortClosedError,
    RegisterError,
)
from hardware.emulator.faults import KINDS as FAULT_KINDS
from hardware.emulator.faults import Fault, FaultSchedule
from hardware.emulator.models import MODELS, ModelSpec, get_model
from hardware.emulator.packet import Instruction, Packet, build_instruction, build_status, parse_packet
from hardware.emulator.packet_log import LogEntry
from hardware.emulator.serial_port import EmulatedSerial
from hardware.emulator.servo import EmulatedServo

__all__ = [
    "FAULT_KINDS",
    "MODELS",
    "ControlTable",
    "EmulatedSerial",
    "EmulatedServo",
    "EmulatorConfigError",
    "EmulatorError",
    "Fault",
    "FaultSchedule",
    "Instruction",
    "LogEntry",
    "ManualClock",
    "ModelSpec",
    "Packet",
    "PacketError",
    "PortClosedError",
    "RealClock",
    "Register",
    "RegisterError",
    "ServoChain",
    "build_instruction",
    "build_status",
    "get_model",
    "parse_packet",
]
