"""The command line's parse-and-validate stage: argv -> checked options, before anything is opened.

`parse_command` is what `servoface.controller.cli.main` runs first: argparse (a usage error exits 2 with the
usage line and the message, control characters escaped), then `check_options` — every number finite and of
a sane size, the shared options within their ranges — raising `CommandLineError` (exit 2, one line naming
the option and what was expected). Nothing here opens a port, an emulator, a file or a window; the
sub-commands' own checks of what only they know (a script's contents, a head profile) follow in ``run``.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, NoReturn

from servoface.controller.cli.terminal import printable
from servoface.controller.errors import ControllerError

if TYPE_CHECKING:
    from _typeshed import SupportsWrite

MAX_INT = 2**53  # no option counts anything near this; beyond it an int is a typo or an attack
MAX_FLOAT = 1e12  # seconds, Hz, mm, ms: nothing servoface takes is this large

# option (argparse dest) -> (low, high, low included, high included), for every command that has it
RANGES: dict[str, tuple[float, float, bool, bool]] = {
    "rate": (0.0, 1000.0, False, True),  # Hz
    "duration": (0.0, 1e7, False, False),  # s
    "hold": (0.0, 1e6, True, True),  # s
    "lead_ms": (0.0, 500.0, True, True),
    "port_http": (0.0, 65535.0, True, True),
    "retries": (0.0, 20.0, True, True),
    "minutes": (0.0, 1e5, False, True),
}
SDK_BAUD_COMMANDS = frozenset({"play", "stream", "say", "studio", "node", "calibrate", "demo"})


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


def _in_range(value: float, lo: float, hi: float, lo_in: bool, hi_in: bool) -> bool:
    return (lo <= value if lo_in else lo < value) and (value <= hi if hi_in else value < hi)


def _expected(lo: float, hi: float, lo_in: bool, hi_in: bool) -> str:
    def show(x: float) -> str:
        return str(int(x)) if float(x).is_integer() else str(x)

    return f"{'[' if lo_in else '('}{show(lo)}, {show(hi)}{']' if hi_in else ')'}"


def check_options(args: argparse.Namespace) -> None:
    """Every number finite and sane, the shared options in range; else `CommandLineError` naming it."""
    for dest, value in sorted(vars(args).items()):
        if dest.startswith("_") or isinstance(value, bool):
            continue
        values = value if isinstance(value, list) else [value]
        for v in values:
            _check_number(dest, v)
    command = getattr(args, "command", None)
    baud = getattr(args, "baud", None)
    if command in SDK_BAUD_COMMANDS and isinstance(baud, int):
        from servoface.hardware.dynamixel_bus import SDK_BAUDS

        if baud not in SDK_BAUDS:
            raise CommandLineError(f"--baud {baud}: expected one of {list(SDK_BAUDS)} bps")


def _check_number(dest: str, v: Any) -> None:
    flag = "--" + dest.replace("_", "-")
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
    if dest in RANGES:
        lo, hi, lo_in, hi_in = RANGES[dest]
        if not _in_range(float(v), lo, hi, lo_in, hi_in):
            raise CommandLineError(f"{flag} {v}: expected a value in {_expected(lo, hi, lo_in, hi_in)}")


def parse_command(argv: Sequence[str] | None, parser: argparse.ArgumentParser | None = None) -> argparse.Namespace:
    """argv -> options, parsed and checked (``parser``: a prebuilt `build_parser()`). A usage error exits 2
    (SystemExit, argparse's way); a value out of range raises `CommandLineError`. Opens nothing."""
    if parser is None:
        from servoface.controller.cli import build_parser

        parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "_run", None) is not None:
        check_options(args)
    return args
