"""The position sentinel (hardware/sentinel.py), from the emulator's side of the wire: the Indirect Address
map written and verified at configure, the per-cycle read of 4 bytes at Indirect Data, a servo reset
mid-run seen the next cycle and brought back with its map, direct reads (and an event) where the map does
not verify, the Fast Sync Read path and the calm cycle."""

from __future__ import annotations

import time

import pytest
from servoface.hardware.bus import open_bus
from servoface.hardware.driver import Driver
from servoface.hardware.emulator import ServoChain
from servoface.hardware.registers import Register
from servoface.hardware.sentinel import MAP_VALUE, SLOT_TARGETS, split
from servoface.hardware.servo_config import ServoSpec
from servoface.hardware.snapshot import FaultKind

from tests.hardware.driver_helpers import assert_goals_within_limits, events_of, make_driver, run

SYNC_READ, FAST_SYNC_READ = 0x82, 0x8A
GOALS = {1: 2600, 2: 1700, 3: 1200, 4: 2050}


def _map(chain: ServoChain, sid: int) -> list[int]:
    return [chain.servo(sid).read_register(f"Indirect Address {n}") for n in range(1, len(SLOT_TARGETS) + 1)]


def _position_reads(chain: ServoChain, after: int = 0) -> list[tuple[int, bytes]]:
    """(instruction, params) of every Sync / Fast Sync Read of a 4-byte block."""
    return [
        (e.instruction, bytes(e.params))
        for e in chain.log.kept()[after:]
        if e.instruction in (SYNC_READ, FAST_SYNC_READ) and e.params[2:4] == bytes((4, 0))
    ]


@pytest.mark.parametrize("fast", [False, True])
def test_the_map_is_written_and_verified_and_each_cycle_reads_4_bytes_of_indirect_data(fast: bool) -> None:
    chain, driver = make_driver(fast_sync_read=fast)
    for sid in (1, 2, 3, 4):
        assert _map(chain, sid) == list(SLOT_TARGETS)  # position 132..134, Status Return Level 68, telemetry
    assert driver.sentinel_info.startswith("positions read through Indirect Data at 208")  # XL330 firmware 52
    n = len(chain.log.kept())
    snaps = run(chain, driver, GOALS, 1.0)
    assert snaps[-1].positions_tick() == GOALS and not any(s.stale or s.missing for s in snaps[-1])
    reads = _position_reads(chain, n)
    inst = FAST_SYNC_READ if fast else SYNC_READ
    assert set(reads) == {(inst, bytes((208, 0, 4, 0, 1, 2, 3, 4)))}
    at_208 = [e for e in chain.log.kept()[n:] if e.instruction == inst and e.params[:2] == bytes((208, 0))]
    assert len(at_208) == len(snaps)  # every cycle; the others are a due motion / thermal group riding along:
    assert {e.params[2] for e in at_208} == {4, 11, 14} and len(reads) >= 0.8 * len(snaps)
    assert not [e for e in chain.log.kept()[n:] if e.instruction in (SYNC_READ, FAST_SYNC_READ) and e.params[0] == 132]
    assert not events_of(driver, FaultKind.SENTINEL)


def test_a_base_control_table_verifies_at_224() -> None:
    chain = ServoChain.create(ids=[1, 2], model="XL430-W250", wire_time=False, clock="manual")
    specs = [ServoSpec(i, "XL430-W250", min_position_tick=1024, max_position_tick=3072) for i in (1, 2)]
    driver = Driver(open_bus("emulator", chain=chain), specs, clock=chain.clock)
    reports = driver.configure()
    assert {sid: r.sentinel.base for sid, r in reports.items() if r.sentinel} == {1: 224, 2: 224}
    driver.torque_on()
    n = len(chain.log.kept())
    snaps = run(chain, driver, {1: 2500, 2: 1500}, 1.0)
    assert snaps[-1].positions_tick() == {1: 2500, 2: 1500}
    assert {p[:4] for _, p in _position_reads(chain, n)} == {bytes((224, 0, 4, 0))}


def test_negative_and_multi_turn_positions_survive_24_bits() -> None:
    assert split(0x02_FFFFFF) == (-1, 2)
    assert split(0x01_000000 | (4096 * 255)) == (4096 * 255, 1)
    assert split(0x02_000000 | ((-4096 * 256) & 0xFFFFFF)) == (-4096 * 256, 2)


@pytest.mark.parametrize("how", ["reboot", "power"])
@pytest.mark.parametrize("fast", [False, True])
def test_a_reset_servo_is_seen_the_next_cycle_and_brought_back_with_its_map(how: str, fast: bool) -> None:
    chain, driver = make_driver(fast_sync_read=fast, profile_velocity=200)
    run(chain, driver, GOALS, 0.3)
    if how == "reboot":
        chain.servo(2).reboot(0.0)  # a brown-out: RAM (the map included) back to defaults, torque off
    else:
        chain.faults.inject(2, "disconnect", duration_s=0.001)  # a power cycle shorter than a cycle
        chain.advance(0.002)
    assert _map(chain, 2) != list(SLOT_TARGETS) and not chain.servo(2).torque_on
    snap = driver.cycle(GOALS)
    seen = [e for e in snap.events if e.kind == FaultKind.RECONNECTED and e.servo_id == 2]
    assert seen and "position sentinel read 0" in seen[0].reaction
    assert snap[2].position_tick != 0  # the reset servo's reply (all zero bytes) was not taken as a position
    assert _map(chain, 2) == list(SLOT_TARGETS)  # re-configured in the same cycle: map rewritten
    assert chain.servo(2).torque_on and chain.servo(2).read_register("PROFILE_VELOCITY") == 200
    snaps = run(chain, driver, GOALS, 1.0)
    assert snaps[-1].positions_tick() == GOALS and snaps[-1][2].torque_on and not snaps[-1][2].stale
    assert len(events_of(driver, FaultKind.RECONNECTED, 2)) == 1  # once, not again by the status read
    assert_goals_within_limits(chain, driver)


def test_reset_detection_does_not_wait_for_the_status_group() -> None:
    """No chain time passes between cycles (the status group is never due again), yet a reset servo is
    seen in the first cycle after it, by its position reply alone."""
    chain, driver = make_driver()
    for _ in range(3):
        driver.cycle(GOALS)  # the first reads of every group (due at once)
    reads0 = driver.telemetry_reads["status"]
    chain.servo(3).reboot(0.0)
    snap = driver.cycle(GOALS)
    assert [e for e in snap.events if e.kind == FaultKind.RECONNECTED and e.servo_id == 3]
    assert driver.telemetry_reads["status"] == reads0 and chain.servo(3).torque_on


def test_back_to_back_the_status_group_has_no_floor_rate_with_the_sentinel_only() -> None:
    chain, driver = make_driver()
    driver.cycle(GOALS)
    status = driver._groups[0]
    assert status.name == "status"
    now = chain.time_s + 100.0
    for g in driver._groups:  # every group far past its floor; the bus never idle (a back-to-back caller)
        g.due_s, g.cost_s = now - 10.0 * (3.0 if g is status else 1.0), 1.0
    driver._idle_s = 0.0
    assert driver._due_group(now) is not status  # the motion / thermal floor still holds
    for g in driver._groups[1:]:
        g.due_s = now + 1.0
    assert driver._due_group(now) is None
    status.due_s = float("-inf")  # an Alert bit or a reaction asks: read at once
    assert driver._due_group(now) is status
    status.due_s = now - 30.0
    driver._idle_s = 2.0  # the bus idle long enough: nominal rate
    assert driver._due_group(now) is status
    driver._idle_s = 0.0
    driver._sentinel = None  # without the sentinel the floor rate is back
    assert driver._due_group(now) is status


def test_a_torque_off_servo_reset_is_reconfigured_with_torque_left_off() -> None:
    chain, driver = make_driver(profile_velocity=150)
    driver.torque_off([4])
    run(chain, driver, GOALS, 0.2)
    chain.servo(4).reboot(0.0)
    snap = driver.cycle(GOALS)
    assert [e for e in snap.events if e.servo_id == 4 and "out of service" in e.reaction]
    assert _map(chain, 4) == list(SLOT_TARGETS) and not chain.servo(4).torque_on
    assert chain.servo(4).read_register("PROFILE_VELOCITY") == 150
    snaps = run(chain, driver, GOALS, 0.2)
    assert not snaps[-1][4].stale and not snaps[-1][4].torque_on


def test_data_elsewhere_keeps_direct_reads_with_an_event() -> None:
    """Firmware whose Indirect Data sits at neither 224 nor 208: the read-back does not verify, so the chain
    reads Present Position directly, and an event says why (never a guess)."""
    chain = ServoChain.create(ids=[1, 2, 3], model="XL330-M288", wire_time=False, clock="manual")
    indirect = chain.servo(2)._indirect
    indirect.blocks = [(240, 168, 20)]  # the data of Indirect Address 1..20 at 240.. on this servo
    specs = [ServoSpec(i, "XL330-M288", min_position_tick=1024, max_position_tick=3072) for i in (1, 2, 3)]
    driver = Driver(open_bus("emulator", chain=chain), specs, clock=chain.clock)
    driver.configure()
    driver.torque_on()
    ev = events_of(driver, FaultKind.SENTINEL)
    assert len(ev) == 1 and ev[0].servo_id is None and "servo 2" in ev[0].reaction
    assert "directly" in driver.sentinel_info
    n = len(chain.log.kept())
    snaps = run(chain, driver, {1: 2000, 2: 2500, 3: 1500}, 1.0)
    assert snaps[-1].positions_tick() == {1: 2000, 2: 2500, 3: 1500}
    assert {p[:4] for _, p in _position_reads(chain, n)} == {bytes((132, 0, 4, 0))}
    chain.servo(1).reboot(0.0)  # without the sentinel a reset is still seen (the status group)
    run(chain, driver, {1: 2000, 2: 2500, 3: 1500}, 0.5)
    assert events_of(driver, FaultKind.RECONNECTED, 1) and chain.servo(1).torque_on


def test_mixed_tables_and_velocity_mode_keep_direct_reads() -> None:
    chain = ServoChain.create(ids=[(1, "XL330-M288"), (2, "XL430-W250")], wire_time=False, clock="manual")
    specs = [ServoSpec(1, "XL330-M288"), ServoSpec(2, "XL430-W250")]
    driver = Driver(open_bus("emulator", chain=chain), specs, clock=chain.clock)
    driver.configure()
    assert "different servos" in driver.sentinel_info and events_of(driver, FaultKind.SENTINEL)
    chain = ServoChain.create(ids=[1], model="XL330-M288", wire_time=False, clock="manual")
    driver = Driver(
        open_bus("emulator", chain=chain), [ServoSpec(1, "XL330-M288", operating_mode=1)], clock=chain.clock
    )
    driver.configure()
    assert "VELOCITY mode" in driver.sentinel_info


def test_folded_telemetry_through_the_map_reads_the_same_values() -> None:
    chain, driver = make_driver()
    chain.set_input_voltage(None, 4.8)
    snaps = run(chain, driver, GOALS, 1.0)
    assert driver.telemetry_reads["thermal"] >= 2 and driver.telemetry_reads["motion"] >= 10
    last = snaps[-1][1]
    assert last.temperature_c == chain.servo(1).read_register("Present Temperature")
    assert last.voltage_v == pytest.approx(4.8)
    assert last.current_ma is not None


def test_over_a_pty_a_reset_is_seen_and_repaired() -> None:
    """The real SDK over a pseudo-terminal (the chain served from its own thread, real time)."""
    chain = ServoChain.create(ids=[1, 2, 3], model="XL330-M288", baud=1_000_000)
    try:
        bus = open_bus("dynamixel", port=chain.serve_pty(), baud=1_000_000, warn_latency=False)
        specs = [ServoSpec(i, "XL330-M288", min_position_tick=1024, max_position_tick=3072) for i in (1, 2, 3)]
        driver = Driver(bus, specs)
        driver.configure()
        driver.torque_on()
        goals = {1: 2000, 2: 2100, 3: 1900}
        for _ in range(20):
            driver.cycle(goals)
        chain.servo(2).reboot(0.0)
        snap = driver.cycle(goals)
        assert [e for e in snap.events if e.servo_id == 2 and "position sentinel" in e.reaction]
        assert _map(chain, 2) == list(SLOT_TARGETS) and chain.servo(2).torque_on
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:
            snap = driver.cycle(goals)
            if snap.positions_tick() == goals:
                break
        assert snap.positions_tick() == goals
        driver.close(torque_off=True)
    finally:
        chain.close()
    assert Register.INDIRECT_208_SENTINEL.address == 208


@pytest.mark.parametrize("fast", [False, True])
def test_another_process_chain_reset_by_a_reboot_on_the_wire_is_seen_and_repaired(fast: bool) -> None:
    """`servoface emulate` in another process over a pty: a Reboot sent behind the driver's back (as a brown-
    out would reset the servo) is seen in the next cycle by the position reply alone, and the map is back."""
    import subprocess
    import sys

    proc = subprocess.Popen(
        [sys.executable, "-m", "servoface.controller.cli", "emulate", "--ids", "1-4", "--model", "XL330-M288",
         "--baud", "1000000"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )  # fmt: skip
    try:
        assert proc.stdout is not None
        path = proc.stdout.readline().strip()
        assert path.startswith("/"), path
        bus = open_bus("dynamixel", port=path, baud=1_000_000, warn_latency=False)
        specs = [ServoSpec(i, "XL330-M288", min_position_tick=1024, max_position_tick=3072) for i in (1, 2, 3, 4)]
        driver = Driver(bus, specs, fast_sync_read=fast)
        driver.configure()
        driver.torque_on()
        assert driver.sentinel_info.startswith("positions read through Indirect Data at 208")
        goals = {1: 2000, 2: 2100, 3: 1900, 4: 2050}
        for _ in range(10):
            driver.cycle(goals)
        bus.reboot(3)  # not the driver's: its records still say servo 3 is in service
        time.sleep(0.05)
        snap = driver.cycle(goals)
        news = [e for e in driver.events if e.servo_id == 3 and e.kind == FaultKind.RECONNECTED]
        assert len(news) == 1 and "position sentinel read 0" in news[0].reaction  # not the status read's
        assert news[0] in snap.events  # the first cycle after the reset
        assert bus.read(3, Register.INDIRECT_ADDRESS_1_14) == MAP_VALUE
        assert bus.read(3, Register.TORQUE_ENABLE) == 1
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:
            snap = driver.cycle(goals)
            if snap.positions_tick() == goals:
                break
        assert snap.positions_tick() == goals and not snap[3].stale
        driver.close(torque_off=True)
    finally:
        proc.terminate()
        try:
            proc.communicate(timeout=5.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()
