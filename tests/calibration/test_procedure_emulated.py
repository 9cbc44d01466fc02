"""The interactive procedure on the emulated chain, through the real driver stack.

The stock dynamixel-sdk talks Protocol 2.0 to the emulator (in-process port); the scripted "hand" turns
the emulated horns with ``move_by_hand`` (torque off) or jogs them with keys (torque on), exactly what a
person at the head does. The CLI's adapter (`BusServoAccess`) is the one under test.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from servoface.calibration.fileformat import load_calibration
from servoface.calibration.procedure import Capture, Jog, ProcedureOptions, Prompt, Reply, run_procedure
from servoface.calibration.spec import ServoSpec
from servoface.controller.cli.calibrate import BusServoAccess

from tests.calibration.helpers import small_specs


def physical_tick(spec: ServoSpec, target: float) -> float:
    if spec.kind == "joint":
        return 2048 + spec.direction * target * 4096 / 360
    return 2048 + spec.direction * math.degrees(math.asin(target / 15.0)) * 4096 / 360


@pytest.fixture
def emulated() -> Iterator[tuple[object, object]]:
    from servoface.hardware.bus import open_bus
    from servoface.hardware.emulator import ServoChain

    chain = ServoChain.create(
        ids=[s.servo_id for s in small_specs()], model="XL330-M288", wire_time=False, clock="manual"
    )
    bus = open_bus("dynamixel", port=chain)
    yield chain, bus
    bus.close()
    chain.close()


class EmulatedHand:
    """Moves servos by hand on the emulator; jogs the ``jog_roles`` with keys instead."""

    def __init__(self, chain: object, specs: list[ServoSpec], jog_roles: set[str]) -> None:
        self.chain = chain
        self.specs = {s.role: s for s in specs}
        self.jog_roles = jog_roles
        self.messages: list[str] = []
        self.jogs = 0

    def tell(self, message: str) -> None:
        self.messages.append(message)

    def ask(self, prompt: Prompt) -> Reply:
        spec = self.specs[prompt.role]
        assert prompt.target is not None
        want = round(physical_tick(spec, prompt.target))
        servo = self.chain.servo(spec.servo_id)  # type: ignore[attr-defined]
        if prompt.role in self.jog_roles:
            if prompt.present_tick != want:
                self.jogs += 1
                self.chain.advance(0.5)  # type: ignore[attr-defined]  # let the last jog finish
                if servo.position_tick != want:
                    return Jog(max(-300, min(300, want - servo.position_tick)))  # one move <= 300 ticks
            return Capture()
        servo.move_by_hand(want)
        return Capture()


def test_interactive_procedure_on_the_emulated_chain(emulated: tuple[object, object], tmp_path: Path) -> None:
    chain, bus = emulated
    specs = small_specs()
    hand = EmulatedHand(chain, specs, jog_roles={"upper_lid_r"})
    result = run_procedure(
        BusServoAccess(bus),
        hand,
        specs,
        "small",  # type: ignore[arg-type]
        options=ProcedureOptions(intermediate=4),
        plot_dir=tmp_path / "plots",
        out=tmp_path / "cal.json",
    )
    cal = load_calibration(tmp_path / "cal.json")
    assert hand.jogs > 0
    for spec in specs:
        s = cal[spec.role]
        t = np.linspace(spec.lower, spec.upper, 31)
        truth = np.array([physical_tick(spec, x) for x in t])
        tolerance = 1.5 if spec.kind == "joint" else 0.01 * (s.max_tick - s.min_tick)
        assert np.max(np.abs(s.curve.forward(t) - truth)) < tolerance, spec.role
        assert (tmp_path / "plots" / f"{spec.role}.png").stat().st_size > 10_000
        assert not chain.servo(spec.servo_id).torque_on  # type: ignore[attr-defined]  # left relaxed
    # the jogged servo was pinned: its first goal write equals where it stood when torque came on
    lid_goals = [v for _, sid, v in chain.goal_writes() if sid == 6]  # type: ignore[attr-defined]
    assert lid_goals[0] == 2048
    assert result.calibration.position_limits_tick()[6] == (
        cal["upper_lid_r"].min_tick,
        cal["upper_lid_r"].max_tick,
    )


class RetryingHand:
    """One servo: the first attempt captures the upper end 20 ticks past neutral and every point there
    (the fit fails: flat), so the procedure narrows the servo's limits to 2048..2068 and measures again;
    the second attempt jogs under torque to the true ticks, past that narrowed range."""

    def __init__(self, chain: object, spec: ServoSpec, abort_after_narrow: bool = False) -> None:
        self.chain = chain
        self.spec = spec
        self.abort_after_narrow = abort_after_narrow
        self.attempt = 0
        self.messages: list[str] = []

    def tell(self, message: str) -> None:
        self.messages.append(message)

    def ask(self, prompt: Prompt) -> Reply:
        from servoface.calibration.procedure import Abort

        servo = self.chain.servo(self.spec.servo_id)  # type: ignore[attr-defined]
        if prompt.step == "neutral" and prompt.present_tick == servo.position_tick and not self._neutral_asked:
            self.attempt += 1
            self._neutral_asked = True
        if prompt.step != "neutral":
            self._neutral_asked = False
        assert prompt.target is not None
        if self.attempt == 1:
            if prompt.step == "point" and self.abort_after_narrow:
                return Abort()
            servo.move_by_hand(2048 if prompt.step == "neutral" else 2068)
            return Capture()
        want = round(physical_tick(self.spec, prompt.target))
        if prompt.present_tick != want:
            self.chain.advance(0.5)  # type: ignore[attr-defined]  # let the last jog finish
            if servo.position_tick != want:
                return Jog(max(-300, min(300, want - servo.position_tick)))
        return Capture()

    _neutral_asked = False


def test_a_re_measure_puts_back_the_limits_the_failed_captures_set(
    emulated: tuple[object, object], tmp_path: Path
) -> None:
    """The failed first attempt narrowed Min/Max Position Limit to 2048..2068; the re-measure puts the
    servo's own limits back before it jogs past them (on the old code the first goal past 2068 got a Data
    Limit Error and the session ended with nothing saved), and the saved run narrows them to the new ends."""
    chain, bus = emulated
    jaw = small_specs()[0]
    servo = chain.servo(jaw.servo_id)  # type: ignore[attr-defined]
    servo.write_register("Min Position Limit", 1000)
    servo.write_register("Max Position Limit", 3500)
    hand = RetryingHand(chain, jaw)
    result = run_procedure(
        BusServoAccess(bus), hand, [jaw], "small", options=ProcedureOptions(), out=tmp_path / "cal.json"
    )
    assert hand.attempt == 2
    assert any("Min/Max Position Limit set to 2048..2068" in m for m in hand.messages)
    assert any("Min/Max Position Limit back to 1000..3500 for the new attempt" in m for m in hand.messages)
    goals = [v for _, sid, v in chain.goal_writes() if sid == jaw.servo_id]  # type: ignore[attr-defined]
    assert max(goals) > 2068  # the jogs went past the first attempt's narrowed range
    s = load_calibration(tmp_path / "cal.json")["jaw"]
    assert abs(s.max_tick - physical_tick(jaw, jaw.upper)) <= 2
    assert (servo.read_register("Min Position Limit"), servo.read_register("Max Position Limit")) == (
        s.min_tick,
        s.max_tick,
    )
    assert result.saved_to is not None


def test_a_run_that_saves_nothing_puts_the_limits_back(emulated: tuple[object, object], tmp_path: Path) -> None:
    """Aborted after the ends narrowed the limits: the servo's own Min/Max Position Limit come back, torque
    off, and no file is written."""
    from servoface.calibration.errors import ProcedureAborted

    chain, bus = emulated
    jaw = small_specs()[0]
    servo = chain.servo(jaw.servo_id)  # type: ignore[attr-defined]
    servo.write_register("Min Position Limit", 1000)
    servo.write_register("Max Position Limit", 3500)
    hand = RetryingHand(chain, jaw, abort_after_narrow=True)
    with pytest.raises(ProcedureAborted):
        run_procedure(BusServoAccess(bus), hand, [jaw], "small", out=tmp_path / "cal.json")
    assert any("set to 2048..2068" in m for m in hand.messages)
    assert (servo.read_register("Min Position Limit"), servo.read_register("Max Position Limit")) == (1000, 3500)
    assert not servo.torque_on
    assert not (tmp_path / "cal.json").exists()
