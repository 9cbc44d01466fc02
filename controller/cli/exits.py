"""Exit codes of the command line, and which errors mean bad input (2) rather than a failed run (1).

One place for the rule the README promises: bad input (an option, a head name or profile, a calibration
or measurement file, an expression, a script, a path that cannot be used, a port that does not exist) is
refused with a message and exit code 2, before anything is driven; 1 is kept for runs that started and
failed (a bus failure, a render that could not be made, servos that ended latched or missing).
"""

from __future__ import annotations

import errno
from pathlib import Path

EXIT_OK = 0
EXIT_FAILURE = 1  # the run started and failed: bus failure, rendering failed, servos latched / missing
EXIT_USAGE = 2  # bad arguments or input: nothing was driven

# a path or device named on the command line that cannot be used as given: the user's to fix
_USAGE_ERRNOS = frozenset(
    {
        errno.ENOENT,
        errno.ENOTDIR,
        errno.EISDIR,
        errno.EEXIST,
        errno.EACCES,
        errno.EPERM,
        errno.EROFS,
        errno.ENAMETOOLONG,
        errno.ENXIO,
        errno.ENODEV,
        errno.ELOOP,
    }
)


def is_input_error(err: BaseException) -> bool:
    """Whether ``err`` means the input was bad (exit 2): the typed errors of servoface's packages for a
    profile, calibration, expression, script or option, and an OSError about a path or device as named."""
    from servoface.calibration import CalibrationError
    from servoface.calibration.errors import ProcedureAborted
    from servoface.controller.errors import ControllerError
    from servoface.hardware.errors import HardwareConfigError
    from servoface.sim.errors import RenderError, SimError

    if isinstance(err, RenderError | ProcedureAborted):
        return False  # rendering unavailable or failed; an operator's abort: the run failed, not the input
    if isinstance(err, SimError | CalibrationError | ControllerError | HardwareConfigError):
        return True
    if isinstance(err, OSError):
        return err.errno in _USAGE_ERRNOS
    return False


def exit_code(err: BaseException) -> int:
    """2 for bad input (:func:`is_input_error`), else 1."""
    return EXIT_USAGE if is_input_error(err) else EXIT_FAILURE


def is_unknown_head(head_arg: str) -> bool:
    """``head_arg`` is neither a built-in head name nor a path that exists (a typo, most likely)."""
    from servoface.sim.heads import BUILTIN_HEADS

    return head_arg not in BUILTIN_HEADS and not Path(head_arg).exists()


def head_message(head_arg: str, err: BaseException, flag: str = "--head") -> str:
    """``--head ARG: what is wrong`` (``flag``: how the command takes the head; "" for a positional), naming
    the path once: the profile loader's messages start with the path as it normalised it (``my_head`` for
    ``my_head/``), or with the file in the folder it could not read (``my_head/head.toml: ...``), which
    says which head already."""
    text = str(err)
    spelt = {head_arg, str(Path(head_arg))} if head_arg.strip() else {head_arg}
    for name in sorted(spelt, key=len, reverse=True):
        if text.startswith(f"{name}: "):
            return f"{flag} {head_arg}: {text.removeprefix(f'{name}: ')}".lstrip()
    first = Path(text.split(": ", 1)[0]) if ": " in text else None
    if head_arg.strip() and first is not None and first.suffix and first.is_relative_to(Path(head_arg)):
        return text  # "my_head/head.toml: not valid TOML ...": the file names the head
    return f"{flag} {head_arg}: {text}".lstrip()


def head_hint(head_arg: str) -> str:
    """What to do about a head that could not be loaded: for a name that is neither built in nor a folder,
    where the names are; for a profile that exists, fix it and check it."""
    from servoface.sim.heads import BUILTIN_HEADS

    if is_unknown_head(head_arg):
        return (
            f"next: use a built-in head ({', '.join(BUILTIN_HEADS)}; `servoface list heads`) or a profile "
            "folder with head.toml (`servoface new DIR --from mechanical` writes one)"
        )
    path = Path(head_arg)
    if path.is_dir() and not (path / "head.toml").is_file():
        return f"next: {path} has no head.toml: `servoface new {path} --from mechanical` writes one"
    return f"next: fix the profile at the place named above and run `servoface check {head_arg}` again"
