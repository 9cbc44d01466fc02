"""`StockSdkLoop`: the plain stock-SDK loop the benches compare with really drives the emulated chain."""

from __future__ import annotations

import pytest
from servoface.hardware.bus import open_bus
from servoface.hardware.emulator import ServoChain
from servoface.hardware.errors import HardwareConfigError
from servoface.hardware.registers import Register
from servoface.hardware.stock_loop import StockSdkLoop


@pytest.mark.parametrize("fast", [False, True])
def test_the_stock_loop_writes_goals_and_reads_positions(fast: bool) -> None:
    chain = ServoChain.create(ids=range(1, 5), wire_time=False)
    bus = open_bus("emulator", chain=chain)
    try:
        for sid in chain.ids:
            bus.write(sid, Register.TORQUE_ENABLE, 1)
        loop = StockSdkLoop(bus, [1, 2, 3], [1, 2, 3, 4], fast=fast)
        got = loop.cycle({1: 2000, 2: 2100, 3: 2200})
        assert set(got) == {1, 2, 3, 4} and loop.failures == 0
        assert [g[1:] for g in chain.goal_writes()[-3:]] == [(1, 2000), (2, 2100), (3, 2200)]
        loop.cycle(2048)
        assert {g[2] for g in chain.goal_writes()[-3:]} == {2048}
    finally:
        bus.close()
        chain.close()


def test_the_stock_loop_needs_an_sdk_port() -> None:
    with pytest.raises(HardwareConfigError, match="DynamixelBus"):
        StockSdkLoop(object(), [1])  # type: ignore[arg-type]
