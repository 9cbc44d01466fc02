"""`servoface cue --heads 'lobby/*' (play NAME | express NAME | say TEXT | neutral) --at +0.5s`, and
`servoface cue --heads 'lobby/*' estop | clear_estop`.

A cue waits for each head's answer (it takes the cue or refuses it: an unknown name, a value out of range, an
e-stop latched) and says which; exit 0 when every head took it, 1 when one refused or did not answer."""

from __future__ import annotations

import argparse
import json
import sys

from servoface.controller.cli.network_args import add_network_arguments, open_from_args

HELP = "start the same action on several heads at one time (clock offsets measured per head)"
ANSWER_WAIT_S = 2.0  # each head answers on taking or refusing a cue (a say is synthesised first: ~0.1-0.5 s)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--heads", required=True, help="SITE/NAME pattern, e.g. 'lobby/*'")
    parser.add_argument(
        "verb", choices=["play", "express", "say", "neutral", "estop", "clear_estop"], help="what to do"
    )
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
        if args.verb == "clear_estop":
            client.clear_estop(args.heads)
            print(f"e-stop cleared on {args.heads} (torque stays off until a command asks for it)")
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
        result = client.cue(args.heads, what, in_s=delay, answers_within_s=ANSWER_WAIT_S)
    except NetworkError as err:
        print(f"servoface cue: {err}", file=sys.stderr)
        return 2
    finally:
        session.close()
    answers = result["answers"]
    taken = [head for head, answer in answers.items() if answer == "accepted"]
    if args.json:
        print(json.dumps(result))
    else:
        for head, off in result["heads"].items():
            # the head's service clock counts from its own start: the offset is that origin, not a sync error
            print(
                f"{head}: service clock = this machine's {off['offset_s']:+.4f} s (+- {off['error_s'] * 1e3:.2f} ms);"
                f" {answers[head]}"
            )
        what_text = f"{args.verb} {args.what}" if args.what else args.verb
        print(f"cue {result['cue']}: {what_text} in {delay:g} s, taken by {len(taken)} of {len(answers)} head(s)")
    if len(taken) < len(answers):
        for head, answer in answers.items():
            if answer != "accepted":
                print(f"servoface cue: {head}: {answer}", file=sys.stderr)
        return 1
    return 0
