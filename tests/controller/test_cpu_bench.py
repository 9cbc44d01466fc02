"""`bench pipeline`'s CPU budget figure: the head as a user opens it (``fast_sync_read="auto"``) over a pty, the
emulator in another process, reads its positions with Fast Sync Read (every emulated servo answers the
start-up probe); forced plain Sync Read is reported as such."""

from __future__ import annotations

from servoface.controller.benchmarks.cpu import _cpu_figure


def test_default_figure_uses_the_probed_fast_read() -> None:
    fig = _cpu_figure(True, "auto", (30.0, 200.0))
    assert "Fast Sync Read" in fig.name
    assert "x6.7" in fig.note  # the cache refill factor is printed beside the figure
    assert fig.value > 0 and fig.limit == 10.0 and fig.better == "lower"


def test_forced_plain_figure_says_so() -> None:
    fig = _cpu_figure(True, False, (30.0, 60.0))
    assert "plain Sync Read" in fig.name
    assert "forced" in fig.note
