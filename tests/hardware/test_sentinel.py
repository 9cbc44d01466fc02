"""The position sentinel (hardware/sentinel.py), from the emulator's side of the wire (the stock SDK talks to
it): the Indirect Address map written and verified at configure (slots 1..4 on a base control table, 17..20
on XL330 firmware >= 52, so every servo's data is at 224), one Sync Read of 3 bytes at 224 per cycle on the
built-in heads' mixed chain (4 where a servo's positions need more than 16 bits), a servo reset mid-run
seen the next cycle and brought back, direct reads (and an event) where the map does not verify or by
request, the status group's low floor rate, folded cycles."""

from __future__ import annotations

import time
import tomllib
from pathlib import Path

import pytest
from servoface.hardware.bus import open_bus
from servoface.hardware.driver import Driver
from servoface.hardware.emulator import ServoChain
from servoface.hardware.fault_policy import FaultPolicy
from servoface.hardware.registers import Register
from servoface.hardware.sentinel import MAP_VALUE, SENTINEL, SENTINEL_SHORT, SLOT_TARGETS, fits_short, split
from servoface.hardware.servo_config import ServoSpec
from servoface.hardware.snapshot import FaultKind

from tests.hardware.driver_helpers import assert_goals_within_limits, events_of, make_driver, run

SYNC_READ, FAST_SYNC_READ = 0x82, 0x8A
WRITES = (0x03, 0x04, 0x83, 0x93)  # Write, Reg Write, Sync Write, Bulk Write
GOALS = {1: 2600, 2: 1700, 3: 1200, 4: 2050}
HEADS = Path(__file__).resolve().parents[2] / "sim" / "heads"
XL330, XL430 = 1, 18  # on the human head


def _head_models(name: str) -> list[tuple[int, str]]:
    """(id, model) of every servo in a built-in head's head.toml."""
    found: list[tuple[int, str]] = []

    def walk(node: object) -> None:
        if isinstance(node, dict):
            servo = node.get("servo")
            if isinstance(servo, dict):
                found.append((int(servo["id"]), str(servo["model"])))
            for value in node.values():
                walk(value)
        elif isinstance(node, list):
            for value in node:
                walk(value)

    walk(tomllib.loads((HEADS / name / "head.toml").read_text()))
    return sorted(found)


def _human(fast: bool | str = "auto", **kw: object) -> tuple[ServoChain, Driver, dict[int, int]]:
    """The human head's chain (its models, mixed XL330 / XL430 / XM430), configured, torque on."""
    models = _head_models("human")
    chain = ServoChain.create(ids=models, baud=1_000_000, wire_time=False, clock="manual")
    specs = [ServoSpec(sid, model, min_position_tick=1024, max_position_tick=3072) for sid, model in models]
    driver = Driver(open_bus("emulator", chain=chain), specs, clock=chain.clock, fast_sync_read=fast, **kw)  # type: ignore[arg-type]
    driver.configure()
    driver.torque_on()
    return chain, driver, {sid: 2048 + (40 if sid % 2 else -40) for sid, _ in models}


def _slots(chain: ServoChain, sid: int, first: int, n: int = 4) -> list[int]:
    return [chain.servo(sid).read_register(f"Indirect Address {k}") for k in range(first, first + n)]


def _n_slots(chain: ServoChain, sid: int) -> int:
    return sum(1 for k in range(1, 64) if f"Indirect Address {k}" in chain.servo(sid).table)


def _reads(chain: ServoChain, after: int = 0) -> list[tuple[int, int, int]]:
    """(address, length, number of ids) of every Sync / Fast Sync Read after log index ``after``."""
    return [
        (e.params[0] | e.params[1] << 8, e.params[2] | e.params[3] << 8, len(e.params) - 4)
        for e in chain.log.kept()[after:]
        if e.instruction in (SYNC_READ, FAST_SYNC_READ)
    ]


def _writes_at(chain: ServoChain, lo: int, hi: int, after: int = 0) -> list[tuple[int, int, int]]:
    """(servo id, start address, length) of every write instruction that touches ``lo..hi-1``."""
    out = []
    for e in chain.log.kept()[after:]:
        p = e.params
        if e.instruction not in WRITES or len(p) < 3:
            continue
        start = p[0] | p[1] << 8
        if e.instruction in (0x03, 0x04):
            length = len(p) - 2
        elif e.instruction == 0x83:
            length = p[2] | p[3] << 8
        else:
            out.append((e.id, -1, -1))  # a Bulk Write: the driver never sends one
            continue
        if start < hi and start + length > lo:
            out.append((e.id, start, length))
    return out


def test_the_built_in_heads_mix_both_tables() -> None:
    for name in ("human", "dog"):
        models = {m for _, m in _head_models(name)}
        assert {"XL330-M288", "XL430-W250", "XM430-W350"} <= models, name
    assert dict(_head_models("human"))[XL330] == "XL330-M288" and dict(_head_models("human"))[XL430] == "XL430-W250"


@pytest.mark.parametrize("fast", [False, True])
def test_the_human_heads_mixed_chain_reads_one_sync_read_of_3_bytes_at_224_per_cycle(fast: bool) -> None:
    chain, driver, goals = _human(fast)
    models = dict(_head_models("human"))
    assert driver.sentinel_info.startswith("positions read through Indirect Data at 224"), driver.sentinel_info
    assert not events_of(driver, FaultKind.SENTINEL)
    for sid, model in models.items():  # XL330 firmware 52: 20 slots, data 208..227; the others 28, from 224
        first = 17 if model == "XL330-M288" else 1
        assert _n_slots(chain, sid) >= 20 and _slots(chain, sid, first) == list(SLOT_TARGETS), (sid, model)
    n = len(chain.log.kept())
    snaps = run(chain, driver, goals, 1.0)
    assert snaps[-1].positions_tick() == goals and not any(s.stale or s.missing for s in snaps[-1])
    reads = _reads(chain, n)
    inst = FAST_SYNC_READ if fast else SYNC_READ
    assert all(e.instruction == inst for e in chain.log.kept()[n:] if e.instruction in (SYNC_READ, FAST_SYNC_READ))
    per_cycle = [r for r in reads if r[0] in (224, 122) or (r[0] == 132 and r[1] == 15)]  # position reads
    assert len(per_cycle) == len(snaps)  # one per cycle, every servo in it
    assert all(k == len(models) for _, _, k in per_cycle)
    plain = [r for r in per_cycle if r[0] == 224]
    assert set(plain) == {(224, 3, len(models))} and len(plain) >= 0.8 * len(snaps)
    assert "3 bytes" in driver.sentinel_info, driver.sentinel_info
    assert (132, 4, len(models)) not in reads  # never a direct 4-byte read of Present Position


def test_only_slots_1_to_4_or_17_to_20_are_written() -> None:
    models = _head_models("human")
    fresh = ServoChain.create(ids=models, wire_time=False, clock="manual")
    chain, driver, goals = _human()
    run(chain, driver, goals, 0.3)
    for sid, model in models:
        ours = range(17, 21) if model == "XL330-M288" else range(1, 5)
        for k in range(1, _n_slots(chain, sid) + 1):
            if k not in ours:
                assert _slots(chain, sid, k, 1) == _slots(fresh, sid, k, 1), (sid, model, k)
    written = _writes_at(chain, 168, 256)
    for sid, model in models:  # a base table: slots 1..4 once; XL330: 1..4 tried (data at 208), written back,
        # then 17..20
        want = [(sid, 168, 8), (sid, 168, 8), (sid, 200, 8)] if model == "XL330-M288" else [(sid, 168, 8)]
        assert [w for w in written if w[0] == sid] == want, (sid, model)


def test_a_reconfigure_with_no_reset_since_writes_no_slot() -> None:
    """Slots that still hold the map are verified first, unwritten: an XL330 re-configured with no reset since
    (a recovery, a second `configure`) keeps its slots 1..4 as they were."""
    models = _head_models("human")
    fresh = ServoChain.create(ids=models, wire_time=False, clock="manual")
    chain, driver, goals = _human()
    run(chain, driver, goals, 0.2)
    n = len(chain.log.kept())
    driver.configure()
    driver.torque_on()
    assert not _writes_at(chain, 168, 256, n) and driver._sentinel
    assert _slots(chain, XL330, 1) == _slots(fresh, XL330, 1) and _slots(chain, XL330, 17) == list(SLOT_TARGETS)
    assert run(chain, driver, goals, 0.5)[-1].positions_tick() == goals


@pytest.mark.parametrize(
    ("sid", "how", "fast"),
    [(XL330, "reboot", False), (XL330, "power", True), (XL430, "reboot", True), (XL430, "power", False)],
)
def test_a_reset_on_the_mixed_chain_is_seen_the_next_cycle_and_brought_back(sid: int, how: str, fast: bool) -> None:
    chain, driver, goals = _human(fast)
    first = 17 if sid == XL330 else 1
    run(chain, driver, goals, 0.5)
    n = len(chain.log.kept())
    if how == "reboot":
        driver.bus.reboot(sid)  # a Reboot on the wire, behind the driver's back
        chain.advance(0.11)  # a rebooting servo is silent for 0.1 s
    else:
        chain.faults.inject(sid, "disconnect", duration_s=0.001)  # a power cycle shorter than a cycle
        chain.advance(0.002)
    assert _slots(chain, sid, first) != list(SLOT_TARGETS) and not chain.servo(sid).torque_on
    present = chain.servo(sid).position_tick
    snap = driver.cycle(goals)
    seen = [e for e in snap.events if e.kind == FaultKind.RECONNECTED and e.servo_id == sid]
    assert seen and "position sentinel read 0" in seen[0].reaction  # the first cycle after the reset
    assert snap[sid].position_tick == present != 0  # the reply's (zero) position was never applied
    assert _slots(chain, sid, first) == list(SLOT_TARGETS)  # re-configured in the same cycle: map rewritten
    assert chain.servo(sid).torque_on
    pins = [(s, g) for _, s, g in chain.goal_writes() if s == sid][-1:]
    assert pins == [(sid, present)] and chain.servo(sid).read_register("Goal Position") == present  # re-pinned
    mapped = [(sid, 168, 8), (sid, 168, 8), (sid, 200, 8)] if sid == XL330 else [(sid, 168, 8)]
    assert _writes_at(chain, 168, 256, n) == mapped  # XL330: slots 1..4 tried, written back, then 17..20
    snaps = run(chain, driver, goals, 1.0)
    assert snaps[-1].positions_tick() == goals and snaps[-1][sid].torque_on and not snaps[-1][sid].stale
    assert len(events_of(driver, FaultKind.RECONNECTED, sid)) == 1  # once, not again by the status read
    assert len(events_of(driver, FaultKind.RECONNECTED)) == 1 and not events_of(driver, FaultKind.SENTINEL)
    assert_goals_within_limits(chain, driver)


def test_reset_detection_does_not_wait_for_the_status_group() -> None:
    """No chain time passes between cycles (the status group is never due again), yet a reset servo is
    seen in the first cycle after it, by its position reply alone (XL330 and XL430 on the human chain)."""
    chain, driver, goals = _human()
    for _ in range(3):
        driver.cycle(goals)  # the first reads of every group (due at once)
    reads0 = driver.telemetry_reads["status"]
    for sid in (XL330, XL430):
        chain.servo(sid).reboot(0.0)
        snap = driver.cycle(goals)
        assert [e for e in snap.events if e.kind == FaultKind.RECONNECTED and e.servo_id == sid]
        assert chain.servo(sid).torque_on
    assert driver.telemetry_reads["status"] == reads0


def test_a_torque_off_servo_reset_is_reconfigured_with_torque_left_off_and_its_position_discarded() -> None:
    chain, driver = make_driver(profile_velocity=150)
    driver.torque_off([4])
    snaps = run(chain, driver, GOALS, 0.2)
    last = snaps[-1][4].position_tick
    chain.servo(4).reboot(0.0)
    snap = driver.cycle(GOALS)
    assert [e for e in snap.events if e.servo_id == 4 and "out of service" in e.reaction]
    assert snap[4].position_tick == last and snap[4].stale  # the reply's (zero) position was not applied
    assert _slots(chain, 4, 17) == list(SLOT_TARGETS) and not chain.servo(4).torque_on
    assert chain.servo(4).read_register("PROFILE_VELOCITY") == 150
    snaps = run(chain, driver, GOALS, 0.2)
    assert not snaps[-1][4].stale and not snaps[-1][4].torque_on and not chain.servo(4).torque_on


def test_an_out_of_service_servo_whose_reconfigure_fails_is_retried_at_the_reprobe_interval() -> None:
    policy = FaultPolicy(reprobe_interval_s=0.25)
    chain, driver = make_driver(policy=policy)
    driver.torque_off([3])
    last = run(chain, driver, GOALS, 0.2)[-1][3].position_tick
    chain.servo(3).reboot(0.0)
    chain.servo(3).write_register("Model Number", 1060)  # an XL430 swapped in: its configure is refused
    n = len(chain.log.kept())
    snaps = run(chain, driver, GOALS, 1.0)  # 100 cycles
    pings = [e.t_s for e in chain.log.kept()[n:] if e.id == 3 and e.instruction == 0x01]
    assert 4 <= len(pings) <= 5, pings  # a configure starts with a ping: once per 0.25 s, not every cycle
    assert all(b - a >= 0.25 - 1e-9 for a, b in zip(pings, pings[1:], strict=False))
    to_3 = [e for e in chain.log.kept()[n:] if e.id == 3]
    assert len(to_3) == len(pings)  # nothing else sent to servo 3 alone (torque is never turned on)
    ev = events_of(driver, FaultKind.RECONNECTED, 3)
    assert len(ev) == 1 and "re-configure failed" in ev[0].reaction
    assert all(s[3].position_tick == last != 0 and not s[3].torque_on for s in snaps)  # its zero never applied
    assert not chain.servo(3).torque_on
    assert snaps[-1].positions_tick()[1] == GOALS[1]  # the others carry on


def _real_time_driver(policy: FaultPolicy, **kw: object) -> tuple[ServoChain, Driver]:
    """4 XL330s with wire time on the real clock: cycles run back to back are really back to back (the bus is
    never idle for as long as a group read takes)."""
    chain = ServoChain.create(ids=[1, 2, 3, 4], model="XL330-M288", baud=1_000_000)
    specs = [ServoSpec(i, "XL330-M288", min_position_tick=1024, max_position_tick=3072) for i in (1, 2, 3, 4)]
    driver = Driver(open_bus("emulator", chain=chain), specs, policy=policy, **kw)  # type: ignore[arg-type]
    driver.configure()
    driver.torque_on()
    for _ in range(5):
        driver.cycle(GOALS)
    return chain, driver


def _status_reads(chain: ServoChain, after: int) -> list[float]:
    return [
        e.t_s
        for e in chain.log.kept()[after:]
        if e.instruction in (SYNC_READ, FAST_SYNC_READ) and e.params[:4] == bytes((64, 0, 7, 0))
    ]


@pytest.mark.parametrize("sentinel", [True, False])
def test_back_to_back_the_status_group_is_read_at_the_sentinels_low_floor_rate(sentinel: bool) -> None:
    """Cycles back to back: with the sentinel the status group is read about every
    `FaultPolicy.sentinel_status_floor_s` (not at its usual floor, and not never); without it, at the usual
    floor (a quarter of its rate). Rates scaled up so the run is short: status 50 Hz, floor 0.08 s / 0.3 s."""
    policy = FaultPolicy(status_hz=50.0, sentinel_status_floor_s=0.3)
    chain, driver = _real_time_driver(policy, position_sentinel=sentinel)
    try:
        assert bool(driver._sentinel) == sentinel
        n, t0 = len(chain.log.kept()), time.monotonic()
        cycles = 0
        while time.monotonic() < t0 + 1.5:
            driver.cycle(GOALS)
            cycles += 1
        status = _status_reads(chain, n)
        gaps = sorted(b - a for a, b in zip(status, status[1:], strict=False))
        assert cycles > 100 and gaps, (cycles, status)
        if sentinel:
            assert 3 <= len(status) <= 6, status  # 1.5 s / 0.3 s
            # (a cycle descheduled between its clock reading and its status read shortens the next gap a
            # little, a stall lengthens one: bounds that still tell 0.3 s from the 0.08 s floor and from 2 s)
            assert gaps[0] >= 0.3 - 0.02 and gaps[len(gaps) // 2] <= 0.45, gaps
        else:
            assert len(status) >= 12 and gaps[len(gaps) // 2] <= 0.1, gaps  # every 0.08 s
        driver.close(torque_off=True)
    finally:
        chain.close()


def test_the_floor_is_validated() -> None:
    for bad in (0.0, -1.0, float("nan"), float("inf"), True, "2"):
        with pytest.raises(ValueError, match="sentinel_status_floor_s"):
            FaultPolicy(sentinel_status_floor_s=bad)  # type: ignore[arg-type]
    assert FaultPolicy(sentinel_status_floor_s=5).sentinel_status_floor_s == 5


def test_a_reset_is_still_seen_by_the_status_floor_where_the_witness_is_blind() -> None:
    """The backstop: were a real servo's lost map to read the witness anyway, the status read (torque found
    off) still sees the reset, back to back within `FaultPolicy.sentinel_status_floor_s`."""
    policy = FaultPolicy(sentinel_status_floor_s=0.3)
    chain, driver = _real_time_driver(policy)
    try:
        servo = chain.servo(2)
        servo.reboot(0.0)
        for k, a in zip(range(17, 21), SLOT_TARGETS, strict=True):
            servo.write_register(f"Indirect Address {k}", a)  # the map "survives" (it does not on the emulator)
        t0 = time.monotonic()
        while time.monotonic() < t0 + 2.0 and not events_of(driver, FaultKind.RECONNECTED, 2):
            driver.cycle(GOALS)
        ev = events_of(driver, FaultKind.RECONNECTED, 2)
        # within the 0.3 s floor (and a loaded machine's stall), well before the default 2 s one
        assert ev and "torque found off" in ev[0].reaction and time.monotonic() - t0 <= 0.8
        driver.cycle(GOALS)
        assert servo.torque_on
        driver.close(torque_off=True)
    finally:
        chain.close()


def test_folded_cycles_read_the_direct_block_and_the_next_plain_cycle_checks_the_witness() -> None:
    chain, driver = make_driver()
    run(chain, driver, GOALS, 0.3)
    driver._groups[1].due_s = float("-inf")  # the motion group asks: it folds into this cycle's position read
    chain.servo(2).reboot(0.0)
    n = len(chain.log.kept())
    present = chain.servo(2).position_tick
    snap = driver.cycle(GOALS)
    assert _reads(chain, n)[0] == (122, 14, 4)  # Moving .. Present Position, direct, as without the sentinel
    assert snap[2].position_tick == present and not snap.events  # applied directly; no witness in it
    snap = driver.cycle(GOALS)
    assert _reads(chain, n)[1] == (224, 3, 4)
    seen = [e for e in snap.events if e.servo_id == 2 and e.kind == FaultKind.RECONNECTED]
    assert seen and "position sentinel read 0" in seen[0].reaction and chain.servo(2).torque_on
    chain.set_input_voltage(None, 4.8)
    snaps = run(chain, driver, GOALS, 1.0)
    assert driver.telemetry_reads["thermal"] >= 2 and driver.telemetry_reads["motion"] >= 10
    assert (132, 15, 4) in _reads(chain, n)  # thermal folded: Present Position .. Present Temperature
    last = snaps[-1][1]
    assert last.temperature_c == chain.servo(1).read_register("Present Temperature")
    assert last.voltage_v == pytest.approx(4.8) and last.current_ma is not None


def test_opting_out_writes_no_indirect_address_and_reads_positions_directly() -> None:
    models = _head_models("human")
    fresh = ServoChain.create(ids=models, wire_time=False, clock="manual")
    chain, driver, goals = _human(position_sentinel=False)
    assert driver.sentinel_info.startswith("off by request") and not events_of(driver, FaultKind.SENTINEL)
    n = len(chain.log.kept())
    snaps = run(chain, driver, goals, 1.0)
    assert snaps[-1].positions_tick() == goals
    assert not _writes_at(chain, 168, 256)  # nothing written to Indirect Address (or Data) at all
    for sid, _ in models:
        for k in range(1, _n_slots(chain, sid) + 1):
            assert _slots(chain, sid, k, 1) == _slots(fresh, sid, k, 1)
    reads = _reads(chain, n)
    assert not [r for r in reads if r[0] >= 168] and (132, 4, len(models)) in reads
    chain.servo(XL430).reboot(0.0)  # a reset is seen by the status read at its usual floor
    run(chain, driver, goals, 0.5)
    assert events_of(driver, FaultKind.RECONNECTED, XL430) and chain.servo(XL430).torque_on
    with pytest.raises(Exception, match="position_sentinel"):
        Driver(driver.bus, [ServoSpec(1, "XL330-M288")], position_sentinel="no")  # type: ignore[arg-type]


@pytest.mark.parametrize("sentinel", [True, False])
def test_face_open_passes_the_opt_out_through(sentinel: bool) -> None:
    """`Face.open` (through `open_head`) on the emulated human head: the sentinel by default; with
    ``position_sentinel=False`` nothing is written to Indirect Address."""
    from servoface.controller.face import Face

    kw = {} if sentinel else {"position_sentinel": False}
    with Face.open("human", emulate=True, wire_time=False, **kw) as face:  # type: ignore[arg-type]
        assert face.driver is not None and face.chain is not None
        assert face.driver.sentinel_info.startswith("positions read through" if sentinel else "off by request")
        assert bool(_writes_at(face.chain, 168, 256)) == sentinel
        assert (_slots(face.chain, XL330, 17) == list(SLOT_TARGETS)) == sentinel


def test_negative_and_multi_turn_positions_survive_24_bits() -> None:
    assert split(0xFFFFFF_02) == (-1, 2)
    assert split((4096 * 255) << 8 | 0x01) == (4096 * 255, 1)
    assert split(((-4096 * 256) & 0xFFFFFF) << 8 | 0x02) == (-4096 * 256, 2)


def test_the_short_read_holds_16_bits_signed_and_only_position_mode_fits_it() -> None:
    assert split(0xFFFF_02, SENTINEL_SHORT) == (-1, 2)
    assert split(4095 << 8 | 0x01, SENTINEL_SHORT) == (4095, 1)
    assert split(0x8000_02, SENTINEL_SHORT) == (-0x8000, 2)
    assert fits_short(3, 0) and fits_short(3, -0x8000) and fits_short(3, 0x7FFF - 4095)
    assert not fits_short(3, 0x7FFF - 4094) and not fits_short(3, -0x8001)  # 0..4095 + offset leaves int16
    assert not fits_short(4, 0) and not fits_short(5, 0)  # Extended / Current-based Position: +-256 turns


@pytest.mark.parametrize("fast", [False, True])
@pytest.mark.parametrize(
    "why, mode, offset",
    [("extended", 4, 0), ("offset", 3, 31_000), ("short", 3, -20_000), ("short", 3, 0)],
)
def test_the_read_is_3_bytes_only_where_every_servo_fits_16_bits(fast: bool, why: str, mode: int, offset: int) -> None:
    """One servo in Extended Position Mode, or with a Homing Offset that takes its positions past 16 bits,
    makes the whole chain read 4 bytes (one Sync Read reads one length from all), and its positions beyond
    16 bits come through; otherwise 3 bytes, negative positions (a negative offset) included. Seen from the
    emulator's side: the reads' lengths, and every position as the servo has it."""
    chain = ServoChain.create(ids=[1, 2, 3], model="XL330-M288", wire_time=False, clock="manual")
    chain.servo(2).write_register("Homing Offset", offset)
    specs = [
        ServoSpec(1, "XL330-M288", min_position_tick=1024, max_position_tick=3072),
        ServoSpec(
            2, "XL330-M288", operating_mode=mode, min_position_tick=1024, max_position_tick=3072 + 77_000 * (mode == 4)
        ),
        ServoSpec(3, "XL330-M288", min_position_tick=1024, max_position_tick=3072),
    ]
    driver = Driver(open_bus("emulator", chain=chain), specs, clock=chain.clock, fast_sync_read=fast)
    driver.configure()
    if mode == 4:
        chain.servo(2).move_by_hand(70_000)  # 17 turns: past 16 bits
    driver.torque_on([1, 3] if offset else None)  # an offset servo stays off: its goals sit beyond its limits
    assert driver._sentinel and not events_of(driver, FaultKind.SENTINEL), driver.sentinel_info
    goals = {1: 2000, 2: 70_000 if mode == 4 else 2500, 3: 1500}
    n = len(chain.log.kept())
    snaps = run(chain, driver, goals, 1.0)
    assert {sid: chain.servo(sid).position_tick for sid in goals} == snaps[-1].positions_tick()
    at = snaps[-1][2].position_tick  # past 16 bits (extended, offset 31000) or negative (offset -20000)
    assert (
        not any(s.stale for s in snaps[-1])
        and at == {0: 70_000 if mode == 4 else 2500, 31_000: 33_048, -20_000: -17_952}[offset]
    )
    plain = {r for r in _reads(chain, n) if r[0] == 224}
    size = 3 if why == "short" else 4
    assert plain == {(224, size, 3)}, plain
    assert driver._sentinel_read is (SENTINEL_SHORT if size == 3 else SENTINEL)
    assert f"{size} bytes" in driver.sentinel_info
    if why != "short":
        assert "servo 2" in driver.sentinel_info, driver.sentinel_info  # which servo needs the 4 bytes, and why
    chain.servo(2).reboot(0.0)  # a reset is still seen by the witness, whichever length
    snap = driver.cycle(goals)
    assert [e for e in snap.events if e.servo_id == 2 and "position sentinel read 0" in e.reaction]


def test_a_reconfigured_servo_that_needs_24_bits_turns_the_chain_to_4_byte_reads() -> None:
    """A servo whose Homing Offset changed behind the driver's back (then reset, so it is re-configured)
    no longer fits 16 bits: from the re-configure on the chain reads 4 bytes, and its positions are right."""
    chain, driver = make_driver()
    run(chain, driver, GOALS, 0.3)
    assert driver._sentinel_read is SENTINEL_SHORT
    n = len(chain.log.kept())
    chain.servo(3).write_register("Homing Offset", 100_000)  # EEPROM: kept through the reset
    chain.servo(3).reboot(0.0)
    snaps = run(chain, driver, GOALS, 1.0)
    assert driver._sentinel_read is SENTINEL and "4 bytes" in driver.sentinel_info
    later = [r for r in _reads(chain, n) if r[0] == 224]
    assert later[0] == (224, 3, 4) and later[-1] == (224, 4, 4)
    at = snaps[-1][3].position_tick  # past 16 bits; the servo chases a goal its offset puts out of reach
    assert at > 0x7FFF and abs(at - chain.servo(3).position_tick) < 200 and not snaps[-1][3].stale


def test_data_elsewhere_keeps_direct_reads_with_an_event() -> None:
    """Firmware whose Indirect Data sits elsewhere: neither map verifies at 224, so the chain reads Present
    Position directly, and an event says why (never a guess)."""
    chain = ServoChain.create(ids=[1, 2, 3], model="XL330-M288", wire_time=False, clock="manual")
    indirect = chain.servo(2)._indirect
    indirect.blocks = [(240, 168, 20)]  # the data of Indirect Address 1..20 at 240.. on this servo
    specs = [ServoSpec(i, "XL330-M288", min_position_tick=1024, max_position_tick=3072) for i in (1, 2, 3)]
    driver = Driver(open_bus("emulator", chain=chain), specs, clock=chain.clock)
    driver.configure()
    driver.torque_on()
    ev = events_of(driver, FaultKind.SENTINEL)
    assert len(ev) == 1 and ev[0].servo_id is None and "servo 2" in ev[0].reaction
    assert "slots 1..4" in ev[0].reaction and "slots 17..20" in ev[0].reaction
    assert "directly" in driver.sentinel_info
    fresh = ServoChain.create(ids=[1, 2, 3], model="XL330-M288", wire_time=False, clock="manual")
    assert [_slots(chain, 2, k, 1) for k in range(1, 21)] == [_slots(fresh, 2, k, 1) for k in range(1, 21)]
    n = len(chain.log.kept())
    snaps = run(chain, driver, {1: 2000, 2: 2500, 3: 1500}, 1.0)
    assert snaps[-1].positions_tick() == {1: 2000, 2: 2500, 3: 1500}
    assert {r for r in _reads(chain, n) if r[1] == 4} == {(132, 4, 3)}
    chain.servo(1).reboot(0.0)  # without the sentinel a reset is still seen (the status group)
    run(chain, driver, {1: 2000, 2: 2500, 3: 1500}, 0.5)
    assert events_of(driver, FaultKind.RECONNECTED, 1) and chain.servo(1).torque_on


def test_velocity_mode_keeps_direct_reads() -> None:
    chain = ServoChain.create(ids=[1], model="XL330-M288", wire_time=False, clock="manual")
    driver = Driver(
        open_bus("emulator", chain=chain), [ServoSpec(1, "XL330-M288", operating_mode=1)], clock=chain.clock
    )
    driver.configure()
    assert "VELOCITY mode" in driver.sentinel_info
    assert not _writes_at(chain, 168, 256)


def test_a_replaced_servo_whose_map_does_not_verify_turns_the_sentinel_off() -> None:
    chain, driver = make_driver()
    run(chain, driver, GOALS, 0.2)
    chain.servo(3)._indirect.blocks = [(240, 168, 20)]  # its firmware changed: data no longer at 224
    chain.servo(3).reboot(0.0)
    snaps = run(chain, driver, GOALS, 1.0)
    assert not driver._sentinel and events_of(driver, FaultKind.SENTINEL)
    assert "directly" in driver.sentinel_info and snaps[-1].positions_tick() == GOALS
    assert chain.servo(3).torque_on and not snaps[-1][3].stale


def test_over_a_pty_a_reset_is_seen_and_repaired() -> None:
    """The real SDK over a pseudo-terminal (the chain served from its own thread, real time)."""
    chain = ServoChain.create(ids=[(1, "XL330-M288"), (2, "XL430-W250"), (3, "XL330-M288")], baud=1_000_000)
    try:
        bus = open_bus("dynamixel", port=chain.serve_pty(), baud=1_000_000, warn_latency=False)
        specs = [
            ServoSpec(i, m, min_position_tick=1024, max_position_tick=3072)
            for i, m in ((1, "XL330-M288"), (2, "XL430-W250"), (3, "XL330-M288"))
        ]
        driver = Driver(bus, specs)
        driver.configure()
        driver.torque_on()
        assert driver.sentinel_info.startswith("positions read through Indirect Data at 224")
        goals = {1: 2000, 2: 2100, 3: 1900}
        for _ in range(20):
            driver.cycle(goals)
        for sid, first in ((2, 1), (3, 17)):
            chain.servo(sid).reboot(0.0)
            snap = driver.cycle(goals)
            assert [e for e in snap.events if e.servo_id == sid and "position sentinel" in e.reaction]
            assert _slots(chain, sid, first) == list(SLOT_TARGETS) and chain.servo(sid).torque_on
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:
            snap = driver.cycle(goals)
            if snap.positions_tick() == goals:
                break
        assert snap.positions_tick() == goals
        driver.close(torque_off=True)
    finally:
        chain.close()


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
        assert driver.sentinel_info.startswith("positions read through Indirect Data at 224")
        goals = {1: 2000, 2: 2100, 3: 1900, 4: 2050}
        for _ in range(10):
            driver.cycle(goals)
        bus.reboot(3)  # not the driver's: its records still say servo 3 is in service
        time.sleep(0.05)
        snap = driver.cycle(goals)
        news = [e for e in driver.events if e.servo_id == 3 and e.kind == FaultKind.RECONNECTED]
        assert len(news) == 1 and "position sentinel read 0" in news[0].reaction  # not the status read's
        assert news[0] in snap.events  # the first cycle after the reset
        assert bus.read(3, Register.INDIRECT_ADDRESS_17_20) == MAP_VALUE
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


def test_ram_restore_on_one_servo_keeps_direct_reads_for_the_chain_and_maps_nothing_on_it() -> None:
    """RAM Restore (Startup Configuration bit 1) may bring a backed-up map back at power-up, so a reset would
    not show in the witness: that servo is not mapped at all, the chain reads directly (an event says why),
    and a reset is still seen by the status group."""
    chain = ServoChain.create(ids=[1, 2, 3], model="XL330-M288", wire_time=False, clock="manual")
    chain.servo(2).write_register("Startup Configuration", 2)
    fresh = ServoChain.create(ids=[2], model="XL330-M288", wire_time=False, clock="manual")
    specs = [ServoSpec(i, "XL330-M288", min_position_tick=1024, max_position_tick=3072) for i in (1, 2, 3)]
    driver = Driver(open_bus("emulator", chain=chain), specs, clock=chain.clock)
    driver.configure()
    driver.torque_on()
    ev = events_of(driver, FaultKind.SENTINEL)
    assert len(ev) == 1 and "servo 2" in ev[0].reaction and "RAM Restore" in ev[0].reaction
    assert "directly" in driver.sentinel_info and "RAM Restore" in driver.sentinel_info
    assert not [w for w in _writes_at(chain, 168, 256) if w[0] == 2]
    assert [_slots(chain, 2, k, 1) for k in range(1, 21)] == [_slots(fresh, 2, k, 1) for k in range(1, 21)]
    n = len(chain.log.kept())
    snaps = run(chain, driver, {1: 2000, 2: 2500, 3: 1500}, 1.0)
    assert snaps[-1].positions_tick() == {1: 2000, 2: 2500, 3: 1500}
    assert {r for r in _reads(chain, n) if r[1] == 4} == {(132, 4, 3)}
    chain.servo(1).reboot(0.0)
    run(chain, driver, {1: 2000, 2: 2500, 3: 1500}, 0.5)
    assert events_of(driver, FaultKind.RECONNECTED, 1) and chain.servo(1).torque_on


def test_startup_torque_on_alone_does_not_refuse_the_sentinel() -> None:
    """Bit 0 (Startup Torque On) restores no RAM: the map still goes at a reset, so the sentinel stays on,
    and it is what sees such a reset (torque comes back on by itself, so the status read would not)."""
    chain = ServoChain.create(ids=[1, 2], model="XL330-M288", wire_time=False, clock="manual")
    chain.servo(2).write_register("Startup Configuration", 1)
    specs = [ServoSpec(i, "XL330-M288", min_position_tick=1024, max_position_tick=3072) for i in (1, 2)]
    driver = Driver(open_bus("emulator", chain=chain), specs, clock=chain.clock)
    driver.configure()
    driver.torque_on()
    assert driver._sentinel and not events_of(driver, FaultKind.SENTINEL)
    run(chain, driver, {1: 2000, 2: 2500}, 0.5)
    chain.servo(2).reboot(0.0)  # comes back with torque on by itself: "torque found off" cannot see it
    assert chain.servo(2).torque_on
    run(chain, driver, {1: 2000, 2: 2500}, 0.1)
    ev = events_of(driver, FaultKind.RECONNECTED, 2)
    assert len(ev) == 1 and "sentinel" in ev[0].reaction
    assert _slots(chain, 2, 17) == list(SLOT_TARGETS)  # map rewritten (XL330: slots 17..20)
