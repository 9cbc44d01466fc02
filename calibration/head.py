"""A head's calibration: every servo by role, with role -> id translation and batch conversions.

Above ``hardware/`` servos are named by role; below it by id. ``targets_to_goals`` is where a role-keyed
set of actuator targets becomes an id-keyed set of goal ticks. It is all-or-nothing: one refused target
raises before anything is returned.

Coupled servos (a skin anchor whose pull also depends on neighbours, see :class:`RbfCoupling`) are solved
after their neighbours, in dependency order; a dependency cycle is refused at construction.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from servoface.calibration.bank import CurveBank
from servoface.calibration.errors import (
    CalibrationError,
    CurveError,
    TargetOutOfRangeError,
    UnknownServoError,
)
from servoface.calibration.servo import ServoCalibration, round_ticks


@dataclass(frozen=True)
class CalibrationMetadata:
    """When and how a calibration was made. ``method``: "procedure", "csv" or "builtin"."""

    created_utc: str = ""
    method: str = "builtin"
    source: str = ""
    notes: str = ""
    extra: Mapping[str, Any] = field(default_factory=dict)


class HeadCalibration:
    """Role -> :class:`ServoCalibration` for one head, with unique roles and ids."""

    def __init__(
        self,
        head: str,
        servos: Sequence[ServoCalibration],
        metadata: CalibrationMetadata | None = None,
    ) -> None:
        if not servos:
            raise CalibrationError(f"head '{head}': a calibration needs at least one servo")
        self.head = head
        self.metadata = metadata or CalibrationMetadata()
        self._by_role: dict[str, ServoCalibration] = {}
        self._by_id: dict[int, ServoCalibration] = {}
        for s in servos:
            if s.role in self._by_role:
                raise CalibrationError(f"head '{head}': role '{s.role}' appears twice")
            if s.servo_id in self._by_id:
                raise CalibrationError(
                    f"head '{head}': servo id {s.servo_id} is used by both "
                    f"'{self._by_id[s.servo_id].role}' and '{s.role}'"
                )
            self._by_role[s.role] = s
            self._by_id[s.servo_id] = s
        self._order = self._solve_order()
        self._roles = tuple(s.role for s in servos)
        self._ids = tuple(s.servo_id for s in servos)
        self._index = {r: i for i, r in enumerate(self._roles)}
        self._bank = CurveBank(servos)
        self._coupled = [j for j, s in enumerate(servos) if s.coupling is not None]
        self._neutral_tick_row = np.array([[s.neutral_tick for s in servos]], dtype=np.float64)
        self._neutral_target_row = np.clip(
            np.array([[s.neutral_target for s in servos]]), self._bank.min_target, self._bank.max_target
        )

    def _solve_order(self) -> list[str]:
        """Roles in an order where every coupled servo comes after its neighbours."""
        order: list[str] = []
        state: dict[str, int] = {}

        def visit(role: str, chain: tuple[str, ...]) -> None:
            if state.get(role) == 2:
                return
            if state.get(role) == 1:
                raise CalibrationError(f"head '{self.head}': coupling cycle {' -> '.join(chain + (role,))}")
            state[role] = 1
            coupling = self._by_role[role].coupling
            for n in coupling.neighbours if coupling else ():
                if n not in self._by_role:
                    raise CalibrationError(f"head '{self.head}': servo '{role}' is coupled to unknown role '{n}'")
                visit(n, chain + (role,))
            state[role] = 2
            order.append(role)

        for role in self._by_role:
            visit(role, ())
        return order

    # ---- lookup --------------------------------------------------------------------------------------
    @property
    def roles(self) -> tuple[str, ...]:
        """Roles in file order (the column order of the batch arrays)."""
        return self._roles

    @property
    def ids(self) -> tuple[int, ...]:
        """Servo ids in the same order as :attr:`roles`."""
        return self._ids

    @property
    def servos(self) -> tuple[ServoCalibration, ...]:
        return tuple(self._by_role[r] for r in self._roles)

    def __getitem__(self, role: str) -> ServoCalibration:
        try:
            return self._by_role[role]
        except KeyError:
            raise UnknownServoError(
                f"head '{self.head}': no servo with role '{role}'; known roles: {list(self._roles)}"
            ) from None

    def __contains__(self, role: object) -> bool:
        return role in self._by_role

    def __iter__(self) -> Iterator[str]:
        return iter(self._roles)

    def __len__(self) -> int:
        return len(self._roles)

    def by_id(self, servo_id: int) -> ServoCalibration:
        try:
            return self._by_id[servo_id]
        except KeyError:
            raise UnknownServoError(
                f"head '{self.head}': no servo with id {servo_id}; known ids: {sorted(self._by_id)}"
            ) from None

    def role_of(self, servo_id: int) -> str:
        return self.by_id(servo_id).role

    def id_of(self, role: str) -> int:
        return self[role].servo_id

    def neutral_goals(self) -> dict[int, int]:
        """id -> neutral tick for every servo."""
        return {s.servo_id: s.neutral_tick for s in self.servos}

    def neutral_targets(self) -> dict[str, float]:
        """role -> target at the neutral tick."""
        return {s.role: s.neutral_target for s in self.servos}

    def position_limits_tick(self, margin_tick: int = 0) -> dict[int, tuple[int, int]]:
        """id -> (Min Position Limit, Max Position Limit) to write to EEPROM as the servo-side backstop."""
        return {s.servo_id: s.position_limits_tick(margin_tick) for s in self.servos}

    # ---- mapping form -------------------------------------------------------------------------------
    def targets_to_goals(self, targets: Mapping[str, float]) -> dict[int, int]:
        """Role -> target (deg/mm) into id -> goal tick, for the roles given.

        Coupled servos need their neighbours' ticks: a neighbour not in ``targets`` is taken at its
        neutral tick. All-or-nothing: raises on the first unknown role or refused target.
        """
        row = self._neutral_target_row.copy()
        cols = [self._column(role) for role in targets]
        row[0, cols] = [float(v) for v in targets.values()]
        ticks = self.targets_to_goals_array(row)[0]
        return {self._ids[j]: int(ticks[j]) for j in cols}

    def columns(self, roles: Iterable[str]) -> NDArray[np.int64]:
        """The batch-array column of each role (:attr:`roles` order); raises on an unknown role."""
        return np.array([self._column(role) for role in roles], dtype=np.int64)

    def column_goals(self, cols: NDArray[np.int64], values: ArrayLike) -> NDArray[np.int64]:
        """`targets_to_goals` with the targets as an array: ``values[k]`` for the role of column ``cols[k]``
        (see `columns`) -> the goal ticks of those columns, (len(cols),) int64. The same arithmetic
        without the dicts (a control frame's path); neighbours not given sit at neutral. Without coupled
        servos, one row through `CurveBank.to_ticks_row` (the same arithmetic, fewer numpy calls)."""
        if not self._coupled:
            flat = self._neutral_target_row[0].copy()
            flat[cols] = values
            return np.asarray(self._bank.to_ticks_row(flat)[cols], dtype=np.int64)
        row = self._neutral_target_row.copy()
        row[0, cols] = values
        return np.asarray(self.targets_to_goals_array(row)[0, cols], dtype=np.int64)

    def column_goals_plain(self, cols: NDArray[np.int64], values: ArrayLike) -> NDArray[np.int64]:
        """`column_goals` through the batch path (the straightforward form; tests compare the two)."""
        row = self._neutral_target_row.copy()
        row[0, cols] = values
        return np.asarray(self.targets_to_goals_array(row)[0, cols], dtype=np.int64)

    def goals_to_targets(self, goals: Mapping[int, int], *, clip: bool = False) -> dict[str, float]:
        """Id -> goal tick into role -> target; coupled servos use their neighbours' goals (or neutral)."""
        row = self._neutral_tick_row.copy()
        cols = [self._index[self.by_id(servo_id).role] for servo_id in goals]
        row[0, cols] = [float(v) for v in goals.values()]
        targets = self.goals_to_targets_array(row, clip=clip)[0]
        return {self._roles[j]: float(targets[j]) for j in cols}

    def _column(self, role: str) -> int:
        self[role]  # raises UnknownServoError naming the known roles
        return self._index[role]

    # ---- batch (array) form ------------------------------------------------------------------------
    def targets_to_goals_array(self, targets: ArrayLike) -> NDArray[np.int64]:
        """(n, S) targets in :attr:`roles` order -> (n, S) int64 goal ticks in the same column order.

        All-or-nothing: the first non-finite or out-of-range target raises, naming its servo.
        """
        t = np.asarray(targets, dtype=np.float64)
        if t.ndim != 2 or t.shape[1] != len(self._roles):
            raise CalibrationError(
                f"head '{self.head}': expected targets of shape (n, {len(self._roles)}) in role order, got {t.shape}"
            )
        if not self._coupled:
            return self._bank.to_ticks(t)
        plain = t.copy()
        plain[:, self._coupled] = self._neutral_target_row[0, self._coupled]
        out = self._bank.to_ticks(plain)
        for role in self._order:
            s = self._by_role[role]
            if s.coupling is not None:
                j = self._index[role]
                others = np.stack([out[:, self._index[n]] for n in s.coupling.neighbours], axis=1)
                out[:, j] = self._coupled_ticks(s, t[:, j], others.astype(np.float64))
        return out

    def goals_to_targets_array(self, goals: ArrayLike, *, clip: bool = False) -> NDArray[np.float64]:
        """(n, S) goal ticks in :attr:`roles` order -> (n, S) targets (deg/mm).

        Refuses non-finite ticks and, unless ``clip``, ticks outside a servo's limits (naming it).
        """
        k = np.asarray(goals, dtype=np.float64)
        if k.ndim != 2 or k.shape[1] != len(self._roles):
            raise CalibrationError(
                f"head '{self.head}': expected goals of shape (n, {len(self._roles)}) in role order, got {k.shape}"
            )
        out = self._bank.to_targets(k, clip=clip)
        for j in self._coupled:
            s = self.servos[j]
            if s.coupling is not None:
                cols = [np.clip(k[:, j], s.min_tick, s.max_tick)] + [
                    np.clip(k[:, self._index[n]], self._by_role[n].min_tick, self._by_role[n].max_tick)
                    for n in s.coupling.neighbours
                ]
                out[:, j] = s.coupling.map.evaluate(np.stack(cols, axis=1))
        return out

    @staticmethod
    def _coupled_ticks(
        s: ServoCalibration, targets: NDArray[np.float64], others: NDArray[np.float64]
    ) -> NDArray[np.int64]:
        """Ticks of a coupled servo for its targets, given its neighbours' ticks (rows of ``others``)."""
        if s.coupling is None:  # pragma: no cover - callers check
            return s.to_ticks(targets)
        if not np.all(np.isfinite(targets)):
            value = float(targets[np.argmax(~np.isfinite(targets))])
            raise TargetOutOfRangeError(s.role, value, s.min_target, s.max_target, s.unit)
        points = np.hstack([np.zeros((targets.shape[0], 1)), others])
        ends = []
        for end_tick in (s.min_tick, s.max_tick):
            points[:, 0] = end_tick
            ends.append(s.coupling.map.evaluate(points))
        lo, hi = np.minimum(ends[0], ends[1]), np.maximum(ends[0], ends[1])
        bad = (targets < lo) | (targets > hi)
        if np.any(bad):
            i = int(np.argmax(bad))
            raise TargetOutOfRangeError(s.role, float(targets[i]), float(lo[i]), float(hi[i]), s.unit)
        try:
            solved = s.coupling.map.solve_axis(targets, points, 0, float(s.min_tick), float(s.max_tick))
        except CurveError as err:
            raise CurveError(f"servo '{s.role}': {err}") from err
        return np.clip(round_ticks(solved), s.min_tick, s.max_tick)
