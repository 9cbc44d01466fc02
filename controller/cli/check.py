"""`servoface check HEAD`: validate a head profile and its calibration; print the servos, limits, ranges."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = "validate a head profile and its calibration; print a table of servos, limits and ranges"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("head", help="built-in head (human, dog) or a profile folder")
    parser.add_argument("--calibration", type=Path, help="calibration JSON (default: the one the profile names)")


def run(args: argparse.Namespace) -> int:
    from servoface.calibration import CalibrationError
    from servoface.controller.errors import ControllerError
    from servoface.controller.face import head_calibration
    from servoface.controller.head_servos import servo_specs
    from servoface.sim.errors import SimError
    from servoface.sim.heads import load_head

    try:
        head = load_head(args.head)
        cal = head_calibration(head, args.calibration)
        specs = servo_specs(head, cal)
    except (SimError, CalibrationError, ControllerError) as err:
        print(f"servoface check: {err}", file=sys.stderr)
        return 1
    print(
        f"head {head.name!r} ({head.face_type}): {len(head.joints)} joints, {len(head.parts)} parts, "
        f"{head.skin.vertices_mm.shape[0]} skin vertices, {len(head.muscles)} muscles, {len(specs)} servos"
    )
    print(f"calibration: {head.calibration_path if args.calibration is None else args.calibration}")
    header = f"{'id':>3} {'role':16} {'model':11} {'kind':6} {'target range':>20}"
    header += f" {'ticks min..max':>15} {'neutral':>7}"
    print(header)
    print("-" * len(header))
    for spec in specs:
        c = cal[spec.role]
        actuator = head.actuator(spec.role)
        rng = f"{c.min_target:.1f}..{c.max_target:.1f} {c.unit}"
        print(
            f"{spec.servo_id:>3} {spec.role:16} {spec.model:11} {actuator.kind:6} {rng:>20} "
            f"{c.min_tick:>6}..{c.max_tick:<6}  {c.neutral_tick:>7}"
        )
    problems = []
    try:
        from servoface.sim.face_model import FaceModel
        from servoface.sim.gate import TwinGate

        face = FaceModel(head)
        gate = TwinGate(head, cal, 0.02, face_model=face)
        neutral = cal.neutral_goals()
        verdict = gate.check(neutral, neutral)
        if verdict.kind != "accept":
            problems.append(f"the neutral pose does not pass the twin gate: {verdict.reasons()}")
        for role, target in face.solve({}).actuator_targets.items():
            if abs(target - cal[role].neutral_target) > cal[role].target_resolution():
                problems.append(
                    f"{role}: the muscle model's neutral {target:.2f} differs from the calibrated "
                    f"neutral {cal[role].neutral_target:.2f} {cal[role].unit}"
                )
    except (SimError, CalibrationError) as err:
        problems.append(str(err))
    for p in problems:
        print(f"problem: {p}")
    print("ok" if not problems else f"{len(problems)} problem(s)")
    return 0 if not problems else 1
