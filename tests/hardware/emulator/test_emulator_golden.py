"""The emulator's behaviour on the wire is pinned: a seeded random session (goals in and out of limits,
profile and torque writes, Sync / Fast Sync / Bulk / single reads of every live span, obstacles, hardware
faults, lost and corrupt replies, reboots), replayed on manual-clock chains with and without wire time,
gives reply bytes, arrival times and live register values whose digests match the ones recorded from the
emulator before its speed-ups (``data/golden_session.json``). The emulator is owned for performance only:
a change that alters any byte, or when it becomes readable, fails here at the first differing block.

Regenerate (only for an intended protocol change, which needs its own review):
``python -m tests.hardware.emulator.test_emulator_golden``.
"""

from __future__ import annotations

import hashlib
import json
import random
from pathlib import Path

import pytest
from servoface.hardware.emulator import ServoChain, build_instruction

DATA = Path(__file__).parent / "data" / "golden_session.json"
IDS = tuple(range(1, 9))
STEPS = 1200
BLOCK = 50  # one digest per this many steps: a mismatch names its block
CASES = {
    "wire": {"wire_time": True},
    "nowire": {"wire_time": False},
    "packet": {"wire_time": True, "delivery": "packet"},
}
SPANS = ((132, 4), (122, 14), (132, 15), (64, 7), (120, 27), (0, 10), (116, 4), (126, 2), (146, 1), (224, 6))


def _le(value: int, size: int) -> bytes:
    return (value & ((1 << (8 * size)) - 1)).to_bytes(size, "little")


def _session(case: str, seed: int) -> list[str]:
    rng = random.Random(seed)
    chain = ServoChain.create(ids=IDS, model="XL330-M288", baud=1_000_000, clock="manual", **CASES[case])
    ser = chain.open_serial()
    digests: list[str] = []
    h = hashlib.sha256()

    def send(pid: int, inst: int, params: bytes) -> None:
        ser.write(build_instruction(pid, inst, params))

    def pump(dt_s: float) -> None:
        chain.advance(dt_s)
        got = ser.read(1 << 16)
        h.update(len(got).to_bytes(4, "little") + got)
        h.update(repr(round(chain.time_s, 9)).encode())

    send(0xFE, 0x83, _le(9, 2) + _le(1, 2) + b"".join(bytes((i, 0)) for i in IDS))  # return delay 0
    send(0xFE, 0x83, _le(64, 2) + _le(1, 2) + b"".join(bytes((i, 1)) for i in IDS))  # torque on
    pump(0.01)
    for step in range(STEPS):
        r = rng.random()
        ids = rng.sample(IDS, rng.randint(1, len(IDS)))
        if r < 0.30:  # goals, a few outside the limits (Data Limit Error, not stored)
            body = b"".join(bytes((i,)) + _le(rng.randint(-200, 4300), 4) for i in ids)
            send(0xFE, 0x83, _le(116, 2) + _le(4, 2) + body)
        elif r < 0.50:
            addr, n = rng.choice(SPANS)
            send(0xFE, 0x82, _le(addr, 2) + _le(n, 2) + bytes(ids))
        elif r < 0.62:
            addr, n = rng.choice(SPANS)
            send(0xFE, 0x8A, _le(addr, 2) + _le(n, 2) + bytes(ids))
        elif r < 0.67:
            body = b"".join(bytes((i,)) + _le(rng.choice(SPANS)[0], 2) + _le(4, 2) for i in ids)
            send(0xFE, 0x92, body)
        elif r < 0.74:
            addr, n = rng.choice(SPANS)
            send(rng.choice(IDS), 0x02, _le(addr, 2) + _le(n, 2))
        elif r < 0.80:  # profile, torque, watchdog, LED writes (some refused)
            addr, size, lo, hi = rng.choice(
                ((112, 4, 0, 400), (108, 4, 0, 100), (64, 1, 0, 1), (98, 1, 0, 3), (65, 1, 0, 1))
            )
            send(rng.choice(IDS), 0x03, _le(addr, 2) + _le(rng.randint(lo, hi), size))
        elif r < 0.83:
            sid = rng.choice(IDS)
            chain.set_obstacle(sid, rng.choice([None, rng.randint(1500, 2600)]))
        elif r < 0.86:
            kind = rng.choice(["no_reply", "corrupt_crc", "late_reply", "dropped_bytes", "overload", "overheating"])
            if kind in ("no_reply", "corrupt_crc", "dropped_bytes"):
                chain.faults.inject(rng.choice(IDS), kind, replies=rng.randint(1, 2))
            else:
                chain.faults.inject(rng.choice(IDS), kind, duration_s=rng.uniform(0.005, 0.05))
        elif r < 0.88:
            send(rng.choice(IDS), 0x08, b"")  # reboot
        elif r < 0.90:
            chain.servo(rng.choice(IDS)).temperature_c = rng.uniform(25.0, 75.0)
        else:
            send(rng.choice(IDS), 0x01, b"")  # ping
        pump(rng.choice([0.0, 0.00005, 0.0003, 0.001, 0.004, 0.02]))
        if step % 7 == 0:
            for s in chain.servos:
                h.update(bytes(s.mem))  # live registers as a host would read them, and the rest of the memory
                h.update(repr((round(s.motor.pos, 6), round(s.motor.temperature_c, 6))).encode())
        if (step + 1) % BLOCK == 0:
            digests.append(h.hexdigest()[:16])
    return digests


def _record() -> dict[str, list[str]]:
    return {f"{case}/{seed}": _session(case, seed) for case in CASES for seed in (1, 2)}


@pytest.mark.parametrize("key", [f"{c}/{s}" for c in CASES for s in (1, 2)])
def test_emulator_session_matches_the_recorded_wire(key: str) -> None:
    want = json.loads(DATA.read_text())[key]
    case, seed = key.split("/")
    got = _session(case, int(seed))
    for block, (a, b) in enumerate(zip(got, want, strict=True)):
        assert a == b, f"{key}: first difference in steps {block * BLOCK}..{(block + 1) * BLOCK - 1}"


if __name__ == "__main__":
    DATA.write_text(json.dumps(_record(), indent=1) + "\n")
    print(f"wrote {DATA}")
