"""Wire-time arithmetic of a Protocol 2.0 control cycle (pure functions; 8N1 = 10 bits per byte).

Byte stuffing is ignored (position values near the centre never form ``FF FF FD``).
"""

from __future__ import annotations

from dataclasses import dataclass

BITS_PER_BYTE = 10  # start + 8 data + stop


def sync_write_bytes(n_servos: int, data_len: int) -> int:
    """Sync Write: header(4) id len(2) inst addr(2) len(2) + n * (id + data) + crc(2)."""
    return 14 + n_servos * (data_len + 1)


def sync_read_instruction_bytes(n_servos: int) -> int:
    return 14 + n_servos


def status_bytes(data_len: int) -> int:
    """One status packet: header(4) id len(2) inst err + data + crc(2)."""
    return 11 + data_len


def fast_sync_read_reply_bytes(n_servos: int, data_len: int) -> int:
    """One combined Fast Sync Read reply: header(4) id len(2) inst + n * (err id data crc(2)) ... see §5."""
    return 8 + n_servos * (data_len + 4)


@dataclass(frozen=True)
class CycleBudget:
    """Bytes and seconds of one sync-write + sync-read cycle on the wire."""

    n_servos: int
    baud: int
    bytes_total: int
    return_delay_s: float
    wire_time_s: float

    @property
    def limit_hz(self) -> float:
        return 1.0 / self.wire_time_s


def cycle_budget(
    n_servos: int,
    baud: int,
    *,
    write_len: int = 4,
    read_len: int = 4,
    return_delay_us: float = 0.0,
    fast: bool = False,
    fast_delay_per_block: bool = False,
) -> CycleBudget:
    """Wire time of Sync Write (``write_len`` bytes each) + Sync Read / Fast Sync Read (``read_len`` each).

    Return Delay Time is paid once per status packet: n times for a Sync Read, once for a Fast Sync Read
    (or n times with ``fast_delay_per_block`` — the e-manual does not say which).
    """
    if n_servos < 1 or baud <= 0:
        raise ValueError(f"cycle_budget: need n_servos >= 1 and baud > 0, got {n_servos}, {baud}")
    if return_delay_us < 0:
        raise ValueError(f"cycle_budget: return_delay_us must be >= 0, got {return_delay_us}")
    total = sync_write_bytes(n_servos, write_len) + sync_read_instruction_bytes(n_servos)
    if fast:
        total += fast_sync_read_reply_bytes(n_servos, read_len)
        delays = n_servos if fast_delay_per_block else 1
    else:
        total += n_servos * status_bytes(read_len)
        delays = n_servos
    delay_s = delays * return_delay_us * 1e-6
    return CycleBudget(n_servos, baud, total, delay_s, total * BITS_PER_BYTE / baud + delay_s)
