"""Clear (0x10) sees the servo as it is when the packet arrives (e-manual "DYNAMIXEL Protocol 2.0", Clear).

e-manual, Protocol 2.0 > Instruction Details > Clear: "Clear multi-turn: resets the Present Position to
within one rotation (0 ~ 4,095) ... only possible while the DYNAMIXEL is stopped; if it is moving, Result
Fail is returned". Every instruction acts on the servo's state at the instant it arrives, so a servo that
stopped a while ago (no packet since) must accept Clear, and the next read must show the cleared position.
"""

from __future__ import annotations

from servoface.hardware.emulator import Instruction as I
from servoface.hardware.emulator.packet import ErrorNumber

from tests.hardware.emulator.helpers import le, quick_chain, transact

CLEAR = b"\x01\x44\x58\x4c\x22"


def _present(ser: object) -> int:
    (st,) = transact(ser, 1, I.READ, le(132, 2) + le(4, 2))  # type: ignore[arg-type]
    assert st.error == 0
    return int.from_bytes(st.data, "little", signed=True)


def _moving_to(goal_tick: int):  # type: ignore[no-untyped-def]
    chain, ser = quick_chain(ids=[1])
    for addr, value, size in ((11, 4, 1), (64, 1, 1), (116, goal_tick, 4)):  # extended mode, torque, goal
        (st,) = transact(ser, 1, I.WRITE, le(addr, 2) + le(value, size))
        assert st.error == 0
    return chain, ser


def test_clear_after_the_servo_stopped_with_no_packet_in_between() -> None:
    """e-manual Protocol 2.0, Clear: a stopped servo clears; the time since the last packet must count."""
    chain, ser = _moving_to(10_000)
    chain.advance(0.3)
    assert 0 < _present(ser) < 10_000  # the last packet saw it moving
    chain.clock.advance(5.0)  # type: ignore[attr-defined]  # the clock runs on; nothing is sent meanwhile
    (st,) = transact(ser, 1, I.CLEAR, CLEAR)
    assert st.error == 0, f"Clear answered error {st.error} although the servo stopped seconds ago"
    assert _present(ser) == 10_000 - 2 * 4096  # 1808: the cleared value, at once


def test_present_position_shows_the_clear_without_another_write() -> None:
    """e-manual Protocol 2.0, Clear: Present Position is reset to one turn by the Clear itself."""
    chain, ser = _moving_to(10_000)
    chain.advance(5.0)
    assert _present(ser) == 10_000
    (st,) = transact(ser, 1, I.CLEAR, CLEAR)
    assert st.error == 0
    assert _present(ser) == 1808


def test_clear_while_moving_is_result_fail() -> None:
    """e-manual Protocol 2.0, Clear: Result Fail while the servo moves."""
    chain, ser = _moving_to(10_000)
    chain.clock.advance(0.05)  # type: ignore[attr-defined]  # mid-move (an XL330 needs ~1.4 s for 10000 ticks)
    (st,) = transact(ser, 1, I.CLEAR, CLEAR)
    assert st.error == ErrorNumber.RESULT_FAIL
