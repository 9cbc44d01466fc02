"""`servoface check HEAD`: validate a head profile and its calibration, and report what the head can express.

Prints the servos (limits, ranges), then the gaps a builder must fix (each with the command that fixes
it: a missing calibration, a role it lacks, a servo model or id that differs from the profile), warnings
(an implausible size: a mesh in metres), and what the head can express: per AU and per library
expression, how much of the muscle-model target the servos' achievable face shows (landmark error in mm)
and the AUs it cannot show at all, with the reason.

Exit codes (the README's rule for every command): 0 nothing to fix; 1 problems found in a profile that
loads (its calibration, a joint range no servo turn can measure, the report); 2 bad input: no profile at
HEAD, or a head.toml that cannot be read, parsed or validated.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

HELP = "validate a head profile and its calibration; report servos, limits and what the head can express"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("head", help="built-in head (human, dog) or a profile folder")
    parser.add_argument("--calibration", type=Path, help="calibration JSON (default: the one the profile names)")
    parser.add_argument("--json", type=Path, metavar="FILE", help="also write the expressiveness report as JSON")
    parser.add_argument("--no-report", action="store_true", help="validation only, skip the expressiveness report")


def _cal_hint(head_arg: str, roles: list[str] | None = None) -> str:
    roles_part = f" --roles {','.join(roles)}" if roles else ""
    template = Path(head_arg) / "calibration_template.csv"
    csv = str(template) if template.is_file() else "measured.csv"
    return (
        f"run `servoface calibrate --head {head_arg}{roles_part} --port /dev/ttyUSB0` (on the head), "
        f"or `--csv {csv}` (role,target,tick rows you measured)"
    )


def _calibration_gaps(head: Any, cal: Any, head_arg: str) -> list[str]:
    """Roles, ids and servo models where the calibration and the profile disagree (each with its fix)."""
    from servoface.controller.head_servos import calibration_mismatches

    found = calibration_mismatches(head, cal)
    problems = []
    missing = [m.role for m in found if m.kind == "missing"]
    if missing:
        names = ", ".join(repr(r) for r in missing)
        problems.append(f"calibration has no servo for role {names}: {_cal_hint(head_arg, missing)}")
    extra = [m.role for m in found if m.kind == "extra"]
    if extra:
        problems.append(
            f"calibration names role(s) {extra} the profile does not have: recalibrate "
            f"(`servoface calibrate --head {head_arg} ...`) or add the actuators to head.toml"
        )
    for m in found:
        if m.kind == "id":
            problems.append(
                f"{m.role}: servo id {m.profile} in head.toml but {m.calibration} in the calibration: fix the id "
                f"(`servoface scan --port ...` lists the ids) or {_cal_hint(head_arg, [m.role])}"
            )
        elif m.kind == "model":
            problems.append(
                f"{m.role}: servo model {m.profile} in head.toml but {m.calibration} in the calibration: "
                f"fix the model in head.toml or {_cal_hint(head_arg, [m.role])}"
            )
    return problems


def run(args: argparse.Namespace) -> int:
    from servoface.calibration import CalibrationError, load_calibration
    from servoface.controller.cli.exits import EXIT_USAGE, head_hint, head_message
    from servoface.controller.cli.terminal import printable
    from servoface.controller.errors import ControllerError
    from servoface.controller.joint_spans import span_problems
    from servoface.sim.errors import SimError
    from servoface.sim.heads import load_head
    from servoface.sim.heads.sizes import size_warnings

    if args.json is not None:  # the report takes a while: a path it cannot be written to fails first
        from servoface.controller.cli import describe_os_error
        from servoface.controller.cli.outputs import writable_file

        try:
            writable_file(args.json)
        except OSError as err:
            print(f"servoface check: --json {args.json}: {describe_os_error(err)}", file=sys.stderr)
            return EXIT_USAGE
    try:
        head = load_head(args.head)
    except (SimError, OSError) as err:
        print(f"servoface check: {printable(head_message(args.head, err, flag=''))}", file=sys.stderr)
        print(f"  {head_hint(args.head)}", file=sys.stderr)
        # bad input, as for every command (2): nothing there to check, or a profile that cannot be read or
        # validated; 1 is kept for the problems found in a profile that loads
        return EXIT_USAGE
    print(
        f"head {head.name!r} ({head.face_type}): {len(head.joints)} joints, {len(head.parts)} parts, "
        f"{head.skin.vertices_mm.shape[0]} skin vertices{'' if head.has_skin else ' (mechanical: no skin)'}, "
        f"{len(head.muscles)} muscles, {len(head.actuators)} servos"
    )
    for w in size_warnings(head):
        print(f"warning: {w}")
    problems: list[str] = []
    cal_path = args.calibration if args.calibration is not None else head.calibration_path
    cal = None
    broken = None  # why a calibration file that exists cannot be used
    if cal_path is None or not Path(cal_path).is_file():
        where = "head.toml names no calibration file" if cal_path is None else f"no calibration file {cal_path} yet"
        problems.append(f"{where}: {_cal_hint(args.head)}")
    else:
        try:
            cal = load_calibration(cal_path)
        except (CalibrationError, OSError) as err:
            broken = printable(err).removeprefix(f"{cal_path}: ")
            problems.append(
                f"calibration file {cal_path} is broken: {broken}; fix it or recalibrate: {_cal_hint(args.head)}"
            )
    # a joint range no servo turn can measure: calibrate would refuse it (a calibrated role has proved it can)
    problems[:0] = span_problems(head, [r for r in head.roles if cal is None or r not in cal.roles])
    if cal is not None:
        print(f"calibration: {cal_path}")
        problems += _calibration_gaps(head, cal, args.head)
    if cal is not None and not problems:
        problems += _servo_table(head, cal)
    uncalibrated = cal is None and broken is None  # (a broken file: the report would fail on it too)
    if (not problems or uncalibrated) and not args.no_report:
        if uncalibrated:
            print("\n(no calibration yet: the report below uses the profile's actuator ranges, without the twin gate)")
        try:
            _report(head, cal, args)
        except (SimError, CalibrationError, ControllerError) as err:
            problems.append(f"expressiveness report: {err}")
    for p in problems:
        print(f"problem: {p}")
    if problems:
        print(f"{len(problems)} problem(s); fix them and run `servoface check {args.head}` again")
        return 1
    print(f"ok: next `servoface preview --all --head {args.head} -o sheet.png`, then `servoface play happiness "
          f"--head {args.head} --emulate` (or --port /dev/ttyUSB0)")  # fmt: skip
    return 0


def _servo_table(head: Any, cal: Any) -> list[str]:
    from servoface.calibration import CalibrationError
    from servoface.controller.head_servos import servo_specs
    from servoface.sim.errors import SimError

    problems: list[str] = []
    try:
        specs = servo_specs(head, cal)
    except (SimError, CalibrationError) as err:
        return [str(err)]
    rw = max([16, *(len(s.role) for s in specs)])  # columns as wide as the longest role and model
    mw = max([11, *(len(s.model) for s in specs)])
    header = f"{'id':>3} {'role':{rw}} {'model':{mw}} {'kind':6} {'target range':>20}"
    header += f" {'ticks min..max':>15} {'neutral':>7}"
    print(header)
    print("-" * len(header))
    for spec in specs:
        c = cal[spec.role]
        actuator = head.actuator(spec.role)
        rng = f"{c.min_target:.1f}..{c.max_target:.1f} {c.unit}"
        print(
            f"{spec.servo_id:>3} {spec.role:{rw}} {spec.model:{mw}} {actuator.kind:6} {rng:>20} "
            f"{c.min_tick:>6}..{c.max_tick:<6}  {c.neutral_tick:>7}"
        )
    try:
        from servoface.sim.gate import TwinGate
        from servoface.sim.render.twin import face_model

        face = face_model(head)
        gate = TwinGate(head, cal, 0.02, face_model=face)
        neutral = cal.neutral_goals()
        verdict = gate.check(neutral, neutral)
        if verdict.kind != "accept":
            problems.append(f"the neutral pose does not pass the twin gate: {verdict.reasons()}")
        for role, target in face.solve({}).actuator_targets.items():
            if abs(target - cal[role].neutral_target) > cal[role].target_resolution():
                problems.append(
                    f"{role}: the muscle model's neutral {target:.2f} differs from the calibrated "
                    f"neutral {cal[role].neutral_target:.2f} {cal[role].unit}: set neutral_deg/neutral_mm in "
                    f"head.toml or recalibrate the role"
                )
        if not problems:
            for w in _apex_warnings(head, cal, face, gate):
                print(f"warning: {w}")
    except (SimError, CalibrationError) as err:
        problems.append(str(err))
    return problems


def _report(head: Any, cal: Any, args: argparse.Namespace) -> None:
    from servoface.sim.achievable import AchievableFace
    from servoface.sim.expressions import load_library
    from servoface.sim.expressiveness import Expressiveness

    report = Expressiveness(AchievableFace(head, cal))
    aus = report.au_scores()
    library = load_library(head.expressions_path or head.face_type)
    exprs = report.expression_scores({k: v for k, v in library.items() if k != "neutral"})
    cannot = [s for s in aus if s.cannot_show]
    cannot_numbers = {s.name for s in cannot}
    shown = [s for s in aus if not s.cannot_show]
    print(
        f"\nwhat this head can express (the servos' achievable face vs the muscle-model target, {len(aus)} AU cases):"
    )
    aw = max([7, *(len(s.name) for s in aus)])  # the name columns as wide as the longest name
    print(f"  {'AU':{aw}} {'shown':>6} {'max err':>8} {'moves':>7}  notes")
    for s in shown:
        note = "; ".join(s.reasons) if s.shown < 0.9 else ""
        print(f"  {s.name:{aw}} {s.shown:6.0%} {s.max_error_mm:6.1f}mm {s.achieved_motion_mm:5.1f}mm  {note}")
    print(f"cannot show ({len(cannot)}): {', '.join(s.name for s in cannot) or 'none'}")
    for s in cannot:
        print(f"  {s.name:{aw}} {'; '.join(s.reasons) or 'moves nothing'}")
    print(f"library expressions ({len(exprs)}, shown: of the whole expression, weighted by AU intensity):")
    rows = []
    ew = max([12, *(len(s.name) for s in exprs)])
    for s in exprs:
        apex = _apex(library[s.name])
        expr_aus = sorted({_au_key(k) for k in apex} & cannot_numbers, key=_au_order)
        share = _share_it_has(apex, set(expr_aus))
        if expr_aus and share > 0:  # "of the rest": scored without them (a joint left in the profile with no
            s = report.score(s.name, _without(apex, set(expr_aus)))  # servo would still move the target)
        overall = s.shown * share  # the face's own model cannot even ask for the AUs it lacks: count them out
        rest = f" ({s.shown:.0%} of the rest)" if share > 0 else " (all of its AUs)"
        lost = f"; without {', '.join(expr_aus)}{rest}" if expr_aus else ""
        print(f"  {s.name:{ew}} {overall:6.0%} {s.max_error_mm:6.1f}mm{lost}")
        rows.append(
            {
                **s.as_dict(),
                "aus_it_cannot_show": expr_aus,
                "au_share": round(share, 3),
                "shown_overall": round(overall, 3),
            }
        )
    if args.json is not None:
        data = {
            "head": head.name,
            "aus": [s.as_dict() for s in aus],
            "cannot_show": [s.name for s in cannot],
            "expressions": rows,
        }
        args.json.write_text(json.dumps(data, indent=2) + "\n")
        print(f"wrote {args.json}")


def _apex_warnings(head: Any, cal: Any, face: Any, gate: Any) -> list[str]:
    """One line per library expression whose apex the twin gate refuses as a pose (a coupling rule, skin
    strain, a collision: `TwinGate.audit`, every state check without shortcuts): played on this head, the gate
    holds the face short of it. Targets outside a servo's calibrated range are clamped first, as the pipeline
    does."""
    from servoface.sim.errors import SimError
    from servoface.sim.expressions import load_library

    library = load_library(head.expressions_path or head.face_type)
    out = []
    for name, expression in library.items():
        if name == "neutral":
            continue
        try:
            targets = face.solve(_apex(expression)).actuator_targets
        except SimError:
            continue  # a pose the head refuses is its own problem, reported by the expressiveness report
        clamped = {
            role: min(max(value, cal[role].min_target), cal[role].max_target)
            for role, value in targets.items()
            if role in cal.roles
        }
        findings = [f for f in gate.audit(cal.targets_to_goals(clamped)) if f.check != "limit"]
        if findings:
            more = f" (and {len(findings) - 1} more)" if len(findings) > 1 else ""
            out.append(
                f"library expression {name!r} at its apex breaks {findings[0]}{more}: the twin gate holds the "
                f"face short of it on this head (loosen the rule in head.toml, or lower its AUs in the expression, "
                f"the AU table or the direct table)"
            )
    return out


def _apex(expression: Any) -> dict[str, float]:
    from servoface.sim.render.clips import apex_aus

    return dict(apex_aus(expression))


def _without(apex: dict[str, float], lacking: set[str]) -> dict[str, float]:
    """An expression's apex AUs without those of ``lacking`` (AU numbers, ``"AU12"``)."""
    return {k: v for k, v in apex.items() if _au_key(k) not in lacking}


def _share_it_has(apex: dict[str, float], lacking: set[str]) -> float:
    """The share of an expression's AU intensity (sum of |value| over its AUs) on AUs the head can show."""
    total = sum(abs(v) for v in apex.values())
    kept = sum(abs(v) for v in _without(apex, lacking).values())
    return kept / total if total > 0 else 1.0


def _au_key(name: str) -> str:
    from servoface.sim.au.mapping import canonical_au_name

    return f"AU{canonical_au_name(name)[0]}"


def _au_order(name: str) -> int:
    return int(name[2:].rstrip("-L"))
