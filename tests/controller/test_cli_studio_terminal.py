"""`servoface studio` shows what came from outside (a calibration file's name, a folder, a host)
with control characters escaped, as the other commands do (`cli.terminal.printable`): an escape sequence in
a file name cannot repaint the operator's terminal. Each refusal is one line, exit 2, before anything opens."""

from __future__ import annotations

from pathlib import Path

import pytest
from servoface.controller.cli import main

ESC = "\x1b[31m"


def _studio(capsys: pytest.CaptureFixture[str], *extra: str) -> tuple[int, str, str]:
    status = main(["studio", "--head", "human", "--emulate", "--no-render", "--port-http", "0", *extra])
    out, err = capsys.readouterr()
    return status, out, err


def _escaped_refusal(status: int, out: str, err: str, *expected: str) -> None:
    assert status == 2, out + err
    assert out == "", out  # nothing served, no closing report: the head was never opened
    assert "\x1b" not in err, repr(err)
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("servoface studio: "), err
    for part in expected:
        assert part in lines[0], lines[0]


@pytest.mark.parametrize("kind", ["missing", "malformed"])
def test_a_calibration_path_with_an_escape_is_shown_escaped(
    kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / f"cal{ESC}red.json"
    if kind == "malformed":
        path.write_text('{"schema_version": 1, "servos": \n')
    expected = "cannot read the calibration file" if kind == "missing" else "not valid JSON"
    status, out, err = _studio(capsys, "--calibration", str(path))
    _escaped_refusal(status, out, err, "cal\\x1b[31mred.json", expected)


def test_an_out_dir_with_an_escape_is_shown_escaped(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / f"nowhere{ESC}"
    status, out, err = _studio(capsys, "--out-dir", str(folder))
    _escaped_refusal(status, out, err, "--out-dir", "nowhere\\x1b[31m", "not a folder")


def test_a_host_with_an_escape_is_shown_escaped(capsys: pytest.CaptureFixture[str]) -> None:
    status, out, err = _studio(capsys, "--host", f"{ESC}example.org")
    _escaped_refusal(status, out, err, "--host \\x1b[31mexample.org", "--allow-remote")


def test_a_head_folder_with_an_escape_is_shown_escaped(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / f"my{ESC}head"
    folder.mkdir()  # a folder without head.toml
    status, _, err = main(["studio", "--head", str(folder), "--emulate", "--no-render"]), "", capsys.readouterr()[1]
    assert status == 2 and "\x1b" not in err and "my\\x1b[31mhead" in err, repr(err)
    assert len(err.splitlines()) == 1, err


def test_a_calibration_of_another_head_names_its_file(capsys: pytest.CaptureFixture[str]) -> None:
    """As play, say and stream (`head_args.checked_calibration`): the file, whose head it is, and where to
    look — before the head is opened."""
    from servoface.sim.heads import load_head

    dog_file = load_head("dog").calibration_path
    assert dog_file is not None
    status, out, err = _studio(capsys, "--calibration", str(dog_file))
    _escaped_refusal(status, out, err, str(dog_file), "it is a calibration of head 'dog'", "servoface check human")
