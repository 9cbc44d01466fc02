"""Errors of the twin gate: contract violations only (expected outcomes are `Verdict` reports)."""

from __future__ import annotations

from servoface.sim.errors import SimError


class GateError(SimError):
    """Base of the gate's errors."""


class GateConfigError(GateError):
    """The gate cannot be built for a head: bad limits, unknown roles in a rule, missing calibration."""


class GateInputError(GateError):
    """A caller broke the gate's contract (e.g. ``last_goals_tick`` misses a servo or is not a valid
    command). Bad *requested* goals are not an error: they give a ``reject`` verdict with reasons."""


class TssCacheError(GateError):
    """A cached TSS table cannot be read or written (the message names the file)."""
