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
    "demo": "servoface.controller.cli.demo",
    "play": "servoface.controller.cli.play",
    "stream": "servoface.controller.cli.stream",
    "preview": "servoface.controller.cli.preview",
    "check": "servoface.controller.cli.check",
    "calibrate": "servoface.controller.cli.calibrate",
    "emulate": "servoface.controller.cli.emulate",
    "scan": "servoface.controller.cli.scan",
    "bench": "servoface.controller.cli.bench",
    "list": "servoface.controller.cli.list",
    "new": "servoface.controller.cli.new",
    "node": "servoface.controller.cli.node",
    "heads": "servoface.controller.cli.heads",
    "cue": "servoface.controller.cli.cue",
    "say": "servoface.controller.cli.say",
    "lipsync": "servoface.controller.cli.lipsync",
    "studio": "servoface.controller.cli.studio",
}


def _load(module_name: str) -> ModuleType | None:
    try:
        return importlib.import_module(module_name)
    except ModuleNotFoundError as err:
        if err.name == module_name:  # sub-command not built yet; anything else is a real error
            return None
        raise


def build_parser() -> argparse.ArgumentParser:
    from servoface.controller.cli.options import CheckedParser

    parser = CheckedParser(
        prog="servoface",
        description="Drive expressive Dynamixel faces: AUs -> muscles -> calibration -> twin gate -> bus.",
    )
    parser.add_argument("--version", action="version", version=f"servoface {version()}")
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
    from servoface.controller.cli.options import CommandLineError, parse_command
    from servoface.controller.cli.terminal import printable

    # a tuple, not list(): once imported, the `list` sub-command's module shadows that name in this package
    argv = tuple(argv) if argv is not None else tuple(sys.argv[1:])
    if argv[:1] == ("--version",):  # answered before the sub-commands are imported
        print(f"servoface {version()}")
        return 0
    parser = build_parser()
    try:
        args = parse_command(argv, parser)  # argparse (usage errors exit 2), then every option's range
    except CommandLineError as err:
        command = next((a for a in argv if a in COMMANDS), "")
        print(f"servoface {command}: {printable(err)}".replace(" :", ":"), file=sys.stderr)
        return 2
    if getattr(args, "_run", None) is None:
        parser.print_help()
        return 2
    try:
        code = int(args._run(args))
        sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's last flush
        return code
    except KeyboardInterrupt:
        print("servoface: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # whoever read the output left (`| head`): nothing to report, as other tools
        _drop_stdout()
        return 141  # 128 + SIGPIPE, what a shell shows for a tool the signal ended
    except OSError as err:  # a path, folder or device the command could not use: say which, no traceback
        from servoface.controller.cli.exits import exit_code

        print(f"servoface {args.command}: {describe_os_error(err)}", file=sys.stderr)
        return exit_code(err)  # 2: a path as given cannot be used; 1: the device or disk failed
    except Exception as err:
        from servoface.controller.cli.exits import EXIT_USAGE, is_input_error

        if not is_input_error(err):
            raise
        print(f"servoface {args.command}: {printable(err)}", file=sys.stderr)  # bad input: a message, exit 2
        return EXIT_USAGE


def version() -> str:
    """The installed distribution's version (``unknown`` when run from a tree that was never installed)."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as dist_version

    try:
        return dist_version("servoface")
    except PackageNotFoundError:
        return "unknown (not installed: `pip install -e .`)"


def describe_os_error(err: OSError) -> str:
    """One line for a failed file or device operation: what, which path, and what to do."""
    import errno

    where = f" {err.filename!r}" if err.filename else ""
    what = err.strerror or str(err)
    hint = {
        errno.EACCES: "check its permissions (a serial port: add yourself to the 'dialout' group)",
        errno.EPERM: "check its permissions",
        errno.ENOENT: "check the path; create the folder first or choose another",
        errno.EROFS: "choose a folder on a writable file system",
        errno.ENOSPC: "free some disk space",
        errno.ENOTDIR: "a part of the path is a file, not a folder",
        errno.EISDIR: "give a file name, not a folder",
        errno.EEXIST: "something of that name is in the way: choose another name",
    }.get(err.errno or 0, "")
    return f"cannot use{where}: {what}" + (f" ({hint})" if hint else "")


if __name__ == "__main__":
    sys.exit(main())


def _drop_stdout() -> None:
    """Point stdout at /dev/null, so the interpreter's last flush does not fail on the closed pipe again."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):  # no file descriptor behind stdout (a test's capture): nothing to flush
        pass
