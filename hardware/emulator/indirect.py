"""Indirect addressing: Indirect Data bytes stand for the bytes whose addresses their Indirect Address
registers hold, so a host can gather scattered registers into one contiguous read or write."""

from __future__ import annotations

from servoface.hardware.emulator.control_table import ControlTable


class IndirectMap:
    """The indirect blocks of one control table: (first data address, first address register, count)."""

    def __init__(self, table: ControlTable) -> None:
        blocks: list[tuple[int, int, int]] = []
        for reg in table:
            if not reg.name.startswith("Indirect Data "):
                continue
            n = int(reg.name.rsplit(" ", 1)[1])
            address_reg = table.get(f"Indirect Address {n}")
            if blocks:
                data0, addr0, count = blocks[-1]
                if data0 + count == reg.address and addr0 + 2 * count == address_reg.address:
                    blocks[-1] = (data0, addr0, count + 1)
                    continue
            blocks.append((reg.address, address_reg.address, 1))
        self.blocks = blocks
        self.data_lo = min((d for d, _, _ in blocks), default=1 << 30)
        self.data_hi = max((d + n for d, _, n in blocks), default=0)

    def target(self, mem: bytearray, address: int) -> int:
        """The real address behind ``address`` (itself unless it is an Indirect Data byte)."""
        for data0, addr0, count in self.blocks:
            if data0 <= address < data0 + count:
                slot = addr0 + 2 * (address - data0)
                return mem[slot] | mem[slot + 1] << 8
        return address

    def targets(self, mem: bytearray, address: int, length: int) -> list[int]:
        return [self.target(mem, a) for a in range(address, address + length)]

    def runs(self, mem: bytearray, address: int, data: bytes) -> list[tuple[int, bytes]]:
        """Split a write into contiguous runs of real addresses (each run is checked like a plain write)."""
        runs: list[tuple[int, bytearray]] = []
        for i, byte in enumerate(data):
            real = self.target(mem, address + i)
            if runs and runs[-1][0] + len(runs[-1][1]) == real:
                runs[-1][1].append(byte)
            else:
                runs.append((real, bytearray((byte,))))
        return [(start, bytes(chunk)) for start, chunk in runs]
