"""Command-line flags: 10^4 generated argv over every sub-command, through the parse-and-validate stage the
CLI itself runs first (`servoface.controller.cli.options.parse_command`, in process, one parser built once).
Whatever the argv: options come back checked, or a usage error exits 2, or a `CommandLineError` (which
`main` prints as one line and turns into exit 2) — never another exception, never a traceback; what reaches
the terminal has its control characters escaped; and nothing is opened (a tripwire on the bus, the emulator
and the serial port: this stage must not touch a head)."""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import re
from collections.abc import Iterator
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from servoface.controller.cli import COMMANDS, build_parser, main
from servoface.controller.cli.options import CommandLineError, parse_command

from tests.fuzz.strategies import fuzz_settings, weird_text

N = int(os.environ.get("SERVOFACE_FUZZ_EXAMPLES", "10000"))
PARSER = build_parser()
_SUB = next(a for a in PARSER._actions if isinstance(a, argparse._SubParsersAction))
SUBPARSERS: dict[str, argparse.ArgumentParser] = dict(_SUB.choices)
# raw control characters a terminal would act on (newline and tab are fine)
RAW_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f\u202a-\u202e\u2066-\u2069]|[\ud800-\udfff]")

NUMBERS = st.sampled_from(
    ["nan", "inf", "-inf", "1e999", "-1e999", "1e308", "-0", "0", "1", "-1", "2", "50", "1000", "1000.0001", "0.0001",
     "57600", "1000000", "4500000", "1234", "9" * 40, "-" + "9" * 40, "1" * 5000, "0x10", "1_000", " 5", "5\n", "",
     "1e-320", "65536", "-65536", "21", "500.5", "3.5e6"]
)  # fmt: skip
TEXT = st.one_of(
    weird_text,
    st.sampled_from(["human", "dog", "/dev/null", "/nonexistent/x", "x.png", "x.mp4", "../../etc/passwd", "-", "--",
                     "-x", "--emulate", "--port", "\x1b[2J\x1b[H", "a\x00b", "\u202eevil", "\ud800", "127.0.0.1:9",
                     "0.0.0.0:0", "[::1]:70000", "1-4", "1:overload", "all", "happiness"])
)  # fmt: skip
VALUE = st.one_of(NUMBERS, TEXT)


@st.composite
def argvs(draw: st.DrawFn) -> list[str]:
    """A sub-command, then options of that sub-command (any order, any values, some repeated, some mangled),
    positionals and stray tokens."""
    name = draw(st.sampled_from(sorted(SUBPARSERS)))
    sub = SUBPARSERS[name]
    actions = [a for a in sub._actions if not isinstance(a, argparse._HelpAction)]
    out = [name]
    for _ in range(draw(st.integers(0, 6))):
        action = draw(st.sampled_from(actions))
        if not action.option_strings:  # a positional
            out.append(draw(VALUE))
            continue
        flag = draw(st.sampled_from(action.option_strings))
        if draw(st.integers(0, 9)) == 0:
            flag = flag[: draw(st.integers(2, max(2, len(flag))))]  # an abbreviation (or an ambiguous one)
        if action.nargs == 0:
            out.append(flag)
        elif action.choices is not None and draw(st.booleans()):
            out += [flag, draw(st.sampled_from([str(c) for c in action.choices]))]
        elif draw(st.integers(0, 4)) == 0:
            out.append(f"{flag}={draw(VALUE)}")
        else:
            out += [flag, draw(NUMBERS if action.type in (int, float) else VALUE)]
    if draw(st.integers(0, 3)) == 0:
        out.insert(draw(st.integers(1, len(out))), draw(TEXT))
    return out


@pytest.fixture(scope="module")
def tripwire() -> Iterator[list[str]]:
    """Anything that would open a bus, an emulated chain or a serial port records itself and fails."""
    from servoface.hardware import dynamixel_bus
    from servoface.hardware.emulator.chain import ServoChain

    opened: list[str] = []

    def trip(what: str) -> Any:
        def refuse(*args: Any, **kw: Any) -> None:
            opened.append(what)
            raise AssertionError(f"the parse stage opened {what}")

        return refuse

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(dynamixel_bus.DynamixelBus, "__init__", trip("a DynamixelBus"))
        mp.setattr(ServoChain, "__init__", trip("an emulated chain"))
        mp.setattr("serial.Serial.__init__", trip("a serial port"), raising=False)
        yield opened


def _parse(argv: list[str]) -> tuple[str, int | None, str]:
    out, err = io.StringIO(), io.StringIO()
    status: int | None = None
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            parse_command(argv, PARSER)
            kind = "ok"
        except SystemExit as exc:
            kind, status = "usage", int(exc.code or 0)
        except CommandLineError as exc:
            kind = "invalid"
            assert str(exc)
            print(str(exc), file=err)  # what main prints (checked for escapes below, like the rest)
    return kind, status, out.getvalue() + err.getvalue()


@fuzz_settings(N)
@given(argvs())
def test_any_argv_is_options_or_a_usage_error(tripwire: list[str], argv: list[str]) -> None:
    kind, status, text = _parse(argv)
    if kind == "usage":
        assert status == 2, (argv, text)
        assert "usage:" in text and "error:" in text, text
    assert "Traceback" not in text
    assert RAW_CONTROL.search(text) is None, repr(text)
    assert tripwire == []


def test_every_sub_command_is_generated() -> None:
    assert set(SUBPARSERS) == {n for n in COMMANDS if n in SUBPARSERS} and len(SUBPARSERS) >= 15


@pytest.mark.parametrize(
    "argv, named",
    [
        (["play", "happiness", "--emulate", "--rate", "nan"], "--rate nan"),
        (["stream", "--emulate", "--stdin", "--duration", "inf"], "--duration inf"),
        (["say", "hi", "--emulate", "--lead-ms", "1e999"], "--lead-ms inf"),
        (["studio", "--head", "human", "--emulate", "--baud", "1234"], "--baud 1234"),
        (["node", "--emulate", "--rate", "1e9"], "--rate"),
        (["bench", "--minutes", "-5"], "--minutes -5"),
        (["calibrate", "--emulate", "--points", "9" * 30], "--points"),
        (["play", "--emulate", "\x1b[2Jhappiness", "\x1b[31mextra"], "\\x1b[31mextra"),
    ],
)
def test_main_says_which_option_and_exits_2(
    tripwire: list[str], argv: list[str], named: str, capsys: pytest.CaptureFixture[str]
) -> None:
    try:
        status = main(argv)
    except SystemExit as exc:  # a usage error: argparse's exit
        status = int(exc.code or 0)
    err = capsys.readouterr().err
    assert status == 2 and named in err, err
    assert RAW_CONTROL.search(err) is None and "Traceback" not in err
    assert tripwire == []
