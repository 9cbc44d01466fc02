"""Software emulator of a Dynamixel Protocol 2.0 servo chain: the far end of the wire.

Deliberately independent of dynamixel-sdk and of servoface's driver code: its packet code and register
maps are a second transcription of the e-manual, so one wrong address cannot pass its own test.

    chain = ServoChain.create(ids=range(1, 25), model="XL330-M288", baud=1_000_000)
    ser = chain.open_serial()      # in-process pyserial-like endpoint
    path = chain.serve_pty()       # or a pseudo-terminal any program can open
"""

from servoface.hardware.emulator.chain import ServoChain
from servoface.hardware.emulator.clock import ManualClock, RealClock
from servoface.hardware.emulator.control_table import ControlTable, Register
from servoface.hardware.emulator.errors import (
    EmulatorConfigError,
    EmulatorError,
    PacketError,
    PortClosedError,
    RegisterError,
)
from servoface.hardware.emulator.faults import KINDS as FAULT_KINDS
from servoface.hardware.emulator.faults import Fault, FaultSchedule
from servoface.hardware.emulator.models import MODELS, ModelSpec, get_model
from servoface.hardware.emulator.packet import (
    Instruction,
    Packet,
    build_instruction,
    build_status,
    parse_packet,
)
from servoface.hardware.emulator.packet_log import LogEntry
from servoface.hardware.emulator.realism import Realism
from servoface.hardware.emulator.serial_port import EmulatedSerial
from servoface.hardware.emulator.servo import EmulatedServo

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
    "Realism",
    "Register",
    "RegisterError",
    "ServoChain",
    "build_instruction",
    "build_status",
    "get_model",
    "parse_packet",
]
