"""Opt-in tests on real servos: SERVOFACE_PORT=/dev/ttyUSB0 SERVOFACE_IDS=1-4 pytest -m hardware.

They use the shared fixtures (`dxl_bus`, `driver`), which open the real port for `hardware`-marked tests and
skip with the reason when SERVOFACE_PORT is not set. Moves stay inside 1024..3072 and are small.
"""

from __future__ import annotations

import pytest
from servoface.hardware.driver import Driver
from servoface.hardware.scan import scan

pytestmark = pytest.mark.hardware


def test_every_configured_servo_answers(dxl_bus, servo_specs) -> None:  # type: ignore[no-untyped-def]
    found = {r.servo_id for r in scan(dxl_bus, [s.servo_id for s in servo_specs])}
    assert found == {s.servo_id for s in servo_specs}


def test_small_move_and_back(driver: Driver) -> None:
    driver.torque_on()
    start = driver.read_state().positions_tick()
    goals = {sid: min(3072, max(1024, tick + 40)) for sid, tick in start.items()}
    snap = driver.read_state()
    for _ in range(100):
        snap = driver.cycle(goals)
    assert all(abs(snap[sid].position_tick - goal) <= 10 for sid, goal in goals.items())  # type: ignore[operator]
    for _ in range(100):
        driver.cycle(start)
