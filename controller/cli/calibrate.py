"""`servoface calibrate --head PATH|human|dog (--port PORT | --emulate | --csv FILE | --builtin) ...`

Calibrate a head's servos and write its calibration file (JSON, atomically):

- interactive (``--port`` or ``--emulate``): torque goes off, you move each servo by hand (or jog it with
  keys) to its neutral, lower and upper targets and a few points between, confirming each; the present
  tick is captured. Curves are fitted, checked (monotone, coverage), plotted, saved;
- ``--csv FILE``: the same fit and checks from measured ``role,target,tick`` rows, no bus needed;
- ``--builtin``: regenerate the ideal calibration of the emulated servos from the head profile's ranges
  (what ships as ``sim/heads/<head>/calibration.json``);
- ``--template``: write the measurement template (``calibration_template.csv``) again for the head as
  head.toml is now; one already there is replaced only with ``--force`` (see ``calibrate_template``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from servoface.controller.calibration_specs import specs_from_head

if TYPE_CHECKING:
    from servoface.calibration.procedure import ProcedureOptions, ProcedureResult, Prompt, Reply
    from servoface.calibration.spec import ServoSpec
    from servoface.hardware.bus import ServoBus

HELP = "calibrate a head's servos (interactive on a port/emulator, or from a CSV) and save the calibration"

KEYS_HELP = """keys: Enter = capture here (at the asked target) | =VALUE = capture, the actuator is at VALUE
      j / k = jog -/+ one step (torque on) | J / K = ten steps | +N / -N = jog N ticks
      g = go where the current calibration file puts the asked target | r = torque off (move by hand)
      d = done (no more points / skip this point) | q = abort (nothing saved) | ? = this help"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--head", required=True, help="head profile: 'human', 'dog' or a profile folder")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--port", help="serial port of the chain (a real adapter, or a pty from 'servoface emulate')")
    source.add_argument("--emulate", action="store_true", help="run on an in-process emulated chain")
    source.add_argument("--csv", type=Path, help="non-interactive: measured role,target,tick rows")
    source.add_argument(
        "--builtin",
        action="store_true",
        help="regenerate the ideal calibration of the emulated servos from the head's ranges",
    )
    source.add_argument(
        "--template",
        action="store_true",
        help="write the measurement template (role,target,tick rows with an ideal servo's ticks) for the head "
        "as head.toml is now, to fill in and pass to --csv (default --out: the profile's calibration_template.csv)",
    )
    parser.add_argument("--baud", type=int, default=1_000_000, help="bus baud rate in bps (default 1000000)")
    parser.add_argument(
        "--out",
        type=Path,
        help="calibration file to write (default: the profile's calibration.json for a profile "
        "folder, ./calibration-<head>.json for a built-in head); with --template, the CSV to write",
    )
    parser.add_argument(
        "--force",
        action="store_true",
        help="with --template: replace a template file already there (it may hold your measured ticks)",
    )
    parser.add_argument("--plot-dir", type=Path, help="write one PNG per calibrated servo here")
    parser.add_argument("--roles", help="comma-separated roles to calibrate (others are kept from the existing file)")
    parser.add_argument("--points", type=int, default=3, help="intermediate points asked per servo (default 3)")
    parser.add_argument(
        "--free-points",
        action="store_true",
        help="after the asked points, let me add points whose target I type in",
    )
    parser.add_argument(
        "--curve",
        choices=("linear", "piecewise_linear", "pchip"),
        help="curve kind for every servo (default: linear for joints, pchip for anchors)",
    )
    parser.add_argument("--jog-step", type=int, default=10, help="ticks per jog key (default 10)")
    parser.add_argument(
        "--mirror",
        help="derive servos as mirror images instead of measuring them: SRC:DST[,SRC:DST], e.g. "
        "brow_inner_l:brow_inner_r (DST = SRC reflected about its neutral tick)",
    )


def builtin_source(head: Any) -> str:
    """The ``metadata.source`` of a generated built-in calibration (no absolute paths: files are shipped)."""
    return f"servoface.calibration.builtin from the ranges of head profile '{head.name}' (ideal emulated servos)"


class BusServoAccess:
    """`ServoAccess` (servoface.calibration.procedure) over a `ServoBus` (single reads and writes)."""

    def __init__(self, bus: ServoBus) -> None:
        self.bus = bus

    def read_present_tick(self, servo_id: int) -> int:
        from servoface.hardware.registers import Register

        return int(self.bus.read(servo_id, Register.PRESENT_POSITION))

    def set_torque(self, servo_id: int, enabled: bool) -> None:
        from servoface.hardware.registers import Register

        self.bus.write(servo_id, Register.TORQUE_ENABLE, 1 if enabled else 0)

    def write_goal_tick(self, servo_id: int, tick: int) -> None:
        from servoface.hardware.registers import Register

        self.bus.write(servo_id, Register.GOAL_POSITION, int(tick))

    def set_position_limits(self, servo_id: int, min_tick: int, max_tick: int) -> None:
        """Min/Max Position Limit (EEPROM, torque off): the servo itself refuses goals past the captured ends."""
        from servoface.hardware.registers import Register

        self.bus.write(servo_id, Register.TORQUE_ENABLE, 0)
        self.bus.write(servo_id, Register.MIN_POSITION_LIMIT, int(min_tick))
        self.bus.write(servo_id, Register.MAX_POSITION_LIMIT, int(max_tick))

    def read_position_limits(self, servo_id: int) -> tuple[int, int]:
        """Min/Max Position Limit in force (put back by a re-measure or a run that saves nothing)."""
        from servoface.hardware.registers import Register

        return int(self.bus.read(servo_id, Register.MIN_POSITION_LIMIT)), int(
            self.bus.read(servo_id, Register.MAX_POSITION_LIMIT)
        )


class TerminalOperator:
    """`servoface.calibration.procedure.Operator` that asks through input() and answers with print()."""

    def __init__(self, jog_step: int = 10) -> None:
        self.jog_step = jog_step
        self._shown_help = False

    def tell(self, message: str) -> None:
        print(f"  ! {message}")

    def ask(self, prompt: Prompt) -> Reply:
        from servoface.calibration.procedure import Abort, Capture, Finish, GoTo, Jog, Relax

        if not self._shown_help:
            print(KEYS_HELP)
            self._shown_help = True
        while True:
            hint = "Enter to capture" if prompt.target is not None else "=VALUE to capture, d when done"
            try:
                text = input(f"[{prompt.role} #{prompt.servo_id} @ {prompt.present_tick}] {prompt.text} ({hint}): ")
            except EOFError:  # end of input (Ctrl-D, a script's stdin ran out): end the prompt's line
                print()
                return Abort()
            except KeyboardInterrupt:
                print()
                raise
            text = text.strip()
            if text == "":
                if prompt.target is None:
                    print("  enter the target as =VALUE (e.g. =4.5), or d when done")
                    continue
                return Capture()
            if text in ("j", "k", "J", "K"):
                step = self.jog_step * (10 if text.isupper() else 1)
                return Jog(step if text.lower() == "k" else -step)
            if text[0] in "+-":
                try:
                    return Jog(int(text))
                except ValueError:
                    print(f"  '{text}': a jog is +N or -N ticks")
                    continue
            if text[0] == "=":
                try:
                    return Capture(float(text[1:]))
                except ValueError:
                    print(f"  '{text}': expected =VALUE in {prompt.unit}, e.g. =4.5")
                    continue
            if text == "g":
                if prompt.suggested_tick is None:
                    print("  no earlier calibration of this servo to go by; jog with j/k")
                    continue
                return GoTo(prompt.suggested_tick)
            if text == "r":
                return Relax()
            if text == "d":
                return Finish()
            if text == "q":
                return Abort()
            print(KEYS_HELP)


def _default_out(head: Any, name: str) -> Path:
    from servoface.sim.heads import BUILTIN_HEADS

    if name in BUILTIN_HEADS or head.profile_dir is None:
        return Path(f"calibration-{head.name}.json")
    return Path(head.calibration_path or Path(head.profile_dir) / "calibration.json")


def run(args: argparse.Namespace) -> int:
    """SIGTERM and SIGHUP (a closed terminal) end a calibration like Ctrl-C: the servo being measured
    gets torque off, nothing half-written is left (files are written atomically), exit 130."""
    import signal
    import threading

    def interrupt(signum: int, frame: object) -> None:
        raise KeyboardInterrupt(signal.Signals(signum).name)

    previous = {}
    if threading.current_thread() is threading.main_thread():
        previous = {s: signal.signal(s, interrupt) for s in (signal.SIGTERM, signal.SIGHUP)}
    try:
        return _run(args)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def _run(args: argparse.Namespace) -> int:
    from servoface.calibration.builtin import write_builtin
    from servoface.calibration.errors import CalibrationError, CalibrationFileError, ProcedureAborted
    from servoface.calibration.fileformat import load_calibration, save_calibration
    from servoface.calibration.procedure import ProcedureOptions, calibrate_from_csv
    from servoface.controller.cli.exits import EXIT_USAGE
    from servoface.hardware.errors import HardwareError
    from servoface.sim.heads import load_head

    if args.force and not args.template:
        print(
            "servoface calibrate: --force: only with --template (a calibration file is replaced as it is)",
            file=sys.stderr,
        )
        return EXIT_USAGE
    try:
        head = load_head(args.head)
    except Exception as err:  # noqa: BLE001 - any profile error is reported, not traced
        print(f"servoface calibrate: {err}", file=sys.stderr)
        return 2
    specs = specs_from_head(head)
    if args.roles:
        wanted = [r.strip() for r in args.roles.split(",") if r.strip()]
        unknown = sorted(set(wanted) - {s.role for s in specs})
        if unknown:
            print(
                f"servoface calibrate: unknown role(s) {unknown}; the head has {[s.role for s in specs]}",
                file=sys.stderr,
            )
            return 2
        specs = [s for s in specs if s.role in wanted]
    from servoface.controller.cli.calibrate_mirror import apply_mirror, parse_mirror

    try:
        mirror = parse_mirror(args.mirror, specs_from_head(head)) if args.mirror else []
    except ValueError as err:
        print(f"servoface calibrate: --mirror: {err}", file=sys.stderr)
        return 2
    specs = [s for s in specs if s.role not in {dst for _, dst in mirror}]
    if args.template:
        from servoface.controller.cli.calibrate_template import run_template

        return run_template(args, head, specs)
    out = args.out or _default_out(head, args.head)
    if args.builtin:
        from servoface.controller.cli.calibrate_template import refused_spans

        if refused_spans(head, specs, "--builtin", args.head):  # as --template and check: the key named
            return EXIT_USAGE
        path = write_builtin(head.name, specs, out, source=builtin_source(head))
        print(f"wrote the built-in calibration of '{head.name}' ({len(specs)} servos) to {path}")
        return 0
    keep = guide = None
    existing = head.calibration_path
    if existing is not None and Path(existing).exists():
        try:
            guide = load_calibration(existing)
        except CalibrationError as err:
            if args.roles:
                print(f"servoface calibrate: cannot keep the other servos: {err}", file=sys.stderr)
                return EXIT_USAGE
            print(f"# ignoring the existing calibration as a guide: {err}")
        keep = guide if args.roles else None
    try:
        if args.csv is not None:
            others = {a.role for a in head.actuators} - {s.role for s in specs}  # --roles, --mirror DST
            result = calibrate_from_csv(
                args.csv, specs, head.name, curve_kind=args.curve, plot_dir=args.plot_dir, keep=keep, skip_roles=others
            )
        else:
            options = ProcedureOptions(
                intermediate=args.points, free_points=args.free_points, curve_kind=args.curve, guide=guide
            )
            result = _interactive(args, specs, head.name, options, keep)
        if mirror:
            result.calibration = apply_mirror(result.calibration, mirror, specs_from_head(head))
        result.saved_to = save_calibration(result.calibration, out)
    except ProcedureAborted as err:
        print(f"servoface calibrate: {err}; nothing saved", file=sys.stderr)
        return 1
    except HardwareError as err:
        print(f"servoface calibrate: bus: {err}; nothing saved", file=sys.stderr)
        return 1
    except CalibrationError as err:  # a measurement file that is missing, malformed or cannot be fit: bad
        # input (2); measurements taken on the head that cannot be fit: the run failed (1)
        print(f"servoface calibrate: {err}", file=sys.stderr)
        if args.csv is not None:
            from servoface.controller.cli.calibrate_template import stale_csv_hint

            needed = {s.role for s in specs} - set(keep.roles if keep is not None else ())
            hint = stale_csv_hint(args.csv, head, args.head, needed)
            if hint is not None:
                print(f"  {hint}", file=sys.stderr)
        return EXIT_USAGE if isinstance(err, CalibrationFileError) or args.csv is not None else 1
    _report(result)
    default = Path(head.calibration_path) if head.calibration_path is not None else None
    same = default is not None and Path(out).resolve() == default.resolve()
    print(f"next: servoface check {args.head}" + ("" if same else f" --calibration {out}"))
    return 0


def _interactive(
    args: argparse.Namespace,
    specs: list[ServoSpec],
    head_name: str,
    options: ProcedureOptions,
    keep: Any,
) -> ProcedureResult:
    from servoface.calibration.procedure import run_procedure
    from servoface.hardware.bus import open_bus

    chain = None
    if args.emulate:
        from servoface.hardware.emulator import ServoChain

        chain = ServoChain.create(ids=[(s.servo_id, s.model) for s in specs], baud=args.baud, wire_time=False)
        bus = open_bus("dynamixel", port=chain, baud=args.baud)
        print(f"# emulated chain: {len(specs)} servos; jog them with j/k (there is no hand to move them)")
    else:
        bus = open_bus("dynamixel", port=args.port, baud=args.baud)
    try:
        check_servos_answer(bus, specs)
        return run_procedure(
            BusServoAccess(bus),
            TerminalOperator(args.jog_step),
            specs,
            head_name,
            options=options,
            plot_dir=args.plot_dir,
            keep=keep,
        )
    finally:
        bus.close()
        if chain is not None:
            chain.close()


def check_servos_answer(bus: ServoBus, specs: list[ServoSpec]) -> None:
    """Ping every servo first: fail before touching anything, naming the silent ids and wrong models."""
    from servoface.hardware.errors import BusError, HardwareConfigError
    from servoface.hardware.registers import model_by_name, model_name

    silent, wrong = [], []
    for s in specs:
        try:
            reply = bus.ping(s.servo_id)
        except BusError:
            silent.append(f"{s.servo_id} ({s.role})")
            continue
        try:
            expected = model_by_name(s.model).number
        except KeyError:
            continue
        if reply.model_number != expected:
            wrong.append(f"{s.servo_id} ({s.role}) is a {model_name(reply.model_number)}, not a {s.model}")
    if silent or wrong:
        problems = ([f"no answer from id(s) {', '.join(silent)}"] if silent else []) + wrong
        raise HardwareConfigError(f"on {bus.port_name} at {bus.baud} bps: " + "; ".join(problems))


def _report(result: Any) -> None:
    cal = result.calibration
    print(f"calibrated {len(result.reports)} servo(s) of '{cal.head}'")
    width = max([18, *(len(role) for role in result.reports)])
    for role, report in result.reports.items():
        s = report.servo
        print(
            f"  {role:{width}s} id {s.servo_id:3d}  {s.curve.kind:16s} ticks {s.min_tick:4d}..{s.max_tick:4d}  "
            f"neutral {s.neutral_tick:4d}  {s.min_target:g}..{s.max_target:g} {s.unit}  "
            f"max residual {report.max_residual_tick:.2f} tick"
        )
    for w in result.warnings:
        print(f"  warning: {w}")
    for role, path in result.plots.items():
        print(f"  plot {role}: {path}")
    if result.saved_to is not None:
        print(f"saved {result.saved_to}")
    print(
        "EEPROM backstop (Min/Max Position Limit) per id: "
        + ", ".join(f"{i}: {lo}..{hi}" for i, (lo, hi) in cal.position_limits_tick().items())
    )
