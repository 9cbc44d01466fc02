"""The command line's rough edges a new user hits: bad input is refused with one message and exit code 2
(runtime failures keep 1), before anything is opened, with a hint that leads somewhere, never a traceback;
and `servoface emulate` serves a profile that is not calibrated yet, so calibration can be rehearsed."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from importlib.metadata import version
from pathlib import Path

import pytest
from servoface.controller.cli import main
from servoface.sim.heads import load_head

ROOT = Path(__file__).resolve().parents[2]
BROKEN_JSON = '{"schema_version": 1, "servos": \n'


@pytest.fixture(scope="module")
def new_head(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A profile as `servoface new DIR --from mechanical` writes it: no calibration.json yet."""
    folder = tmp_path_factory.mktemp("profiles") / "my_head"
    assert main(["new", str(folder), "--from", "mechanical"]) == 0
    assert not (folder / "calibration.json").exists()
    return folder


@pytest.fixture(scope="module")
def broken_head(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A profile whose calibration.json is truncated JSON."""
    folder = tmp_path_factory.mktemp("profiles") / "bad_head"
    assert main(["new", str(folder), "--from", "mechanical"]) == 0
    (folder / "calibration.json").write_text(BROKEN_JSON)
    return folder


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    status = main(argv)
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    return status, out, err


# --- 1. emulate: an uncalibrated profile is served; a broken calibration is refused ---------------------


@pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals need a POSIX system")
def test_cli_emulate_serves_an_uncalibrated_profile_at_rest(
    new_head: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    state = tmp_path / "state.json"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "servoface.controller.cli",
            "emulate",
            "--head",
            str(new_head),
            "--state-file",
            str(state),
        ],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None and proc.stderr is not None
        pty = proc.stdout.readline().strip()
        assert pty.startswith("/dev/"), (pty, proc.stderr.read())
        deadline = time.monotonic() + 30
        note = ""
        while time.monotonic() < deadline and "not calibrated" not in note:
            note = proc.stderr.readline()
        assert f"servoface calibrate --head {new_head} --port {pty}" in note, note
        assert "tick 2048" in note
        ids = sorted(a.servo.id for a in load_head(new_head).actuators)
        assert main(["scan", "--port", pty, "--ids", ",".join(map(str, ids))]) == 0  # every servo answers
        found = [line.split() for line in capsys.readouterr().out.splitlines() if line.strip()[:1].isdigit()]
        assert [int(row[0]) for row in found] == ids
    finally:
        proc.terminate()
        _, rest = proc.communicate(timeout=30)
    assert proc.returncode == 0 and "Traceback" not in rest, rest
    servos = json.loads(state.read_text())["servos"]
    assert {s["present_position"] for s in servos.values()} == {2048}


def test_cli_emulate_refuses_a_broken_calibration(broken_head: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, out, err = _run(["emulate", "--head", str(broken_head)], capsys)
    assert status == 2 and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and str(broken_head / "calibration.json") in lines[0] and "not valid JSON" in lines[0], err


# --- 2. say: the expression checked before the head is opened -------------------------------------------


def test_cli_say_refuses_an_unknown_expression_before_opening(capsys: pytest.CaptureFixture[str]) -> None:
    status, out, err = _run(["say", "hello", "--head", "human", "--emulate", "--expression", "hapiness"], capsys)
    assert status == 2
    assert err.startswith("servoface say: unknown expression 'hapiness' (did you mean 'happiness'?); known: ["), err
    assert len(err.strip().splitlines()) == 1 and out == ""


# --- 3. exit codes: bad input is 2 -------------------------------------------------------------------------


def test_cli_demo_unknown_head_is_refused_before_opening(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, _, err = _run(["demo", "--head", "humen", "--out", str(tmp_path / "out")], capsys)
    assert status == 2
    assert "opening head" not in err and not (tmp_path / "out").exists()
    assert "servoface demo: --head humen: expected a built-in head name" in err
    assert "servoface list heads" in err and "servoface check humen" not in err  # (check only repeats it)


def test_cli_check_unknown_head(capsys: pytest.CaptureFixture[str]) -> None:
    status, _, err = _run(["check", "humen"], capsys)
    assert status == 2
    assert "servoface check: humen: expected a built-in head name" in err
    assert "head.toml at that key" not in err and "servoface list heads" in err


def test_cli_preview_with_a_broken_calibration_is_bad_input(
    broken_head: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    status, _, err = _run(["preview", "happiness", "--head", str(broken_head), "-o", str(tmp_path / "b.png")], capsys)
    assert status == 2
    assert str(broken_head / "calibration.json") in err and "not valid JSON" in err
    assert not (tmp_path / "b.png").exists()


def test_cli_scan_bad_baud_and_missing_port(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, _, err = _run(["scan", "--port", str(tmp_path / "P"), "--baud", "12345"], capsys)
    assert status == 2 and "servoface scan: --baud 12345: expected one of" in err
    status, _, err = _run(["scan", "--port", str(tmp_path / "ttyUSB0")], capsys)
    assert status == 2 and "cannot open port" in err and "ttyUSB0" in err


def test_cli_calibrate_missing_csv(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, _, err = _run(
        ["calibrate", "--head", "human", "--csv", str(tmp_path / "nosuch.csv"), "--out", str(tmp_path / "c.json")],
        capsys,
    )
    assert status == 2 and "nosuch.csv: cannot read the measurement file" in err
    assert not (tmp_path / "c.json").exists()


def test_cli_demo_out_is_an_existing_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "happy.png").write_bytes(b"")
    status, _, err = _run(["demo", "--out", str(tmp_path / "happy.png")], capsys)
    assert status == 2 and "--out" in err and "happy.png" in err


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs /proc (Linux) as a folder nothing can be made in")
def test_cli_new_in_a_folder_that_cannot_take_it(capsys: pytest.CaptureFixture[str]) -> None:
    status, _, err = _run(["new", "/proc/servoface-no-such-head"], capsys)
    assert status == 2 and "servoface new: /proc/servoface-no-such-head" in err


# --- 4. hints that lead somewhere ------------------------------------------------------------------------


def test_cli_check_names_a_broken_calibration_file(broken_head: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, out, _ = _run(["check", str(broken_head)], capsys)
    assert status == 1  # the profile loads: check reports its problems
    assert "no calibration yet" not in out
    assert f"calibration file {broken_head / 'calibration.json'} is broken: not valid JSON" in out, out


# --- 5. smaller ones -------------------------------------------------------------------------------------


def test_cli_version(capsys: pytest.CaptureFixture[str]) -> None:
    status, out, _ = _run(["--version"], capsys)
    assert status == 0 and out.strip() == f"servoface {version('servoface')}"


def test_cli_preview_refuses_at_without_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, _, err = _run(
        ["preview", "happiness", "--head", "human", "-o", str(tmp_path / "x.png"), "--at", "3"], capsys
    )
    assert status == 2 and "servoface preview: --at" in err and "--input" in err
    assert not (tmp_path / "x.png").exists()


def test_cli_binary_calibration_file_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    png = tmp_path / "happy.png"
    png.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)))
    status, out, _ = _run(["check", "human", "--calibration", str(png), "--no-report"], capsys)
    assert status == 1 and f"calibration file {png} is broken: not a calibration JSON file" in out, out
    status, _, err = _run(["play", "happiness", "--emulate", "--calibration", str(png)], capsys)
    assert status == 2 and f"{png}: not a calibration JSON file" in err and "utf-8" not in err


def test_cli_check_json_folder_checked_first(capsys: pytest.CaptureFixture[str]) -> None:
    status, out, err = _run(["check", "human", "--json", "/nonexistent-servoface/x.json"], capsys)
    assert status == 2 and "--json" in err and "/nonexistent-servoface" in err
    assert out == ""  # nothing was checked or reported before the refusal


def test_cli_scan_refuses_negative_latency(capsys: pytest.CaptureFixture[str]) -> None:
    status, _, err = _run(["scan", "--port", "P", "--latency-ms", "-3"], capsys)
    assert status == 2 and err.startswith("servoface scan: --latency-ms -3: expected milliseconds"), err


def test_cli_preview_unknown_head_named_once(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, _, err = _run(["preview", "happiness", "--head", "humen", "-o", str(tmp_path / "x.png")], capsys)
    assert status == 2
    first = err.splitlines()[0]
    assert first == (
        "servoface preview: --head humen: expected a built-in head name ['human', 'dog'] or a profile folder "
        "with head.toml (did you mean 'human'?)"
    ), first


def test_cli_check_a_folder_without_head_toml(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    status, _, err = _run(["check", str(tmp_path)], capsys)
    assert status == 2  # nothing there to check (a malformed head.toml is bad input too: 2)
    assert f"servoface new {tmp_path} --from mechanical" in err and "head.toml at that key" not in err


def test_cli_play_refuses_a_script_for_the_other_face_before_opening(capsys: pytest.CaptureFixture[str]) -> None:
    status, _, err = _run(["play", "human_performance", "--head", "dog", "--emulate"], capsys)
    assert status == 2
    assert "opening head" not in err and "stop (" not in err  # refused before the head was opened
    assert "is for a human face; head 'dog' is dog" in err


def test_cli_play_names_an_expression_of_the_other_face(capsys: pytest.CaptureFixture[str]) -> None:
    status, _, err = _run(["play", "smelling", "--head", "human", "--emulate"], capsys)
    assert status == 2
    assert "unknown expression 'smelling' (a dog expression; head 'human' is a human face); known: [" in err


def test_cli_studio_on_a_taken_port_is_refused_before_the_head_opens(capsys: pytest.CaptureFixture[str]) -> None:
    import socket

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        status, out, err = _run(
            ["studio", "--head", "human", "--emulate", "--port-http", str(port), "--no-render"], capsys
        )
    assert status == 2
    assert f"--port-http {port}: cannot listen on 127.0.0.1:{port}" in err and "or 0 for any free one" in err, err
    assert "stop (" not in out + err  # the head was never opened


@pytest.mark.parametrize(
    "argv, flag, expected",
    [
        (["preview", "happiness", "--size", "-5x3"], "--size", "16..4096 px per side, got -5x3"),
        (["scan", "--port", "P", "--latency-ms", "-3.5"], "--latency-ms -3.5", "expected milliseconds"),
        (["play", "human_performance", "--emulate", "--rate", "-.5"], "--rate -0.5", "expected a control rate"),
    ],
)
def test_cli_a_value_that_starts_with_a_dash_reaches_its_options_check(
    argv: list[str], flag: str, expected: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """argparse took ``-5x3`` (not a plain negative number) for another option and said only "expected one
    argument"; the value now reaches the option's own check, whose message names the flag and the range."""
    status, _, err = _run([*argv, "-o", str(tmp_path / "x.png")] if argv[0] == "preview" else argv, capsys)
    assert status == 2 and flag in err and expected in err, err
    assert "expected one argument" not in err


def test_cli_play_misspelt_head_names_the_nearest_and_the_next_step(capsys: pytest.CaptureFixture[str]) -> None:
    """As demo and preview: `play --head hman` names 'human' and says where the head names are, before
    anything is opened."""
    status, _, err = _run(["play", "happiness", "--head", "hman", "--emulate"], capsys)
    assert status == 2
    lines = err.splitlines()
    assert lines[0] == (
        "servoface play: --head hman: expected a built-in head name ['human', 'dog'] or a profile folder with "
        "head.toml (did you mean 'human'?)"
    ), lines[0]
    assert "servoface list heads" in lines[1] and "opening head" not in err


def test_cli_output_into_a_closed_pipe_ends_quietly() -> None:
    """`servoface list | head -0`: the reader is gone before anything is written; no "Broken pipe" error or
    traceback, exit 141 (as a tool SIGPIPE ended)."""
    import subprocess
    import sys

    proc = subprocess.Popen(
        [sys.executable, "-m", "servoface.controller.cli", "list"], stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()  # the reader goes away before the listing is written
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == 141, err
    assert "Broken pipe" not in err and "Traceback" not in err and "Exception ignored" not in err, err
