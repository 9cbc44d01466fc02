"""The command line's parse-and-validate stage: argv -> checked options, before anything is opened.

`parse_command` is what `servoface.controller.cli.main` runs first: argparse (a usage error exits 2 with the
usage line and the message, control characters escaped), then `check_options` — every number finite and of
a sane size, every option in :data:`RANGES` within its range — raising `CommandLineError` (exit 2, one line
naming the flag as typed on the command line, the value and what was expected). :data:`RANGES` is the one
place a numeric option's range is written: the sub-commands' ``run`` functions do not check them again.
Nothing here opens a port, an emulator, a file or a window; the sub-commands' own checks of what only they
know (a script's contents, a head profile, a file's suffix) follow in ``run``.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NoReturn

from servoface.controller.cli.terminal import printable
from servoface.controller.errors import ControllerError

if TYPE_CHECKING:
    from _typeshed import SupportsWrite

MAX_INT = 2**53  # no option counts anything near this; beyond it an int is a typo or an attack
MAX_FLOAT = 1e12  # seconds, Hz, mm, ms: nothing servoface takes is this large


@dataclass(frozen=True)
class Range:
    """Where an option's value must lie: ``lo``..``hi``, each end included or not; ``what`` the value is."""

    lo: float
    hi: float
    lo_in: bool
    hi_in: bool
    what: str

    def contains(self, value: float) -> bool:
        lo_ok = self.lo <= value if self.lo_in else self.lo < value
        return lo_ok and (value <= self.hi if self.hi_in else value < self.hi)

    def expected(self) -> str:
        def show(x: float) -> str:
            return str(int(x)) if float(x).is_integer() else str(x)

        interval = f"{'[' if self.lo_in else '('}{show(self.lo)}, {show(self.hi)}{']' if self.hi_in else ')'}"
        return f"{self.what} in {interval}"


# option (argparse dest) -> its range, for every command that has it: the only place these are checked
RANGES: dict[str, Range] = {
    "rate": Range(0.0, 1000.0, False, True, "a control rate in Hz"),
    "duration": Range(0.0, 1e7, False, False, "a positive number of seconds"),
    "hold": Range(0.0, 1e6, True, True, "seconds"),
    "lead_ms": Range(0.0, 500.0, True, True, "milliseconds"),
    "port_http": Range(0.0, 65535.0, True, True, "a TCP port (0: any free one)"),
    "retries": Range(0.0, 20.0, True, True, "a number of retries"),
    "minutes": Range(0.0, 1e5, False, True, "minutes"),
    "min_confidence": Range(0.0, 1.0, True, True, "a tracker confidence"),
    "rest_s": Range(0.0, 1e4, True, False, "seconds"),
    "input_fps": Range(0.0, 1e4, False, True, "frames per second"),
    "face_id": Range(0.0, MAX_INT, True, True, "a face index (0: the first)"),
    "columns": Range(1.0, 1e4, True, True, "a number of columns"),
    "latency_ms": Range(0.0, 1000.0, True, True, "milliseconds"),
}
SDK_BAUD_COMMANDS = frozenset({"play", "stream", "say", "studio", "node", "calibrate", "demo", "scan"})


class CommandLineError(ControllerError):
    """An option's value is out of range or not a usable number (exit status 2)."""


class CheckedParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose usage errors show what the user typed with control characters escaped
    (argparse echoes unrecognised arguments as they are: an ANSI escape would reach the terminal)."""

    def error(self, message: str) -> NoReturn:
        self.print_usage(sys.stderr)
        self.exit(2, f"{self.prog}: error: {printable(message)}\n")

    def _print_message(self, message: str, file: SupportsWrite[str] | None = None) -> None:
        if message:
            super()._print_message(printable(message), file)


def check_options(args: argparse.Namespace, flags: Mapping[str, str] | None = None) -> None:
    """Every number finite and sane, every option of :data:`RANGES` in range; else `CommandLineError` naming
    it (``flags``: dest -> the flag as the command spells it; default ``--`` + the dest)."""
    flags = flags or {}
    for dest, value in sorted(vars(args).items()):
        if dest.startswith("_") or isinstance(value, bool):
            continue
        values = value if isinstance(value, list) else [value]
        for v in values:
            _check_number(flags.get(dest) or "--" + dest.replace("_", "-"), dest, v)
    command = getattr(args, "command", None)
    baud = getattr(args, "baud", None)
    if command in SDK_BAUD_COMMANDS and isinstance(baud, int):
        from servoface.hardware.dynamixel_bus import SDK_BAUDS

        if baud not in SDK_BAUDS:
            raise CommandLineError(f"--baud {baud}: expected one of {list(SDK_BAUDS)} bps")


def _check_number(flag: str, dest: str, v: Any) -> None:
    if isinstance(v, float):
        if not math.isfinite(v) or abs(v) > MAX_FLOAT:
            raise CommandLineError(f"{flag} {v}: expected a finite number (at most {MAX_FLOAT:g} in size)")
    elif isinstance(v, int):
        if abs(v) > MAX_INT:
            raise CommandLineError(
                f"{flag}: expected an integer of at most {MAX_INT} in size, got one of {len(str(abs(v)))} digits"
            )
    else:
        return
    limits = RANGES.get(dest)
    if limits is not None and not limits.contains(float(v)):
        raise CommandLineError(f"{flag} {v:g}: expected {limits.expected()}")


def option_flags(parser: argparse.ArgumentParser, command: str | None) -> dict[str, str]:
    """dest -> the long flag of each option of sub-command ``command`` (e.g. ``input_fps`` -> ``--fps``)."""
    subparsers = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]  # noqa: SLF001
    sub = subparsers[0].choices.get(command) if subparsers and command else None
    flags: dict[str, str] = {}
    for action in (sub or parser)._actions:  # noqa: SLF001 - argparse keeps its actions there
        if action.option_strings:
            flags[action.dest] = max(action.option_strings, key=len)
    return flags


def join_dash_values(argv: Sequence[str], parser: argparse.ArgumentParser) -> list[str]:
    """``--size -5x3`` as ``--size=-5x3``: argparse takes a value that starts with ``-`` and is not a plain
    negative number (``-5x3``, ``-1e3``, ``-0.5s``) for another option and says only "expected one argument";
    joined, the value reaches the option's own check, whose message names the flag and what it expects. Only
    for an option of the sub-command that takes one value, and a value that is a dash and a digit or dot."""
    subparsers = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]  # noqa: SLF001
    command = next((a for a in argv if subparsers and a in subparsers[0].choices), None)
    sub = subparsers[0].choices[command] if command is not None else parser
    takes_one = {
        flag
        for action in sub._actions  # noqa: SLF001 - argparse keeps its actions there
        if action.option_strings and action.nargs is None and not isinstance(action, argparse._StoreConstAction)  # noqa: SLF001
        for flag in action.option_strings
    }
    out: list[str] = []
    tokens = list(argv)
    k = 0
    while k < len(tokens):
        token = tokens[k]
        value = tokens[k + 1] if k + 1 < len(tokens) else ""
        if token in takes_one and len(value) > 1 and value[0] == "-" and (value[1].isdigit() or value[1] == "."):
            out.append(f"{token}={value}")
            k += 2
            continue
        if token == "--":
            out.extend(tokens[k:])
            break
        out.append(token)
        k += 1
    return out


def parse_command(argv: Sequence[str] | None, parser: argparse.ArgumentParser | None = None) -> argparse.Namespace:
    """argv -> options, parsed and checked (``parser``: a prebuilt `build_parser()`). A usage error exits 2
    (SystemExit, argparse's way); a value out of range raises `CommandLineError`. Opens nothing."""
    if parser is None:
        from servoface.controller.cli import build_parser

        parser = build_parser()
    args = parser.parse_args(join_dash_values(argv if argv is not None else sys.argv[1:], parser))
    if getattr(args, "_run", None) is not None:
        check_options(args, option_flags(parser, getattr(args, "command", None)))
    return args
