"""The calibration procedure core with a scripted operator, the CSV mode, and the plots."""

from __future__ import annotations

import math
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from servoface.calibration.errors import (
    CalibrationError,
    CoverageError,
    MeasurementCsvError,
    ProcedureAborted,
    ProcedureError,
)
from servoface.calibration.fileformat import load_calibration
from servoface.calibration.procedure import (
    Abort,
    Capture,
    Finish,
    GoTo,
    Jog,
    ProcedureOptions,
    Prompt,
    Relax,
    Reply,
    calibrate_from_csv,
    run_procedure,
)
from servoface.calibration.spec import ServoSpec

from tests.calibration.helpers import small_specs


def true_tick(spec: ServoSpec, target: float) -> float:
    """The physical head: joints linear (mirrored for _r), anchors on a 15 mm crank."""
    if spec.kind == "joint":
        return 2048 + spec.direction * target * 4096 / 360
    return 2048 + spec.direction * math.degrees(math.asin(target / 15.0)) * 4096 / 360


@dataclass
class FakeServos:
    """ServoAccess of ideal servos: a goal moves the horn at once when torque is on."""

    present: dict[int, int]
    torque: dict[int, bool] = field(default_factory=dict)
    log: list[tuple[str, int, int]] = field(default_factory=list)

    def read_present_tick(self, servo_id: int) -> int:
        return self.present[servo_id]

    def set_torque(self, servo_id: int, enabled: bool) -> None:
        self.torque[servo_id] = enabled
        self.log.append(("torque", servo_id, int(enabled)))

    def write_goal_tick(self, servo_id: int, tick: int) -> None:
        self.log.append(("goal", servo_id, tick))
        if self.torque.get(servo_id):
            self.present[servo_id] = tick


class ScriptedHand:
    """An operator who moves each servo by hand to the asked target (or jogs first when told to)."""

    def __init__(self, servos: FakeServos, specs: list[ServoSpec], jog_first: bool = False) -> None:
        self.servos = servos
        self.specs = {s.role: s for s in specs}
        self.jog_first = jog_first
        self.prompts: list[Prompt] = []
        self.messages: list[str] = []
        self.extra: list[float] = []

    def tell(self, message: str) -> None:
        self.messages.append(message)

    def ask(self, prompt: Prompt) -> Reply:
        self.prompts.append(prompt)
        spec = self.specs[prompt.role]
        if prompt.step == "extra":
            if not self.extra:
                return Finish()
            value = self.extra.pop()
            self.servos.present[spec.servo_id] = round(true_tick(spec, value))
            return Capture(value)
        assert prompt.target is not None
        want = round(true_tick(spec, prompt.target))
        if self.jog_first and prompt.present_tick != want:
            return Jog(max(-300, min(300, want - prompt.present_tick)))  # jog there under torque, in steps
        if not self.servos.torque.get(spec.servo_id):
            self.servos.present[spec.servo_id] = want  # move the horn by hand
        return Capture()


def _run(tmp_path: Path, **kw: object) -> tuple[FakeServos, ScriptedHand, object]:
    specs = small_specs()
    servos = FakeServos({s.servo_id: 2048 for s in specs})
    hand = ScriptedHand(servos, specs, jog_first=bool(kw.pop("jog_first", False)))
    plots = tmp_path / "plots" if kw.pop("plots", True) else None
    result = run_procedure(servos, hand, specs, "small", plot_dir=plots, out=tmp_path / "cal.json", **kw)  # type: ignore[arg-type]
    return servos, hand, result


def test_procedure_captures_fits_plots_and_saves(tmp_path: Path) -> None:
    servos, hand, result = _run(tmp_path, options=ProcedureOptions(intermediate=3))
    cal = load_calibration(tmp_path / "cal.json")
    assert cal.metadata.method == "procedure"
    specs = {s.role: s for s in small_specs()}
    for role in cal:
        s, spec = cal[role], specs[role]
        assert (s.min_target, s.max_target) == (spec.lower, spec.upper)
        assert s.curve.kind == ("linear" if spec.kind == "joint" else "pchip")
        # the fitted curve reproduces the 'physical' head: within a tick for the geared joints, within 1 %
        # of the tick span for the crank-driven anchors measured at only 6 points
        t = np.linspace(spec.lower, spec.upper, 41)
        truth = np.array([true_tick(spec, x) for x in t])
        tolerance = 1.5 if spec.kind == "joint" else 0.01 * (s.max_tick - s.min_tick)
        assert np.max(np.abs(s.curve.forward(t) - truth)) < tolerance
        assert np.allclose(s.curve.forward(s.measured_points[:, 0]), s.measured_points[:, 1], atol=0.6)
        assert s.direction == spec.direction
        assert len(s.measured_points) == len({spec.lower, spec.neutral, spec.upper}) + 3
        png = tmp_path / "plots" / f"{role}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # torque was switched off before and after every servo, never left on
    assert all(not on for on in servos.torque.values())
    steps = [p.step for p in hand.prompts if p.role == "upper_lid_r"]
    assert steps == ["neutral", "lower", "upper", "point", "point", "point"]


def test_jogging_pins_the_goal_before_torque_on(tmp_path: Path) -> None:
    servos, hand, result = _run(tmp_path, jog_first=True, plots=False, options=ProcedureOptions(intermediate=1))
    first_torque_on = servos.log.index(("torque", 18, 1))
    assert servos.log[first_torque_on - 1] == ("goal", 18, 2048)  # goal = present, then torque on
    assert load_calibration(tmp_path / "cal.json")["jaw"].to_tick(25.0) == round(2048 + 25 * 4096 / 360)


def test_relax_switches_torque_off_after_a_jog() -> None:
    specs = small_specs()[:1]
    servos = FakeServos({18: 2048})

    class JogThenHand(ScriptedHand):
        def ask(self, prompt: Prompt) -> Reply:
            if prompt.step == "upper" and servos.present[18] == 2048:
                return Jog(50)
            if prompt.step == "upper" and servos.torque.get(18):
                return Relax()
            return super().ask(prompt)

    result = run_procedure(servos, JogThenHand(servos, specs), specs, "one", options=ProcedureOptions(intermediate=0))
    assert ("goal", 18, 2098) in servos.log
    on = servos.log.index(("torque", 18, 1))
    assert ("torque", 18, 0) in servos.log[on:]  # relaxed before the hand moved it on
    assert result.calibration["jaw"].to_tick(25.0) == round(2048 + 25 * 4096 / 360)


def test_quick_jogs_add_up_from_the_last_goal_and_goto_moves_there() -> None:
    """The horn lags behind its goal (present stays put): jogs must not restart from the present tick."""
    specs = small_specs()[:1]
    servos = FakeServos({18: 2048})
    script: list[Reply] = [Jog(10), Jog(10), Jog(10), GoTo(2300), Relax()]

    class Lagging(ScriptedHand):
        def ask(self, prompt: Prompt) -> Reply:
            if prompt.step == "upper" and script:
                servos.present[18] = 2048  # has not moved yet
                return script.pop(0)
            return super().ask(prompt)

    run_procedure(servos, Lagging(servos, specs), specs, "one", options=ProcedureOptions(intermediate=0))
    goals = [v for kind, sid, v in servos.log if kind == "goal"]
    assert goals == [2048, 2058, 2068, 2078, 2300]  # pin, three jogs from the last goal, go-to


def test_free_points_are_added_and_abort_saves_nothing(tmp_path: Path) -> None:
    specs = small_specs()[:1]
    servos = FakeServos({18: 2048})
    hand = ScriptedHand(servos, specs)
    hand.extra = [3.3, 17.5]
    result = run_procedure(servos, hand, specs, "one", options=ProcedureOptions(intermediate=0, free_points=True))
    assert sorted(result.calibration["jaw"].measured_points[:, 0].tolist()) == [0.0, 3.3, 17.5, 25.0]

    class Quitter(ScriptedHand):
        def ask(self, prompt: Prompt) -> Reply:
            return Abort() if prompt.step == "upper" else super().ask(prompt)

    with pytest.raises(ProcedureAborted, match="'jaw'"):
        run_procedure(servos, Quitter(servos, specs), specs, "one", out=tmp_path / "never.json")
    assert not (tmp_path / "never.json").exists()


def test_a_bad_capture_is_reported_and_the_servo_measured_again(tmp_path: Path) -> None:
    specs = small_specs()[:1]
    servos = FakeServos({18: 2048})

    class Clumsy(ScriptedHand):
        """First attempt: leaves the horn at neutral for the upper limit (not monotone)."""

        attempts = 0

        def ask(self, prompt: Prompt) -> Reply:
            if prompt.step == "neutral":
                Clumsy.attempts += 1
            if prompt.step == "upper" and Clumsy.attempts == 1:
                return Capture()
            return super().ask(prompt)

    hand = Clumsy(servos, specs)
    result = run_procedure(servos, hand, specs, "one", options=ProcedureOptions(intermediate=2))
    assert Clumsy.attempts == 2
    assert any("attempt 1 of 3" in m for m in hand.messages)
    assert result.calibration["jaw"].to_tick(25.0) == round(2048 + 25 * 4096 / 360)

    class Hopeless(ScriptedHand):
        def ask(self, prompt: Prompt) -> Reply:
            return Capture()  # never moves anything

    with pytest.raises(ProcedureError, match="no usable calibration after 3 attempts"):
        run_procedure(servos, Hopeless(servos, specs), specs, "one")


def _write_csv(path: Path, specs: list[ServoSpec], n: int = 6) -> None:
    lines = ["role,target,tick", "# measured with a protractor and calipers"]
    for s in specs:
        for t in np.linspace(s.lower, s.upper, n):
            lines.append(f"{s.role},{t:.4f},{round(true_tick(s, float(t)))}")
    path.write_text("\n".join(lines) + "\n")


def test_csv_mode_end_to_end(tmp_path: Path) -> None:
    specs = small_specs()
    _write_csv(tmp_path / "m.csv", specs)
    result = calibrate_from_csv(
        tmp_path / "m.csv", specs, "small", plot_dir=tmp_path / "plots", out=tmp_path / "cal.json"
    )
    cal = load_calibration(tmp_path / "cal.json")
    assert cal.metadata.method == "csv" and cal.metadata.source.endswith("m.csv")
    assert cal.roles == tuple(s.role for s in specs)
    goals = cal.targets_to_goals({"jaw": 12.5, "lip_corner_r": 5.0})
    assert goals[18] == pytest.approx(2048 + 12.5 * 4096 / 360, abs=1)
    assert goals[13] == pytest.approx(true_tick(specs[3], 5.0), abs=1.5)
    assert set(result.plots) == {s.role for s in specs}
    png = (tmp_path / "plots" / "lip_corner_r.png").read_bytes()
    assert _png_size(png)[0] > 300


@pytest.mark.parametrize(
    "body, line, message",
    [
        ("jaw,0,2048\njaw,25\n", 2, "expected 3 columns"),
        ("jaw,0,2048\njaw,x,2100\n", 2, "target 'x' is not a number"),
        ("jaw,0,2048\njaw,nan,2100\n", 2, "not a finite number"),
        ("jaw,0,2048\njaw,25,2332.5\n", 2, "tick '2332.5' is not an integer"),
        ("jaw,0,2048\njaw,25,5000\n", 2, "outside 0..4095"),
        ("jaw,0,2048\nnose,2,2100\n", 2, "unknown role 'nose'"),
        ("role,target,tick\njaw,0,2048\njaw,10,2200\njaw,25,2100\n", 4, "ticks fall .* strictly increasing"),
        ("jaw,0,2048\n\n# c\njaw,0,2100\n", 4, "target 0 already measured on line 1"),
        ("jaw,0,2048\n", 1, "only one measurement"),
        ("# nothing\n", 0, "no measurements"),
        ("jaw,0,2048\njaw,25,2332\njaw,-1e9,1593\n", 3, r"target -1e\+09 deg is far outside its range 0\.\.25 deg"),
        ("jaw,0,2048\njaw,250,4000\n", 2, r"far outside its range 0\.\.25 deg \(.*-25\.\.50 accepted\)"),
    ],
)
def test_csv_errors_name_the_line(tmp_path: Path, body: str, line: int, message: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(body)
    with pytest.raises(MeasurementCsvError, match=message) as info:
        calibrate_from_csv(path, small_specs()[:1], "one")
    assert info.value.line == line
    assert str(path) in str(info.value)


def test_coverage_and_monotonicity_are_checked_with_numbers(tmp_path: Path) -> None:
    spec = small_specs()[:1]
    path = tmp_path / "short.csv"
    path.write_text("jaw,0,2048\njaw,10,2162\njaw,20,2276\n")
    with pytest.raises(CoverageError, match=r"span 0\.\.20 deg but the range is 0\.\.25 deg"):
        calibrate_from_csv(path, spec, "one")
    path.write_text("jaw,0,2048\njaw,1,2059\njaw,25,2332\n")
    result = calibrate_from_csv(path, spec, "one")
    assert any("no measured point between 1 and 25 deg" in w for w in result.warnings)
    path.write_text("jaw,0,2048\njaw,12,2248\njaw,25,2332\n")
    result = calibrate_from_csv(path, spec, "one", curve_kind="linear")
    assert any("misses a measured point by" in w for w in result.warnings)


def test_points_a_little_past_the_ends_are_welcome(tmp_path: Path) -> None:
    """Only a point more than a range width past an end is refused: one just past pins the curve's end."""
    path = tmp_path / "past.csv"
    path.write_text("jaw,-24,1775\njaw,0,2048\njaw,25,2332\njaw,49,2605\n")
    result = calibrate_from_csv(path, small_specs()[:1], "one")
    assert result.calibration["jaw"].to_tick(12.5) == pytest.approx(2048 + 12.5 * 4096 / 360, abs=1)


def test_ticks_that_do_not_follow_the_target_are_refused_not_saved_flat(tmp_path: Path) -> None:
    """Two points far apart whose ticks barely differ fit a line that maps the whole range to one tick: an
    error saying so (it was "tick limits 2048..2048 must satisfy ..." from deep inside)."""
    path = tmp_path / "flat.csv"
    path.write_text("jaw,-25,2047\njaw,50,2049\n")
    with pytest.raises(CalibrationError, match=r"whole range 0\.\.25 deg maps to one tick \(2048\)"):
        calibrate_from_csv(path, small_specs()[:1], "one", out=tmp_path / "cal.json")
    assert not (tmp_path / "cal.json").exists()


def _png_size(data: bytes) -> tuple[int, int]:
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", data[16:24])
    # every chunk's CRC is valid and the image data decompresses: a real, complete PNG
    pos, idat = 8, b""
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind = data[pos + 4 : pos + 8]
        chunk = data[pos + 8 : pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length : pos + 12 + length])
        assert zlib.crc32(kind + chunk) == crc
        idat += chunk if kind == b"IDAT" else b""
        pos += 12 + length
    assert len(zlib.decompress(idat)) > width * height
    return width, height


def _corner_pull_mm(own_tick: float, depressor_tick: float) -> float:
    """A mouth corner on a 15 mm crank, dragged down 0.01 mm per tick of its depressor neighbour."""
    return 15.0 * math.sin(math.radians((own_tick - 2048) * 360 / 4096)) - 0.01 * (depressor_tick - 2048)


def test_csv_with_neighbour_columns_fits_a_coupled_anchor(tmp_path: Path) -> None:
    corner = ServoSpec("lip_corner_l", 12, "XL330-M288", "mm", -4.0, 12.0, 0.0, "anchor", 1)
    depressor = ServoSpec("lip_depressor_l", 14, "XL330-M288", "mm", 0.0, 9.0, 0.0, "anchor", 1)
    lines = ["role,target,tick"]
    for t in np.linspace(0, 9, 5):
        lines.append(f"lip_depressor_l,{t:.4f},{round(true_tick(depressor, float(t)))}")
    for own in np.linspace(1850, 2680, 6).round():
        for dep in (2048, 2200, 2350):
            lines.append(f"lip_corner_l,{_corner_pull_mm(own, dep):.5f},{int(own)},lip_depressor_l={dep}")
    (tmp_path / "m.csv").write_text("\n".join(lines) + "\n")
    result = calibrate_from_csv(tmp_path / "m.csv", [corner, depressor], "coupled", out=tmp_path / "c.json")
    cal = load_calibration(tmp_path / "c.json")
    s = cal["lip_corner_l"]
    assert s.coupling is not None and s.coupling.neighbours == ("lip_depressor_l",)
    assert s.curve.kind == "pchip" and s.neutral_tick == 2048
    for pull, dep_mm in ((5.0, 0.0), (5.0, 6.0), (-2.0, 8.0), (10.0, 3.0)):
        goals = cal.targets_to_goals({"lip_corner_l": pull, "lip_depressor_l": dep_mm})
        assert _corner_pull_mm(goals[12], goals[14]) == pytest.approx(pull, abs=0.1)  # the physical pull
    # without the coupling (1-D slice at the neighbour's neutral) the depressor's drag would be missed
    dep_tick = cal["lip_depressor_l"].to_tick(6.0)
    assert abs(_corner_pull_mm(s.to_tick(5.0), dep_tick) - 5.0) > 2.0
    assert result.reports["lip_corner_l"].servo.coupling is not None

    bad = lines[:-1] + ["lip_corner_l,3.0,2100,lip_pucker=2048"]
    (tmp_path / "bad.csv").write_text("\n".join(bad) + "\n")
    with pytest.raises(MeasurementCsvError, match="neighbour 'lip_pucker' of 'lip_corner_l' is not another"):
        calibrate_from_csv(tmp_path / "bad.csv", [corner, depressor], "coupled")
    bad = lines[:-1] + ["lip_corner_l,3.0,2100"]
    (tmp_path / "bad.csv").write_text("\n".join(bad) + "\n")
    with pytest.raises(MeasurementCsvError, match=f"line {len(bad)}: role 'lip_corner_l': neighbours"):
        calibrate_from_csv(tmp_path / "bad.csv", [corner, depressor], "coupled")
