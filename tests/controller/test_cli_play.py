"""`servoface play` on the emulated chain (in-process) and its argument errors."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from servoface.controller.cli import main


def test_play_expression_on_the_emulator(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    trace = tmp_path / "trace.jsonl"
    status = main(["play", "happiness", "--emulate", "--hold", "0.2", "--trace", str(trace)])
    out, err = capsys.readouterr()
    assert status == 0, out + err
    frames = int(out.split()[0])
    assert frames >= 2 and "verdicts" in out  # (how many depends on the machine's load: frames are skipped)
    lines = [json.loads(line) for line in trace.read_text().splitlines()]
    assert len(lines) == frames
    assert "stop (end): eased to neutral" in out and "on every servo" in out
    assert {line["verdict"] for line in lines} <= {"accept", "clip", "reject"}
    apex = max(lines, key=lambda d: d["aus"].get("AU12", 0.0))
    assert apex["aus"]["AU12"] > 0.5 and len(apex["goals_sent"]) == 30


def test_play_script_on_the_emulator(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    script = tmp_path / "blink.toml"
    script.write_text(
        '[script]\nface = "human"\nend_s = 0.3\n[poses]\nshut = { AU43 = 0.8 }\n'
        '[expressions.shut]\nduration_s = 0.2\nmovements = [{ pose = "shut", percent = 100 }]\n'
        '[[play]]\nat_s = 0.0\nexpression = "shut"\n'
    )
    assert main(["play", str(script), "--emulate"]) == 0
    assert "frames" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, named",
    [
        (["play", "happiness"], "--port"),  # neither --port nor --emulate
        (["play", "happiness", "--emulate", "--port", "/dev/null"], "--port"),
        (["play", "happiness", "--emulate", "--rate", "0"], "--rate"),
        (["play", "happiness", "--emulate", "--rate", "fast"], "--rate"),
        (["play", "happiness", "--emulate", "--hold", "-1"], "--hold"),
        (["play", "glee", "--emulate"], "glee"),
        (["play", "happiness", "--emulate", "--head", "no_such_head"], "no_such_head"),
        (["play", "happiness", "--emulate", "--baud", "1234"], "1234"),
        (["play", "missing.toml", "--emulate"], "missing.toml"),
        (["play", "--emulate"], "what"),
    ],
)
def test_bad_arguments_exit_2_with_a_message(argv: list[str], named: str, capsys: pytest.CaptureFixture[str]) -> None:
    status: int | str | None
    try:
        status = main(argv)
    except SystemExit as exc:  # argparse's own errors
        status = exc.code
    err = capsys.readouterr().err
    assert status == 2, err
    assert named in err, err
    assert "Traceback" not in err


def test_bench_unknown_suite_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "nosuch"]) == 2
    assert "nosuch" in capsys.readouterr().err


def test_a_typo_is_reported_before_the_port_is_opened(capsys: pytest.CaptureFixture[str]) -> None:
    # the port does not exist: the error must be about the expression, found before touching any port
    assert main(["play", "glee", "--port", "/dev/does-not-exist"]) == 2
    err = capsys.readouterr().err
    assert "glee" in err and "does-not-exist" not in err


def test_bench_rows_say_what_ratio_means_and_end_with_a_count(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A two-figure suite (a module of this test, registered as a suite): the text ends with the verdict
    count; --json lines carry their suite."""
    import json
    import sys
    import types

    from servoface.controller import benchmarks
    from servoface.controller.benchmarks.figure import Figure

    suite = types.ModuleType("tests_two_figures")
    suite.run = lambda quick=False: iter(  # type: ignore[attr-defined]
        [Figure("fast", 2.0, "ms", limit=1.0, better="lower"), Figure("wide", 0.95, "x", limit=1.0, goal_ratio=0.9)]
    )
    monkeypatch.setitem(sys.modules, "tests_two_figures", suite)
    monkeypatch.setitem(benchmarks.SUITES, "two", "tests_two_figures")
    assert main(["bench", "two"]) == 0  # a short figure does not fail the run
    out = capsys.readouterr().out
    assert "# ratio: how many times better than the limit" in out
    assert out.strip().splitlines()[-1].startswith("# 2 figures: 1 meet their goal, 1 short, 0 without a goal")
    assert main(["bench", "two", "--json"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [r["suite"] for r in rows] == ["two", "two"] and [r["verdict"] for r in rows] == ["short", "meets"]
