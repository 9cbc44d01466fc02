"""The wire-time arithmetic against the reference sheet's table (§8)."""

from __future__ import annotations

import pytest
from servoface.hardware.wire import cycle_budget, fast_sync_read_reply_bytes, status_bytes, sync_write_bytes


@pytest.mark.parametrize(
    ("n", "baud", "sw_sr_ms", "sw_fast_ms"),
    [
        (1, 57_600, 8.51, 8.68),
        (6, 1_000_000, 1.54, 1.20),
        (12, 4_000_000, 0.70, 0.51),
        (20, 1_000_000, 4.48, 3.16),
        (30, 3_000_000, 2.19, 1.52),
    ],
)
def test_cycle_times_match_the_reference_table(n: int, baud: int, sw_sr_ms: float, sw_fast_ms: float) -> None:
    assert cycle_budget(n, baud).wire_time_s * 1e3 == pytest.approx(sw_sr_ms, abs=0.01)
    assert cycle_budget(n, baud, fast=True).wire_time_s * 1e3 == pytest.approx(sw_fast_ms, abs=0.01)


def test_return_delay_is_paid_per_status_packet() -> None:
    plain = cycle_budget(20, 1_000_000)
    slow = cycle_budget(20, 1_000_000, return_delay_us=500)
    assert slow.wire_time_s - plain.wire_time_s == pytest.approx(20 * 500e-6)
    fast = cycle_budget(20, 1_000_000, fast=True, return_delay_us=500)
    assert fast.return_delay_s == pytest.approx(500e-6)
    assert cycle_budget(20, 1_000_000, fast=True, return_delay_us=500, fast_delay_per_block=True).return_delay_s == (
        pytest.approx(20 * 500e-6)
    )


def test_packet_sizes() -> None:
    assert sync_write_bytes(2, 4) == 24  # e-manual sync write example: FF FF FD 00 FE 11 00 ... = 7 + 0x11
    assert status_bytes(4) == 15
    assert fast_sync_read_reply_bytes(3, 4) == 7 + 25  # e-manual: 3 devices x 4 bytes -> LEN 25


def test_bad_arguments() -> None:
    with pytest.raises(ValueError):
        cycle_budget(0, 1_000_000)
    with pytest.raises(ValueError):
        cycle_budget(3, 1_000_000, return_delay_us=-1)
