"""`servoface list [scripts|samples|heads|expressions]`: what the package ships, by name, with its path."""

from __future__ import annotations

import argparse

HELP = "list what servoface ships (scripts, samples, heads, expressions), by name, with their paths"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "kind",
        nargs="?",
        choices=["scripts", "samples", "heads", "expressions", "all"],
        default="all",
        help="what to list (default: all)",
    )


def run(args: argparse.Namespace) -> int:
    from servoface.controller.shipped import KINDS, list_shipped

    kinds = KINDS if args.kind == "all" else (args.kind,)
    for kind in kinds:
        items = list_shipped(kind)
        print(f"# {kind} ({len(items)})")
        width = max((len(i.name) for i in items), default=4)
        for item in items:
            note = f"  {item.note}" if item.note else ""
            print(f"  {item.name:<{width}}  {item.path}{note}")
    print(
        "# use a name anywhere a file goes: `servoface play human_performance --emulate`, "
        "`servoface play --input sample:openface_smile --emulate`, `--head dog`"
    )
    return 0
