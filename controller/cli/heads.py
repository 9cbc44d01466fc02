"""`servoface heads [--connect EP] [--site S]`: the heads present on Zenoh, with their status."""

from __future__ import annotations

import argparse
import json
import sys

from servoface.controller.cli.network_args import add_network_arguments, open_from_args

HELP = "list the heads on Zenoh (presence) with their status"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("pattern", nargs="?", default="*/*", help="SITE/NAME, '*' allowed (default */*)")
    parser.add_argument("--json", action="store_true", help="one JSON object per head")
    parser.add_argument("--timeout", type=float, default=1.0, help="seconds to wait for answers (default 1)")
    add_network_arguments(parser, node=False)


def run(args: argparse.Namespace) -> int:
    from servoface.controller.network.client import HeadsClient
    from servoface.controller.network.errors import NetworkError

    try:
        session = open_from_args(args, node=False)
    except NetworkError as err:
        print(f"servoface heads: {err}", file=sys.stderr)
        return 2
    try:
        heads = HeadsClient(session).heads(args.pattern, timeout_s=args.timeout)
    except NetworkError as err:
        print(f"servoface heads: {err}", file=sys.stderr)
        return 2
    finally:
        session.close()
    for h in heads:
        if args.json:
            print(json.dumps({"site": h.site, "name": h.name, **h.status}))
        else:
            s = h.status
            print(
                f"{h.site}/{h.name}  {s.get('head', '?')} ({s.get('face_type', '?')}), {len(s.get('servos', []))} "
                f"servos, frames {s.get('frames')}, late {s.get('late')}, e-stop {s.get('estop_latched')}"
            )
    if not heads:
        print(f"# no head matches {args.pattern} (check --connect)", file=sys.stderr)
    return 0 if heads else 1
