"""Errors of the head service (all are ControllerErrors, so front ends catch one base)."""

from servoface.controller.errors import ControllerError


class ServiceError(ControllerError):
    """A command the service refuses at submit time (bad track, bad time, bad source), or a misuse."""


class EStopLatchedError(ServiceError):
    """A motion or torque-on command while the e-stop is latched; clear it first (`clear_estop`)."""


class ServiceClosedError(ServiceError):
    """A command after `shutdown` (or after the loop died on a bus failure)."""


class CommandFailedError(ServiceError):
    """A command that was accepted failed while running (its handle's ``error`` says why)."""
