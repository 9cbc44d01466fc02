"""`servoface calibrate --head DIR --template [--out FILE] [--force]`: the measurement template, written again
for the head as head.toml is now (a servo added or taken out, a range changed since `servoface new`).

A template already there may hold the ticks the builder measured: it is replaced only with ``--force``
(as `servoface new` treats the builder's files), else the command is refused naming it and nothing is
written; ``--out NEW.csv`` writes beside it. The file is written atomically.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Collection, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from servoface.controller.cli.exits import EXIT_OK, EXIT_USAGE
from servoface.controller.new_head.template import TEMPLATE_CSV

if TYPE_CHECKING:
    from servoface.calibration.spec import ServoSpec
    from servoface.sim.head import Head


def default_template(head: Head, head_arg: str) -> Path:
    """The profile's ``calibration_template.csv``; for a built-in head, ``./calibration_template-<name>.csv``."""
    from servoface.sim.heads import BUILTIN_HEADS

    if head_arg in BUILTIN_HEADS or head.profile_dir is None:
        return Path(f"calibration_template-{head.name}.csv")
    return Path(head.profile_dir) / TEMPLATE_CSV


def refused_spans(head: Head, specs: Sequence[ServoSpec], flag: str, head_arg: str) -> bool:
    """Print the joint ranges of ``specs`` that no servo turn can measure (`joint_spans`: check's wording, the
    profile key named) and what to do; True if there were any (then nothing is written: exit 2)."""
    from servoface.controller.joint_spans import span_problems

    problems = span_problems(head, [s.role for s in specs])
    for p in problems:
        print(f"servoface calibrate: {flag}: {p}", file=sys.stderr)
    if problems:
        print(f"  nothing written; fix head.toml and run `servoface check {head_arg}`", file=sys.stderr)
    return bool(problems)


def run_template(args: argparse.Namespace, head: Head, specs: Sequence[ServoSpec]) -> int:
    """Write the template of ``specs`` (the head's servos, or those of ``--roles``); 2 and nothing written
    for a range no servo turn can measure or a file that is there already (without ``--force``)."""
    from servoface.calibration.errors import CalibrationError
    from servoface.controller.cli.outputs import writable_file
    from servoface.controller.new_head.template import write_template

    out = Path(args.out) if args.out is not None else default_template(head, args.head)
    if refused_spans(head, specs, "--template", args.head):
        return EXIT_USAGE
    writable_file(out)  # OSError (exit 2, naming the path) for a folder that is not there or a folder as --out
    if out.exists() and not args.force:
        print(
            f"servoface calibrate: --template: {out} exists already (it may hold the ticks you measured); "
            f"nothing written: pass --force to replace it, or --out NEW.csv to write another file",
            file=sys.stderr,
        )
        return EXIT_USAGE
    try:
        path = write_template(head.name, specs, out)
    except CalibrationError as err:
        print(f"servoface calibrate: --template: {err}; nothing written", file=sys.stderr)
        return EXIT_USAGE
    print(f"wrote the calibration template of '{head.name}' ({len(specs)} servos, an ideal servo's ticks) to {path}")
    print(
        f"next: replace the ticks by the ones you measure, then `servoface calibrate --head {args.head} --csv {path}`"
    )
    return EXIT_OK


def stale_csv_hint(csv: Path, head: Head, head_arg: str, needed: Collection[str]) -> str | None:
    """A next step when ``csv`` and head.toml name different servos (rows for a servo taken out, none for
    one added: head.toml edited since the template was written); None when they agree or the file cannot
    be read. ``needed``: the roles this run must find rows for."""
    from servoface.calibration.errors import CalibrationError
    from servoface.calibration.measurements import read_measurements_csv

    try:
        have = set(read_measurements_csv(csv))
    except CalibrationError:
        return None
    missing = sorted(set(needed) - have)
    extra = sorted(have - set(head.roles))
    if not missing and not extra:
        return None
    differ = "; ".join(
        ([f"no rows for {', '.join(missing)}"] if missing else [])
        + ([f"rows for {', '.join(extra)}, not a servo in head.toml"] if extra else [])
    )
    template = default_template(head, head_arg)
    how = f"servoface calibrate --head {head_arg} --template"
    if not template.exists():
        return f"next: {csv} has {differ}: head.toml edited since? `{how}` writes the rows of the head as it is now"
    return (
        f"next: {csv} has {differ}: head.toml edited since? `{how} --out NEW.csv` writes the rows of the head "
        f"as it is now (`--template --force` replaces {template})"
    )
