"""`servoface` command line: one module per sub-command, imported lazily.

Each sub-command module defines ``HELP: str``, ``add_arguments(parser)`` and ``run(args) -> int``, and
keeps heavy imports (pyrender, trimesh, dynamixel_sdk) inside ``run`` so ``servoface --help`` is fast.
``print``/``input`` are allowed only in this package.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence
from types import ModuleType

# name -> module implementing it, in the order shown by --help
COMMANDS: dict[str, str] = {
    "demo": "controller.cli.demo",
    "play": "controller.cli.play",
    "stream": "controller.cli.stream",
    "preview": "controller.cli.preview",
    "check": "controller.cli.check",
    "calibrate": "controller.cli.calibrate",
    "emulate": "controller.cli.emulate",
    "scan": "controller.cli.scan",
    "bench": "controller.cli.bench",
}


def _load(module_name: str) -> ModuleType | None:
    try:
        return importlib.import_module(module_name)
    except ModuleNotFoundError as err:
        if err.name == module_name:  # sub-command not built yet; anything else is a real error
            return None
        raise


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="servoface",
        description="Drive expressive Dynamixel faces: AUs -> muscles -> calibration -> twin gate -> bus.",
    )
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, module_name in COMMANDS.items():
        module = _load(module_name)
        if module is None:
            continue
        sub = subparsers.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(sub)
        sub.set_defaults(_run=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "_run", None) is None:
        parser.print_help()
        return 2
    try:
        return int(args._run(args))
    except KeyboardInterrupt:
        print("servoface: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
