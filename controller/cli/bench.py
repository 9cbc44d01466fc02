"""`servoface bench [SUITE ...|all] [--json] [--quick]`: measured figures next to their limits (default: the
quick set `DEFAULT_SUITES`; ``all``: every suite but the long ones)."""

from __future__ import annotations

import argparse
import importlib
import json
import sys
from collections import Counter

HELP = "run benchmarks and print figures (one JSON object per line with --json)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from servoface.controller.benchmarks import DEFAULT_SUITES, LONG_SUITES, SUITES

    parser.add_argument(
        "suites",
        nargs="*",
        metavar="SUITE",
        help=f"which suites to run ({', '.join(SUITES)}, or all: every one but {', '.join(sorted(LONG_SUITES))}); "
        f"default {' '.join(DEFAULT_SUITES)}",
    )
    parser.add_argument("--json", action="store_true", help="one JSON object per figure per line")
    parser.add_argument("--quick", action="store_true", help="fewer repetitions (smoke run)")
    parser.add_argument("--minutes", type=float, default=None, help="duration of long-running suites (pty: 2, soak: 1)")


def run(args: argparse.Namespace) -> int:
    from servoface.controller.benchmarks import SUITES
    from servoface.controller.benchmarks.figure import SuiteUnavailable, machine_description

    names = suite_names(args.suites)
    unknown = [n for n in names if n not in SUITES]
    if unknown:
        print(f"servoface bench: unknown suite(s) {unknown}; expected some of {list(SUITES)}", file=sys.stderr)
        return 2
    if not args.json:
        print(f"# machine: {machine_description()}")
        print(
            f"# {'suite':9s} {'figure':48s} {'value':>12s} {'unit':10s} {'verdict':7s} "
            "goal (floor: at least / ceiling: at most); vs limit"
        )
        print("# ratio: how many times better than the limit (value / limit for a floor, limit / value for a ceiling)")
    status = 0
    verdicts: Counter[str] = Counter()
    for name in names:
        try:
            module = importlib.import_module(SUITES[name])
        except ModuleNotFoundError as err:
            if err.name != SUITES[name]:
                raise
            print(f"servoface bench: suite '{name}' is not built yet", file=sys.stderr)
            status = 1
            continue
        options = {"minutes": args.minutes} if args.minutes is not None and _takes_minutes(module) else {}
        try:
            for figure in module.run(quick=args.quick, **options):
                verdicts[figure.verdict] += 1
                if args.json:
                    print(json.dumps({"suite": name, **figure.as_dict()}), flush=True)
                else:
                    print(_row(name, figure), flush=True)
        except SuiteUnavailable as err:
            print(f"servoface bench: suite '{name}' cannot run here: {err}", file=sys.stderr)
            status = 1
    if not args.json:
        print(summary_line(verdicts))
    return status


def summary_line(verdicts: Counter[str]) -> str:
    """``# 14 figures: 11 meet their goal, 2 short, 1 without a goal`` (a short figure does not change the
    exit status: benchmarks measure, and a shared machine's load moves them; the README quotes quiet runs)."""
    total = sum(verdicts.values())
    return (
        f"# {total} figures: {verdicts['meets']} meet their goal, {verdicts['short']} short, "
        f"{verdicts['-']} without a goal (short figures do not fail the run: they depend on the machine's load)"
    )


def suite_names(requested: list[str]) -> list[str]:
    """The suites to run: ``DEFAULT_SUITES`` when none is named; ``all`` is every suite but the long ones
    (a long one named beside it still runs)."""
    from servoface.controller.benchmarks import DEFAULT_SUITES, LONG_SUITES, SUITES

    names = list(requested or DEFAULT_SUITES)
    if "all" in names:
        everything = [n for n in SUITES if n not in LONG_SUITES]
        names = everything + [n for n in names if n != "all" and n not in everything]
    return names


def _takes_minutes(module: object) -> bool:
    import inspect

    return "minutes" in inspect.signature(module.run).parameters  # type: ignore[attr-defined]


def _row(suite: str, figure: object) -> str:
    from servoface.controller.benchmarks.figure import Figure

    assert isinstance(figure, Figure)
    goal = figure.goal_text() or "no goal"
    limit = ""
    if figure.limit is not None:
        ratio = figure.ratio
        limit = f"; limit {figure.limit:g}" + (f", ratio {ratio:.3f}" if ratio is not None else "")
    return f"{suite:11s} {figure.name:48s} {figure.value:12.4g} {figure.unit:10s} {figure.verdict:7s} {goal}{limit}"
