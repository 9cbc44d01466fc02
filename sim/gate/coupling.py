"""Coupling rules between servos, checked on actuator targets (deg / mm), vectorised over commands.

A servo's *share of travel* is its target's distance from neutral divided by the distance from neutral to
the actuator's limit on that side (0 at neutral, 1 at the limit), signed (+ towards ``upper``).
Rule kinds:
- ``not_all_past``: the listed servos may not all be past ``share`` at once (e.g. the same side's smile
  and frown pullers);
- ``sum_at_most``: the sum of their shares (each counted only in ``direction``) stays <= ``share``.
``direction`` is "+", "-" or "any" (absolute share).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate.errors import GateConfigError
from servoface.sim.gate.verdict import Finding

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class CouplingLimit:
    """One rule in the gate's form (see module docstring)."""

    name: str
    roles: tuple[str, ...]
    share: float
    kind: Literal["not_all_past", "sum_at_most"] = "not_all_past"
    direction: Literal["+", "-", "any"] = "+"


def travel_share(targets: FloatArray, lower: FloatArray, upper: FloatArray, neutral: FloatArray) -> FloatArray:
    """Signed share of travel per actuator; ``targets`` (..., n), the bounds (n,)."""
    return scaled_share(targets, neutral, *travel_scales(lower, upper, neutral))


def travel_scales(lower: FloatArray, upper: FloatArray, neutral: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(travel up, travel down) from neutral per actuator (1 where there is none): `travel_share`'s divisors."""
    return np.where(upper > neutral, upper - neutral, 1.0), np.where(neutral > lower, neutral - lower, 1.0)


def scaled_share(targets: FloatArray, neutral: FloatArray, up: FloatArray, down: FloatArray) -> FloatArray:
    """`travel_share` with its divisors (`travel_scales`) computed once."""
    d = targets - neutral
    return np.where(d >= 0, d / up, d / down)


class CouplingCheck:
    """Rules bound to actuator columns; ``ok`` and ``findings`` on (k, n) / (n,) share arrays."""

    def __init__(self, rules: Sequence[CouplingLimit], roles: Sequence[str]) -> None:
        col = {r: i for i, r in enumerate(roles)}
        self.rules = tuple(rules)
        self._cols: list[NDArray[np.int64]] = []
        for rule in self.rules:
            missing = [r for r in rule.roles if r not in col]
            if missing:
                raise GateConfigError(f"coupling rule '{rule.name}': unknown role(s) {missing}; known {list(roles)}")
            if not 0.0 <= rule.share <= float(len(rule.roles)):
                raise GateConfigError(f"coupling rule '{rule.name}': share {rule.share} out of range")
            self._cols.append(np.array([col[r] for r in rule.roles], dtype=np.int64))
        # all rules at once for `ok`: (R, L) padded columns, pad masked out of min and sum
        width = max((len(c) for c in self._cols), default=0)
        self._pad_cols = np.zeros((len(self.rules), width), dtype=np.int64)
        self._pad_ok = np.zeros((len(self.rules), width), dtype=bool)
        for i, c in enumerate(self._cols):
            self._pad_cols[i, : len(c)] = c
            self._pad_ok[i, : len(c)] = True
        self._sign = np.array([-1.0 if r.direction == "-" else 1.0 for r in self.rules])[:, None]
        self._abs = np.array([r.direction == "any" for r in self.rules])[:, None]
        self._is_min = np.array([r.kind == "not_all_past" for r in self.rules])
        self._limit = np.array([r.share for r in self.rules], dtype=np.float64)

    def _scores(self, shares: FloatArray) -> list[tuple[FloatArray, float]]:
        """Per rule: (score (...,), limit); the rule holds where score <= limit."""
        out = []
        for rule, cols in zip(self.rules, self._cols, strict=True):
            s = shares[..., cols]
            s = s if rule.direction == "+" else (-s if rule.direction == "-" else np.abs(s))
            if rule.kind == "not_all_past":
                out.append((np.min(s, axis=-1), rule.share))
            else:
                out.append((np.sum(np.maximum(s, 0.0), axis=-1), rule.share))
        return out

    def ok(self, shares: FloatArray) -> NDArray[np.bool_]:
        """True where every rule holds; shape ``shares.shape[:-1]``."""
        if not self.rules:
            return np.ones(shares.shape[:-1], dtype=bool)
        s = shares[..., self._pad_cols]  # (..., R, L)
        s = np.where(self._abs, np.abs(s), s * self._sign)
        lowest = np.where(self._pad_ok, s, np.inf).min(axis=-1)
        total = np.where(self._pad_ok, np.maximum(s, 0.0), 0.0).sum(axis=-1)
        score = np.where(self._is_min, lowest, total)
        return np.asarray((score <= self._limit).all(axis=-1), dtype=bool)

    def findings(self, shares: FloatArray) -> list[Finding]:
        """One finding per broken rule, naming its roles and their shares; [] fast when all hold."""
        if not self.rules or bool(self.ok(shares)):
            return []
        out = []
        for rule, (score, limit) in zip(self.rules, self._scores(shares), strict=True):
            if float(score) > limit:
                what = "all past" if rule.kind == "not_all_past" else "sum of shares"
                parts = ", ".join(
                    f"{r} {float(shares[c]):+.2f}"
                    for r, c in zip(rule.roles, self._cols[self.rules.index(rule)], strict=True)
                )
                out.append(
                    Finding(
                        "coupling",
                        f"rule '{rule.name}': {what} {float(score):.2f} > {limit:.2f} of travel ({parts})",
                        rule.roles[0],
                        None,
                        float(score),
                        limit,
                        "share",
                    )
                )
        return out


def limits_from_head(head: Any) -> list[CouplingLimit]:
    """The head's coupling rules in gate form. Reads ``head.coupling_rules`` duck-typed: a
    `servoface.sim.rig.CouplingRule` (``roles``, ``max_sum_share``: sum of absolute shares) or a rule with ``roles``
    and ``max_share`` / ``share`` and optionally ``name``, ``kind``, ``direction``."""
    out: list[CouplingLimit] = []
    for i, rule in enumerate(getattr(head, "coupling_rules", ()) or ()):
        if isinstance(rule, CouplingLimit):
            out.append(rule)
            continue
        roles = tuple(getattr(rule, "roles", ()))
        name = str(getattr(rule, "name", "") or getattr(rule, "note", "") or f"rule{i}")
        if getattr(rule, "max_sum_share", None) is not None:  # servoface.sim.rig.CouplingRule: sum of |shares|
            out.append(CouplingLimit(name, roles, float(rule.max_sum_share), "sum_at_most", "any"))
            continue
        share = getattr(rule, "max_share", getattr(rule, "share", None))
        if share is None or not roles:
            raise GateConfigError(
                f"coupling rule #{i} of head '{getattr(head, 'name', '?')}' has no roles/share: {rule!r}"
            )
        raw_kind = getattr(rule, "kind", "not_all_past")
        kind: Literal["not_all_past", "sum_at_most"] = (
            "sum_at_most" if raw_kind in ("sum_at_most", "sum", "total") else "not_all_past"
        )
        raw_dir = getattr(rule, "direction", "+")
        direction: Literal["+", "-", "any"] = "-" if raw_dir == "-" else ("any" if raw_dir == "any" else "+")
        out.append(CouplingLimit(name, roles, float(share), kind, direction))
    return out
