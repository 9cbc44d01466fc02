"""The plain stock-SDK control loop that `servoface bench` measures servoface against, in the same run.

Per cycle it does what the SDK's own sync read/write example does: ``GroupSyncWrite.addParam`` for every
servo, ``txPacket``, ``clearParam``; ``GroupSyncRead.txRxPacket``; ``isAvailable`` + ``getData`` for every
servo. The SDK objects are built once, the packet handler too (the SDK's own, not the bus's table-CRC one).
The port is the one `DynamixelBus` opens (its `sdk_handlers`: the
same in-process chain connection, reply window and GIL-yielding empty read), so a comparison measures what
runs above the port. dynamixel_sdk is reached through `servoface.hardware.dynamixel_bus` (the one module
that imports it).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from servoface.hardware.bus import ServoBus
from servoface.hardware.dynamixel_bus import DynamixelBus, sdk  # the one module that imports dynamixel_sdk
from servoface.hardware.errors import BusError, HardwareConfigError
from servoface.hardware.registers import Register

GOAL = Register.GOAL_POSITION
PRESENT = Register.PRESENT_POSITION


class StockSdkLoop:
    """Sync Write of Goal Position to ``write_ids`` + Sync Read of Present Position from ``read_ids``."""

    def __init__(
        self,
        bus: ServoBus,
        write_ids: Sequence[int],
        read_ids: Sequence[int] | None = None,
        *,
        fast: bool = False,
    ) -> None:
        """``fast``: read with ``GroupSyncRead.fastSyncRead`` (Fast Sync Read) instead of ``txRxPacket``."""
        if not isinstance(bus, DynamixelBus):
            raise HardwareConfigError(f"the stock SDK loop needs a DynamixelBus (an SDK port), got {bus!r}")
        self.port, _ = bus.sdk_handlers()
        self.packet: Any = sdk.PacketHandler(2.0)  # the stock SDK's own (the bus's checksums faster)
        self.fast = fast
        self.write_ids = list(write_ids)
        self.read_ids = list(read_ids if read_ids is not None else write_ids)
        self._write: Any = sdk.GroupSyncWrite(self.port, self.packet, GOAL.address, GOAL.size)
        self._read: Any = sdk.GroupSyncRead(self.port, self.packet, PRESENT.address, PRESENT.size)
        for sid in self.read_ids:
            self._read.addParam(sid)
        self.failures = 0

    def cycle(self, goal_tick: int | Mapping[int, int]) -> dict[int, int]:
        """One cycle: every servo's goal at ``goal_tick`` (or ``goal_tick[id]``); the positions read (empty
        on a failed read)."""
        for sid in self.write_ids:
            goal = goal_tick if isinstance(goal_tick, int) else goal_tick[sid]
            data = [sdk.DXL_LOBYTE(sdk.DXL_LOWORD(goal)), sdk.DXL_HIBYTE(sdk.DXL_LOWORD(goal)),
                    sdk.DXL_LOBYTE(sdk.DXL_HIWORD(goal)), sdk.DXL_HIBYTE(sdk.DXL_HIWORD(goal))]  # fmt: skip
            self._write.addParam(sid, data)
        comm = self._write.txPacket()
        self._write.clearParam()
        if comm != sdk.COMM_SUCCESS:
            raise BusError(f"stock SDK loop: sync write failed: {self.packet.getTxRxResult(comm)}")
        try:
            comm = self._read.fastSyncRead() if self.fast else self._read.txRxPacket()
        except IndexError:  # the SDK's fastSyncRead indexing the empty data of a late packet of another id
            self.port.is_using = False
            comm = sdk.COMM_RX_CORRUPT
        if comm != sdk.COMM_SUCCESS:
            self.failures += 1
            return {}
        out = {}
        for sid in self.read_ids:
            if self._read.isAvailable(sid, PRESENT.address, PRESENT.size):
                out[sid] = self._read.getData(sid, PRESENT.address, PRESENT.size)
        return out
