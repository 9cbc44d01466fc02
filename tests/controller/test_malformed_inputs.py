"""Malformed input found by exploratory testing from the outside, each refused by the real command line
(`servoface play --input`, `play SCRIPT`, `stream --stdin`) with exit 2, one message naming the file, line,
column or field and what was expected, no traceback, and nothing opened: a tripwire fails if a bus, an
emulated chain or a serial port is made. (Before the fixes: a ZeroDivisionError or OverflowError traceback,
a crash after torque-on, a recording written with ``Infinity``, a 512 MiB+ device read into memory.)"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from servoface.controller.cli import main
from servoface.controller.inputs import InputError, load_recording
from servoface.controller.inputs.csv_table import read_text

OF_HEAD = "frame, face_id, timestamp, confidence, success, AU12_r"
FAP_MASK = " ".join(["0"] * 2 + ["1"] + ["0"] * 65)  # FAP 3 (open_jaw) only


@pytest.fixture
def tripwire(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[str]]:
    """Anything that would open a bus, an emulated chain or a serial port records itself and fails."""
    from servoface.hardware import dynamixel_bus
    from servoface.hardware.emulator.chain import ServoChain

    opened: list[str] = []

    def trip(what: str) -> Any:
        def refuse(*args: Any, **kw: Any) -> None:
            opened.append(what)
            raise AssertionError(f"bad input opened {what}")

        return refuse

    monkeypatch.setattr(dynamixel_bus.DynamixelBus, "__init__", trip("a DynamixelBus"))
    monkeypatch.setattr(ServoChain, "__init__", trip("an emulated chain"))
    monkeypatch.setattr("serial.Serial.__init__", trip("a serial port"), raising=False)
    yield opened


def _refused(argv: list[str], capsys: pytest.CaptureFixture[str], tripwire: list[str]) -> str:
    status = main(argv)
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err and "internal error" not in err, err
    assert status == 2, (status, out, err)
    assert tripwire == []
    return err


def _fap(fps: str, n_frames: str, frames: int = 4) -> str:
    body = "".join(f"{FAP_MASK}\n{k} {100 * k}\n" for k in range(frames))
    return f"2.1 take {fps} {n_frames}\n{body}"


CASES = [
    # sub-normal timestamp steps: 1 / (step * 1e-3) divided by zero while picking the unit
    (
        "subnormal.csv",
        OF_HEAD + "\n" + "".join(f"{k + 1}, 0, {k * 5e-324!r}, 0.9, 1, {k % 3}\n" for k in range(6)),
        None,
    ),
    # a frame count of 1e400 in a FAP header: int(inf)
    ("count.fap", _fap("25", "1e400"), "line 1: expected '<version> <name> <fps> <n_frames>'"),
    # a header frame rate so small that the frames' times overflow to inf
    ("tiny_fps.fap", _fap("1e-308", "4"), "column 'frame': "),
    # times 2e308 apart: finite, but not measured from the first row
    ("apart.jsonl", '{"t": -1e308, "aus": {"AU12": 0.5}}\n' + '{"t": 1e308, "aus": {"AU12": 0.6}}\n' * 2, "line 2"),
    # a take whose time jumps by 1e308 s: played for ever (and crashed play on the frame count)
    ("endless.jsonl", '{"t": 0, "aus": {"AU12": 0.5}}\n' + '{"t": 1e308, "aus": {"AU12": 0.6}}\n' * 2, "1e+308 s"),
    # every row bad: the refusal names the first bad field, not only a count
    ("unknown_au.jsonl", '{"t": 0, "aus": {"AU99": 0.5}}\n', "line 1.aus.AU99"),
    ("text_time.csv", "t,jawOpen\nabc,0.5\ndef,0.5\n", "line 2, column 't'"),
]


@pytest.mark.parametrize(("name", "text", "named"), CASES, ids=[c[0] for c in CASES])
def test_play_input_refuses_a_malformed_tracker_file_before_opening(
    name: str, text: str, named: str | None, tmp_path: Path, capsys: pytest.CaptureFixture[str], tripwire: list[str]
) -> None:
    path = tmp_path / name
    path.write_text(text)
    if named is None:  # readable after all (rows timed at the reader's fps): loads, with a finite length
        rec = load_recording(path)
        assert rec.duration_s == pytest.approx(5 / 30) and "rows timed at 30 fps" in rec.report.time
        return
    err = _refused(["play", "--input", str(path), "--head", "human", "--emulate"], capsys, tripwire)
    assert str(path) in err and named in err, err
    assert err.count("\n") == 1, err


def test_a_device_or_a_file_too_large_is_refused_without_reading_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], tripwire: list[str]
) -> None:
    if not Path("/dev/zero").exists():
        pytest.skip("needs /dev/zero (a POSIX system)")
    err = _refused(["play", "--input", "/dev/zero", "--head", "human", "--emulate"], capsys, tripwire)
    assert "/dev/zero: a device, not a regular file, a pipe or a terminal; expected a tracker recording" in err
    sparse = tmp_path / "take.csv"
    with sparse.open("wb") as fh:  # 2 GB declared, no blocks written
        fh.truncate(2 * 1024**3)
    err = _refused(["play", "--input", str(sparse), "--head", "human", "--emulate"], capsys, tripwire)
    assert f"{sparse}: 2 GiB; a tracker recording is at most 512 MiB" in err
    small = tmp_path / "small.csv"
    small.write_text("x" * 2000)
    with pytest.raises(InputError, match="small.csv: 2000 bytes; a shape ranges file is at most 1 KiB"):
        read_text(small, max_bytes=1024, what="a shape ranges file")


def test_stream_refuses_a_token_file_or_shape_ranges_that_never_end(
    capsys: pytest.CaptureFixture[str], tripwire: list[str]
) -> None:
    if not Path("/dev/zero").exists():
        pytest.skip("needs /dev/zero (a POSIX system)")
    base = ["stream", "--stdin", "--head", "human", "--emulate"]
    err = _refused([*base, "--token-file", "/dev/zero"], capsys, tripwire)
    assert "--token-file /dev/zero: its first line is longer than 4096 bytes" in err
    err = _refused([*base, "--shape-ranges", "/dev/zero"], capsys, tripwire)
    assert "/dev/zero: cannot read shape ranges: a device, not a regular file, a pipe or a terminal" in err


SCRIPT = "[script]\nface = 'human'\n[poses]\nsmile = { AU12 = 0.5 }\n"
SCRIPTS = [
    ("say_far.toml", SCRIPT + "[[play]]\nat_s = 1e308\nsay = 'hi'\n", "play[0].at_s"),
    (
        "long_expression.toml",
        SCRIPT + "[expressions.s]\nduration_s = 1e300\nmovements = [{ pose = 'smile', percent = 100 }]\n"
        "[[play]]\nat_s = 0\nexpression = 's'\n",
        "expressions.s.duration_s",
    ),
    (
        "keyframe_far.toml",
        SCRIPT + "[expressions.k]\nkeyframes = [{ t_s = 0, pose = 'smile' }, { t_s = 1e308, pose = 'smile' }]\n"
        "[[play]]\nat_s = 0\nexpression = 'k'\n",
        "expressions.k.keyframes[1].t_s",
    ),
    ("gaze_far.toml", SCRIPT + "[[gaze]]\nat_s = 1e308\nahead = true\n", "gaze[0].at_s"),
    (
        "runs_past_a_day.toml",
        SCRIPT + "[expressions.s]\nduration_s = 80000\nmovements = [{ pose = 'smile', percent = 100 }]\n"
        "[[play]]\nat_s = 80000\nexpression = 's'\n",
        "script.end_s: the play and gaze entries run to 160000 s",
    ),
]


@pytest.mark.parametrize(("name", "text", "named"), SCRIPTS, ids=[s[0] for s in SCRIPTS])
def test_play_refuses_script_times_beyond_a_day_before_opening(
    name: str, text: str, named: str, tmp_path: Path, capsys: pytest.CaptureFixture[str], tripwire: list[str]
) -> None:
    """Before: loaded (only end_s was bounded), then `int(inf)` or a 5e13-frame subscription crashed the run
    after torque-on (exit 1, "internal error OverflowError")."""
    path = tmp_path / name
    path.write_text(text)
    err = _refused(["play", str(path), "--head", "human", "--emulate"], capsys, tripwire)
    assert named in err and "86400" in err, err


@pytest.mark.skipif(sys.platform == "win32", reason="a POSIX pipe on stdin")
def test_stream_record_of_far_apart_times_replays(tmp_path: Path) -> None:
    """`servoface stream --stdin --record` (a real process, the emulated head) fed times 2e308 apart wrote
    ``"t": Infinity`` (not JSON; `play --input` refused its own recording). Now every line is JSON and the
    recording replays."""
    rec = tmp_path / "rec.jsonl"
    lines = [
        {"t": -1e308, "aus": {"AU12": 0.5}},
        {"t": 1e308, "aus": {"AU12": 0.7}},
        {"t": 1e308, "aus": {"AU12": 0.2}},
        {"aus": {"AU12": 0.3}},
    ]
    cmd = [sys.executable, "-m", "servoface.controller.cli", "stream", "--stdin", "--head", "human", "--emulate"]
    proc = subprocess.run(
        [*cmd, "--record", str(rec)],
        input="".join(json.dumps(m) + "\n" for m in lines),
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stdout + proc.stderr and "4 messages recorded" in proc.stdout
    written = rec.read_text().splitlines()
    assert len(written) == 4 and not any("Infinity" in line or "NaN" in line for line in written)
    times = [json.loads(line)["t"] for line in written]  # strict JSON
    assert times == sorted(times) and times[-1] < 3600.0
    replay = load_recording(rec)
    assert len(replay) == 4 and [f.get("AU12") for f in replay.frames] == [0.5, 0.7, 0.2, 0.3]


def test_a_call_longer_than_the_subscription_cap_runs() -> None:
    """A valid script or take of more than ~5.5 h (end_s up to a day is allowed) asked the service for a
    queue of one trace per frame of its length: over the cap of 10^6 the call failed after torque-on with
    `subscribe: maxlen must be an integer 1..1000000`. The queue is capped now (the newest frames kept)."""
    from servoface.controller.face import Face

    with Face.open("human", emulate=True) as face:
        move = lambda svc: svc.set_aus({"AU12": 0.3}, track="face", transition_s=0.2)  # noqa: E731
        perf = face._perform(move, 30_000.0)  # noqa: SLF001 - the seam every long play and take goes through
        assert perf.traces and perf.traces[-1].aus.get("AU12") == pytest.approx(0.3)  # it ran, frames kept


# --- user-named files read whole: a device, a FIFO, a directory or a huge file is refused unread -------------

LIMIT = 16 * 2**20  # TEXT_LIMIT_BYTES: scripts, profiles, tables, libraries, calibration JSON, CSV, transcripts


def _sparse(path: Path, size: int) -> Path:
    """A file of ``size`` bytes that takes no disk (its length declared, no blocks written)."""
    with path.open("wb") as fh:
        fh.truncate(size)
    return path


@contextmanager
def _fifo(path: Path) -> Iterator[Path]:
    """A FIFO nobody writes to. The old code blocked opening it for ever: after 5 s a writer comes and goes,
    so a reader that waited sees an empty file (a failed assertion) instead of hanging the test run."""
    os.mkfifo(path)
    done = threading.Event()

    def writer() -> None:
        if done.wait(5.0):
            return
        while not done.is_set():
            try:
                os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))
            except OSError:  # ENXIO: no reader (yet)
                time.sleep(0.05)

    thread = threading.Thread(target=writer, daemon=True)
    thread.start()
    try:
        yield path
    finally:
        done.set()
        thread.join()


@pytest.mark.skipif(not hasattr(os, "mkfifo") or not Path("/dev/zero").exists(), reason="POSIX devices and FIFOs")
def test_play_refuses_a_script_that_is_a_device_a_fifo_a_folder_or_too_large(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], tripwire: list[str]
) -> None:
    """Before: `play zero.toml` (a symlink to /dev/zero) read until memory ran out, a FIFO hung for ever, a
    3 GiB file was read whole; a folder named x.toml was an OSError."""
    zero = tmp_path / "zero.toml"
    zero.symlink_to("/dev/zero")
    folder = tmp_path / "folder.toml"
    folder.mkdir()
    huge = _sparse(tmp_path / "huge.toml", 3 * 2**30)
    over = _sparse(tmp_path / "over.toml", LIMIT + 1)
    with _fifo(tmp_path / "fifo.toml") as fifo:
        expected = [
            (zero, "a device, not a regular file; expected a script file"),
            (folder, "a directory, not a regular file; expected a script file"),
            (fifo, "a pipe (FIFO), not a regular file; expected a script file"),
            (huge, "3 GiB; a script file is at most 16 MiB"),
            (over, f"{LIMIT + 1} bytes; a script file is at most 16 MiB"),
        ]
        for path, message in expected:
            err = _refused(["play", str(path), "--head", "human", "--emulate"], capsys, tripwire)
            assert f"{path}: {message}" in err, err
            assert err.count("\n") == 1, err


def test_a_head_profile_or_its_expression_library_over_the_limit_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], tripwire: list[str]
) -> None:
    """Before: head.toml and the library it names were read whole, however large."""
    from tests.integration import own_heads as oh

    folder = tmp_path / "big_head"
    folder.mkdir()
    _sparse(folder / "head.toml", LIMIT + 1)
    err = _refused(["play", "happiness", "--head", str(folder), "--emulate"], capsys, tripwire)
    assert f"head.toml: {LIMIT + 1} bytes; a head profile is at most 16 MiB" in err, err

    head = oh.write_mechanical(tmp_path / "mech")
    text = (head / "head.toml").read_text()
    (head / "head.toml").write_text(
        text.replace('au_direct = "direct.toml"', 'au_direct = "direct.toml"\nexpressions = "lib.toml"')
    )
    _sparse(head / "lib.toml", 2 * 2**30)
    err = _refused(["play", "happiness", "--head", str(head), "--emulate"], capsys, tripwire)
    assert f"{head / 'lib.toml'}: 2 GiB; an expression library is at most 16 MiB" in err, err


@pytest.mark.parametrize(("key", "what"), [("au_table", "an AU table"), ("au_direct", "a direct AU table")])
def test_check_refuses_an_own_au_table_over_the_limit(
    key: str, what: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: an own AU table or direct table was read whole, however large (`check` reads both)."""
    from tests.integration import own_heads as oh

    head = oh.write_mechanical(tmp_path / "mech")
    text = (head / "head.toml").read_text()
    if key == "au_table":
        text = text.replace('au_direct = "direct.toml"', 'au_direct = "direct.toml"\nau_table = "big.toml"')
    else:
        text = text.replace('au_direct = "direct.toml"', 'au_direct = "big.toml"')
    (head / "head.toml").write_text(text)
    _sparse(head / "big.toml", LIMIT + 1)
    status = main(["check", str(head)])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err and status in (1, 2), (status, out, err)
    assert f"big.toml: {LIMIT + 1} bytes; {what} is at most 16 MiB" in out + err, out + err


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero (a POSIX system)")
def test_a_calibration_or_measurement_file_that_never_ends_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: `--calibration /dev/zero` and `calibrate --csv /dev/zero` read until memory ran out."""
    for argv, message in [
        (["play", "happiness", "--head", "human", "--emulate", "--calibration", "/dev/zero"], "/dev/zero: a device"),
        (
            [
                "play",
                "happiness",
                "--head",
                "human",
                "--emulate",
                "--calibration",
                str(_sparse(tmp_path / "c.json", LIMIT + 1)),
            ],
            f"c.json: {LIMIT + 1} bytes; a calibration file is at most 16 MiB",
        ),
        (
            ["calibrate", "--head", "human", "--csv", "/dev/zero", "--out", str(tmp_path / "cal.json")],
            "/dev/zero: a device",
        ),
        (
            [
                "calibrate",
                "--head",
                "human",
                "--csv",
                str(_sparse(tmp_path / "m.csv", 2**30)),
                "--out",
                str(tmp_path / "cal.json"),
            ],
            "m.csv: 1 GiB; a measurement CSV is at most 16 MiB",
        ),
    ]:
        status = main(argv)
        out, err = capsys.readouterr()
        assert status == 2 and "Traceback" not in out + err, (status, out, err)
        assert message in err, err
    assert not (tmp_path / "cal.json").exists()


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero (a POSIX system)")
def test_lipsync_refuses_a_transcript_that_never_ends_or_is_a_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: `lipsync --transcript /dev/zero` read until memory ran out (later: 16 MiB of zeros). A stream
    is still taken (`--transcript <(...)`), up to 16 MiB; a device that is not a terminal is refused."""
    base = ["lipsync", str(tmp_path / "speech.wav"), "--head", "human", "--out", str(tmp_path / "out")]
    for path, message in [
        (
            "/dev/zero",
            "--transcript '/dev/zero': a device, not a regular file, a pipe or a terminal; expected a transcript",
        ),
        (str(tmp_path), f"--transcript {str(tmp_path)!r}: a directory, not a regular file; expected a transcript"),
    ]:
        status = main([*base, "--transcript", path])
        out, err = capsys.readouterr()
        assert status == 2 and "Traceback" not in out + err, (status, out, err)
        assert message in err, err


@pytest.mark.skipif(not hasattr(os, "mkfifo") or not Path("/dev/zero").exists(), reason="POSIX devices and FIFOs")
def test_node_refuses_a_users_file_or_tls_file_that_is_a_device_a_fifo_or_too_large(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], tripwire: list[str]
) -> None:
    """Before: `node --users-file /dev/zero` read until memory ran out and a FIFO hung the node before it
    listened; a TLS file of any size was read whole."""
    users = tmp_path / "users.txt"
    users.write_text("alice:pw\n")
    big = _sparse(tmp_path / "big.pem", 2 * 2**20)
    base = ["node", "--name", "t1", "--emulate", "--duration", "1"]
    tls = ["--listen", "tls/127.0.0.1:7447", "--users-file", str(users), "--tls-cert", str(big), "--tls-key", str(big)]
    with _fifo(tmp_path / "fifo.pem") as fifo:
        for argv, message in [
            (
                [*base, "--users-file", "/dev/zero"],
                "users file /dev/zero: a device, not a regular file; expected a users file",
            ),
            ([*base, "--users-file", str(big)], f"users file {big}: 2 MiB; a users file is at most 1 MiB"),
            (
                [*base, *tls, "--tls-ca", str(fifo)],
                f"--tls-ca {fifo}: a pipe (FIFO), not a regular file; expected a PEM certificate file",
            ),
            ([*base, *tls, "--tls-ca", str(big)], f"--tls-ca {big}: 2 MiB; a PEM certificate file is at most 1 MiB"),
        ]:
            err = _refused(argv, capsys, tripwire)
            assert message in err, err


def test_a_script_naming_a_library_expression_says_how_to_play_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], tripwire: list[str]
) -> None:
    """Before: `expression = "happiness"` in a script with no expressions said only `expected one of: none
    defined`, though happiness is a library expression, played with `library = "happiness"`."""
    head = "[script]\nface = 'human'\n[[play]]\nat_s = 0\n"
    for name, body, hint in [
        ("expr.toml", "expression = 'happiness'\n", "write library = 'happiness' instead of expression = 'happiness'"),
        ("seq.toml", "sequence = ['happiness']\n", "define it first: [expressions.happiness] library = 'happiness'"),
    ]:
        path = tmp_path / name
        path.write_text(head + body)
        err = _refused(["play", str(path), "--head", "human", "--emulate"], capsys, tripwire)
        assert "unknown expression 'happiness'; expected one of: none defined" in err, err
        assert f"('happiness' is in the human expression library: {hint})" in err, err
    path = tmp_path / "typo.toml"
    path.write_text(head + "expression = 'smirk'\n")
    err = _refused(["play", str(path), "--head", "human", "--emulate"], capsys, tripwire)
    assert err.rstrip().endswith("expected one of: none defined"), err
