"""`servoface cue --heads 'lobby/*' (play NAME | express NAME | say TEXT | neutral) --at +0.5s`."""

from __future__ import annotations

import argparse
import json
import sys

from servoface.controller.cli.network_args import add_network_arguments, open_from_args

HELP = "start the same action on several heads at one time (clock offsets measured per head)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--heads", required=True, help="SITE/NAME pattern, e.g. 'lobby/*'")
    parser.add_argument("verb", choices=["play", "express", "say", "neutral", "estop"], help="what to do")
    parser.add_argument("what", nargs="?", default=None, help="script/expression name, or the text to say")
    parser.add_argument("--at", default="+0.5s", help="when, from now (default +0.5s)")
    parser.add_argument("--intensity", type=float, default=1.0, help="express: intensity 0..1")
    parser.add_argument("--json", action="store_true", help="print the cue as JSON")
    add_network_arguments(parser, node=False)


def run(args: argparse.Namespace) -> int:
    from servoface.controller.network.client import HeadsClient, parse_at
    from servoface.controller.network.errors import NetworkError

    try:
        delay = parse_at(args.at)
        session = open_from_args(args, node=False)
    except NetworkError as err:
        print(f"servoface cue: {err}", file=sys.stderr)
        return 2
    try:
        client = HeadsClient(session)
        if args.verb == "estop":
            client.estop(args.heads, reason="servoface cue estop")
            print(f"e-stop sent to {args.heads}")
            return 0
        what: dict[str, object] = {"verb": args.verb}
        if args.verb in ("play", "express"):
            if not args.what:
                print(f"servoface cue: {args.verb} needs a name", file=sys.stderr)
                return 2
            what["name"] = args.what
            if args.verb == "express":
                what["intensity"] = args.intensity
        elif args.verb == "say":
            what["text"] = args.what or ""
        result = client.cue(args.heads, what, in_s=delay)
    except NetworkError as err:
        print(f"servoface cue: {err}", file=sys.stderr)
        return 2
    finally:
        session.close()
    if args.json:
        print(json.dumps(result))
    else:
        for head, off in result["heads"].items():
            print(f"{head}: clock offset {off['offset_s'] * 1e3:+.2f} ms (+- {off['error_s'] * 1e3:.2f} ms)")
        print(f"cue {result['cue']}: {args.verb} {args.what or ''} in {delay:g} s on {len(result['heads'])} head(s)")
    return 0
