"""`safe_stop.bus_problem` (asked every frame by `play_timeline`) reads each servo's `missing` through
`peek_state` (a driver's snapshot builds no state for it): the same answer as looking at every state, on
random snapshots (lazy captures and built states mixed, any servos missing, the port up or down)."""

from __future__ import annotations

import dataclasses

import numpy as np
from servoface.controller.face import Face
from servoface.controller.safe_stop import bus_problem
from servoface.hardware.snapshot import ChainSnapshot, LazyServoStates


def _reference(snapshot: ChainSnapshot | None) -> str | None:
    """`bus_problem` as it was: every servo's state looked at."""
    if snapshot is None:
        return None
    if not snapshot.bus_connected:
        return "the port failed (adapter unplugged, emulator gone?)"
    if snapshot.servos and all(s.missing for s in snapshot.servos.values()):
        return "no servo answers"
    return None


def test_bus_problem_by_peeking_is_the_look_at_every_state() -> None:
    face = Face.open("human", emulate=True, wire_time=False)
    try:
        for k in range(6):
            face.pipeline.step({"AU12": 0.05 * k})
        snapshot = face.pipeline.last_snapshot
        assert snapshot is not None and type(snapshot.servos) is LazyServoStates
        items = dict(snapshot.servos._items)  # captures (tuples) while only positions moved
    finally:
        face.close(ease_s=0.0)
    assert any(type(v) is tuple for v in items.values())
    rng = np.random.default_rng(61)
    answers = set()
    for _ in range(400):
        all_missing = rng.random() < 0.4
        ids = list(items)[: int(rng.integers(0, len(items) + 1))] if rng.random() < 0.2 else list(items)
        servos: dict[int, object] = {}
        for sid in ids:
            item = items[sid]
            missing = all_missing or bool(rng.random() < 0.9)
            state = item[0] if type(item) is tuple else item
            state = dataclasses.replace(state, missing=missing)  # type: ignore[type-var]
            lazy = type(item) is tuple and rng.random() < 0.8
            servos[sid] = (state, *item[1:]) if lazy else state  # type: ignore[misc]
        kept = dict(servos)
        snap = ChainSnapshot.owning(0.0, 1, servos, (), snapshot.stats, bool(rng.random() < 0.9))  # type: ignore[arg-type]
        want = _reference(ChainSnapshot.owning(0.0, 1, kept, (), snapshot.stats, snap.bus_connected))  # type: ignore[arg-type]
        assert bus_problem(snap) == want
        answers.add(want)
    assert answers == {None, "no servo answers", "the port failed (adapter unplugged, emulator gone?)"}
    assert bus_problem(None) is None
