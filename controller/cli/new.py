"""`servoface new DIR --from human|dog|mechanical`: write a commented head profile to edit (bring-up step)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = "write a new head profile folder to edit: a copy of the human or dog head, or a mechanical 8-servo head"


def _folder(text: str) -> Path:
    """A folder name; an empty one (an unset shell variable, `servoface new $DIR`) would mean the current folder."""
    if not text.strip():
        raise argparse.ArgumentTypeError("expected the name of the profile folder to create, got ''")
    return Path(text)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("folder", type=_folder, help="the profile folder to create (may exist, empty)")
    parser.add_argument(
        "--from",
        dest="kind",
        choices=["human", "dog", "mechanical"],
        default="mechanical",
        help="starting point: the built-in human or dog head (skin, muscles, anchors) or a mechanical head "
        "(rigid parts on joints, no skin; default)",
    )
    parser.add_argument("--force", action="store_true", help="overwrite an existing head.toml in the folder")


def run(args: argparse.Namespace) -> int:
    from servoface.controller.cli import describe_os_error
    from servoface.controller.errors import ControllerError
    from servoface.controller.new_head import TEMPLATE_CSV, write_new_head
    from servoface.sim.errors import SimError

    try:
        made = write_new_head(args.folder, args.kind, force=args.force)
    except (ControllerError, SimError) as err:
        print(f"servoface new: {err}", file=sys.stderr)
        return 2
    except OSError as err:
        from servoface.controller.cli.exits import exit_code

        print(f"servoface new: {args.folder}: {describe_os_error(err)}", file=sys.stderr)
        return exit_code(err)  # 2: a folder that cannot be made where it was asked for
    folder = made.folder
    print(f"wrote a {made.kind} head profile to {folder}:")
    for path in made.files:
        if path.parent == folder:
            print(f"  {path.name}")
    n_meshes = sum(1 for p in made.files if p.parent != folder)
    if n_meshes:
        print(f"  meshes/ ({n_meshes} STL files: replace them by your own parts)")
    print("next steps:")
    print(
        f"  1. edit {folder / 'head.toml'}: servo ids and models (`servoface scan --port /dev/ttyUSB0`), joints, parts"
    )
    print(f"  2. measure each servo and put the ticks in {folder / TEMPLATE_CSV}, then")
    print(f"     servoface calibrate --head {folder} --csv {folder / TEMPLATE_CSV}")
    print(f"     (or interactively on the head: servoface calibrate --head {folder} --port /dev/ttyUSB0)")
    print(f"  3. servoface check {folder}")
    return 0
