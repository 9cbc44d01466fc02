"""The command line's numeric ranges live in one table (`options.RANGES`), checked at the parse seam
(`options.parse_command`) for every sub-command that has the option: each end of each range refused or taken
as written there, the message naming the flag as that command spells it and what was expected; and no
sub-command's ``run`` checks them again."""

from __future__ import annotations

import argparse
import ast
from pathlib import Path

import pytest
from servoface.controller.cli import build_parser, main
from servoface.controller.cli.options import RANGES, CommandLineError, option_flags, parse_command

PARSER = build_parser()
_SUB = next(a for a in PARSER._actions if isinstance(a, argparse._SubParsersAction))
CLI = Path(__file__).resolve().parents[2] / "controller" / "cli"

# what each sub-command needs besides the option under test to get past argparse
BASE: dict[str, list[str]] = {
    "play": ["happiness", "--emulate"],
    "stream": ["--emulate", "--stdin"],
    "say": ["hi", "--emulate"],
    "lipsync": ["take.wav"],
    "studio": ["--emulate", "--head", "human"],
    "node": ["--emulate", "--name", "n1"],
    "demo": [],
    "scan": ["--port", "/dev/null"],
    "bench": [],
    "preview": ["joy", "-o", "x.png"],
    "calibrate": ["--emulate"],
}


def _cases() -> list[tuple[str, str, str, float, bool]]:
    """(command, dest, flag, value, accepted) at and just beyond each end of each range."""
    cases = []
    for command, sub in sorted(_SUB.choices.items()):
        for action in sub._actions:
            if action.dest not in RANGES or not action.option_strings:
                continue
            r = RANGES[action.dest]
            flag = max(action.option_strings, key=len)
            step = 1.0 if action.type is int else 1e-3
            hi = min(r.hi, 1e9)
            ends = ((r.lo, r.lo_in), (r.lo - step, False), (hi, r.hi_in or hi < r.hi), (hi + step, hi < r.hi))
            cases += [(command, action.dest, flag, value, ok) for value, ok in ends]
    return cases


CASES = _cases()


def test_every_range_is_reached_by_some_command() -> None:
    assert {dest for _, dest, _, _, _ in CASES} == set(RANGES)
    assert ("play", "input_fps", "--fps") in {c[:3] for c in CASES}
    assert ("preview", "input_fps", "--input-fps") in {c[:3] for c in CASES}


@pytest.mark.parametrize(("command", "dest", "flag", "value", "accepted"), CASES)
def test_each_end_of_each_range_at_the_parse_seam(
    command: str, dest: str, flag: str, value: float, accepted: bool
) -> None:
    sub = _SUB.choices[command]
    action = next(a for a in sub._actions if a.dest == dest)
    shown = str(int(value)) if action.type is int else repr(value)
    argv = [command, *BASE.get(command, []), flag, shown]
    if accepted:
        args = parse_command(argv, PARSER)
        assert getattr(args, dest) == pytest.approx(value)
        return
    with pytest.raises(CommandLineError) as err:
        parse_command(argv, PARSER)
    message = str(err.value)
    assert message.startswith(f"{flag} "), message  # the flag as this command spells it
    assert "expected" in message and RANGES[dest].what in message, message


def test_main_prints_one_line_naming_the_command_and_the_flag(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["play", "--input", "x.csv", "--emulate", "--fps", "0"]) == 2
    err = capsys.readouterr().err
    assert err.strip() == "servoface play: --fps 0: expected frames per second in (0, 10000]", err
    assert main(["studio", "--head", "human", "--emulate", "--port-http", "70000"]) == 2
    assert "servoface studio: --port-http 70000: expected a TCP port (0: any free one) in [0, 65535]" in (
        capsys.readouterr().err
    )


def test_option_flags_name_each_dest_by_its_long_flag() -> None:
    assert option_flags(PARSER, "play")["input_fps"] == "--fps"
    assert option_flags(PARSER, "preview")["input_fps"] == "--input-fps"
    assert option_flags(PARSER, "preview")["output"] == "--output"


def test_no_run_function_checks_a_range_again() -> None:
    """One source of truth: an order comparison (< <= > >=) on ``args.<an option of RANGES>`` anywhere in the
    CLI package but options.py is a second copy of a range."""
    copies = []
    for path in sorted(CLI.glob("*.py")):
        if path.name == "options.py":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.Compare) or not any(
                isinstance(op, ast.Lt | ast.LtE | ast.Gt | ast.GtE) for op in node.ops
            ):
                continue
            for side in (node.left, *node.comparators):
                if (
                    isinstance(side, ast.Attribute)
                    and isinstance(side.value, ast.Name)
                    and side.value.id == "args"
                    and side.attr in RANGES
                ):
                    copies.append(f"{path.name}:{node.lineno}: args.{side.attr}")
    assert copies == [], copies
