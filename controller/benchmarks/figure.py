"""One measured figure, printed by `servoface bench` next to what it is measured against."""

from __future__ import annotations

import json
import os
import platform
from dataclasses import dataclass
from typing import Any, Literal


@dataclass(frozen=True)
class Figure:
    """A benchmark result.

    ``limit`` is what the value is compared with (e.g. the wire limit), ``goal`` the target ratio or value,
    ``ratio`` = value / limit (or limit / value for "lower is better" figures, see ``better``).
    """

    name: str
    value: float
    unit: str
    limit: float | None = None
    goal: float | None = None
    better: Literal["higher", "lower"] = "higher"
    note: str = ""

    @property
    def ratio(self) -> float | None:
        if self.limit is None or self.limit == 0 or self.value == 0:
            return None
        return self.value / self.limit if self.better == "higher" else self.limit / self.value

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"name": self.name, "value": round(self.value, 6), "unit": self.unit}
        if self.limit is not None:
            out["limit"] = round(self.limit, 6)
        if self.goal is not None:
            out["goal"] = self.goal
        ratio = self.ratio
        if ratio is not None:
            out["ratio"] = round(ratio, 4)
        if self.note:
            out["note"] = self.note
        return out

    def to_json(self) -> str:
        return json.dumps(self.as_dict())


def machine_description() -> str:
    """A one-line description of the machine, printed with every bench run."""
    return (
        f"{platform.machine()} {os.cpu_count()} cpu, Python {platform.python_version()}, {platform.system()}"
    )
