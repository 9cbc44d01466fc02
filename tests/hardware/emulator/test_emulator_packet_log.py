"""The emulator's packet log stays bounded however long a run goes (a ring with absolute indexes), and a
reader that remembered ``len(log)`` still gets exactly the packets that came after."""

from __future__ import annotations

import tracemalloc

import pytest
from servoface.hardware.emulator import EmulatorError, ServoChain
from servoface.hardware.emulator.chain import RUN_LOG_LIMIT
from servoface.hardware.emulator.packet import build_instruction
from servoface.hardware.emulator.packet_log import LogEntry, PacketLog


def test_a_long_run_keeps_at_most_the_limit_and_indexes_stay_absolute() -> None:
    chain = ServoChain.create(ids=[1, 2], wire_time=False, log_limit=1000)
    ser = chain.open_serial()
    ping = build_instruction(1, 0x01)
    for k in range(10_000):
        if k == 9_990:
            mark = len(chain.log)
        ser.write(ping)
        ser.read(64)
    log = chain.log
    assert len(log) == 10_000 and len(log.kept()) <= 1000  # counted all, kept the newest
    assert log.first_index == 10_000 - len(log.kept())
    assert len(log[mark:]) == 10 and all(e.instruction == 0x01 for e in log[mark:])
    assert log[-1] is log[len(log) - 1]
    with pytest.raises(IndexError):
        log[0]  # dropped long ago
    del log[:]
    assert len(log) == 10_000 and log.kept() == [] and log[mark:] == []
    ser.write(ping)
    assert len(log) == 10_001 and len(log[10_000:]) == 1
    chain.close()


def test_memory_stays_bounded_for_a_run_of_hours() -> None:
    """Five hours' worth of 30-servo Sync Writes at 50 Hz (2.5 packets a frame) through a run's log: the log
    never holds more than RUN_LOG_LIMIT entries, and the memory it takes stops growing."""
    params = bytes(4 + 30 * 5)  # a Sync Write of 30 goals
    log = PacketLog(RUN_LOG_LIMIT)
    tracemalloc.start()
    try:
        peaks = []
        for hour in range(5):
            for k in range(RUN_LOG_LIMIT // 2):  # (a tenth of an hour's packets, each hour: the shape is the same)
                log.append(LogEntry(hour * 3600.0 + k * 0.008, 254, 0x83, params))
            peaks.append(tracemalloc.get_traced_memory()[0])
            assert len(log.kept()) <= RUN_LOG_LIMIT
    finally:
        tracemalloc.stop()
    assert max(peaks[2:]) <= 1.2 * peaks[1], peaks  # flat once the ring is full


def test_a_run_chain_is_made_with_the_run_limit() -> None:
    from servoface.controller.service import open_head

    opened = open_head("human", emulate=True, wire_time=False)
    try:
        assert opened.chain.log.limit == RUN_LOG_LIMIT
    finally:
        opened.driver.close(torque_off=True)
        opened.close()


def test_a_limit_below_two_is_refused() -> None:
    with pytest.raises(EmulatorError, match="log_limit"):
        ServoChain.create(ids=[1], log_limit=1)
