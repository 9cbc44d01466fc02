"""Calibration never moves a servo outside a safe window: before the limits are captured, every jog and
go-to is bounded around where the servo is and within the declared range; ``+4000`` is refused with a
message and never reaches the wire."""

from __future__ import annotations

import subprocess
from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st
from servoface.calibration.procedure import Abort, GoTo, Jog, ProcedureOptions, Prompt, Reply, _Session

from tests.calibration.helpers import small_specs
from tests.calibration.test_procedure import FakeServos
from tests.integration.safe_stop_rig import bench, servoface

JAW_LIMITS = (2048, 2332)  # the shipped human calibration's jaw


def test_plus_4000_at_the_jaws_neutral_prompt_never_reaches_the_wire(tmp_path: Path) -> None:
    """Over a pty, checked from the emulator's side: only the allowed jogs were written."""
    keys = "+4000\n-4000\n+301\nK\nK\nK\nK\n-1000\nq\n"
    with bench(tmp_path) as b:
        proc = servoface(
            "calibrate",
            "--head",
            "human",
            "--port",
            b.port,
            "--roles",
            "jaw",
            "--out",
            str(tmp_path / "c.json"),
            env={"SERVOFACE_LOCK_DIR": str(b.lock_dir)},
        )
        out, err = _feed(proc, keys)
        state = b.final_state()
    jaw = [g for _, sid, g in state["goal_writes"] if sid == 18]
    assert out.count("refused") >= 5, out  # +4000, -4000, +301, the 4th K (past the window), -1000
    assert "safe window" in out and "at most 300 ticks" in out
    assert jaw and max(jaw) <= JAW_LIMITS[1] + 40 and min(jaw) >= JAW_LIMITS[0] - 40, jaw
    assert jaw == [2048, 2148, 2248, 2348]  # pin, then three K jogs of 100; nothing else
    assert state["servos"]["18"]["torque_enable"] == 0  # aborted: torque off again
    assert "nothing saved" in err


def _feed(proc: subprocess.Popen[str], keys: str) -> tuple[str, str]:
    return proc.communicate(input=keys, timeout=120)


class Replies:
    """An operator who sends a given list of replies at the neutral prompt, then aborts."""

    def __init__(self, replies: list[Reply]) -> None:
        self.replies = list(replies)
        self.messages: list[str] = []

    def tell(self, message: str) -> None:
        self.messages.append(message)

    def ask(self, prompt: Prompt) -> Reply:
        return self.replies.pop(0) if self.replies else Abort()


moves = st.lists(
    st.one_of(
        st.builds(Jog, st.one_of(st.integers(-5000, 5000), st.integers(-(10**30), 10**30))),
        st.builds(GoTo, st.integers(-10_000, 10_000)),
    ),
    max_size=12,
)


@settings(max_examples=2000, deadline=None)
@given(moves, st.integers(100, 4000))
def test_no_jog_sequence_leaves_the_window(replies: list[Reply], start: int) -> None:
    spec = small_specs()[0]  # jaw, 0..25 deg: 285 ticks
    servos = FakeServos({spec.servo_id: start})
    session = _Session(servos, Replies(replies), ProcedureOptions())
    session.open_window(spec)
    lo, hi = session.window
    assert lo >= start - 285 - 40 and hi <= start + 285 + 40
    for reply in replies:
        present = servos.present[spec.servo_id]
        before = len(servos.log)
        if isinstance(reply, Jog):
            session.jog(spec, reply.delta_tick)
        else:
            session.move_to(spec, reply.tick)
        for kind, _, tick in servos.log[before:]:
            if kind == "goal":
                assert lo <= tick <= hi and abs(tick - present) <= 300
