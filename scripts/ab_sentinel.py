"""A/B: Driver with the position sentinel vs the same Driver with it off (direct reads + status floor)."""

import statistics
from servoface.controller.benchmarks.bus import _chain_and_bus, STOCK, SETTLE, N_SERVOS
from servoface.controller.benchmarks.interleave import interleaved
from servoface.hardware.bus import open_bus
from servoface.hardware.driver import Driver
from servoface.hardware.servo_config import ServoSpec
from servoface.hardware.stock_loop import StockSdkLoop

for fast in (False, True):
    baud = 1_000_000
    chain, setup = _chain_and_bus(baud, wire_time=True)
    setup.close()
    ids = chain.ids
    buses = [open_bus("emulator", chain=chain, baud=baud) for _ in range(3)]
    stock = StockSdkLoop(buses[0], ids, fast=fast)
    drivers = []
    for b, sentinel in zip(buses[1:], (True, False)):  # B: direct reads of 132, the usual status floor
        d = Driver(
            b,
            [ServoSpec(s, "XL330-M288", return_delay_us=0) for s in ids],
            fast_sync_read=fast,
            position_sentinel=sentinel,
        )
        d.configure()
        d.torque_on()
        drivers.append(d)
    steps = {
        STOCK: lambda n: stock.cycle(2048 + (n & 1)),
        "driver sentinel": lambda n: drivers[0].cycle({s: 2048 + (n & 1) for s in ids}),
        "driver direct": lambda n: drivers[1].cycle({s: 2048 + (n & 1) for s in ids}),
    }
    stats = interleaved(steps, STOCK, 8, 2.0, settle=SETTLE)
    a, b = stats["driver sentinel"], stats["driver direct"]
    pair = statistics.median(x / y for x, y in zip(a.rates, b.rates))
    print(
        f"fast={fast}: sentinel x{statistics.median(a.ratios):.4f} stock, direct x{statistics.median(b.ratios):.4f} stock;"
        f" sentinel/direct per round median x{pair:.4f}; reads {drivers[0].telemetry_reads} vs {drivers[1].telemetry_reads}"
    )
    for x in buses:
        x.close()
    chain.close()
