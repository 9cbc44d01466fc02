"""`validate_aus`' fast path (a canonical name with a float in range, taken as is) gives exactly what the
full checks give: the same frame, or the same error, on random frames with odd names and values."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pytest
from servoface.controller.au_names import au_ranges, default_au_names, intensity_range
from servoface.controller.errors import FrameError
from servoface.controller.frame import MAX_AUS, _shown, canonical_au, check_intensity, validate_aus


def _reference(aus: Mapping[Any, Any], face_type: Any) -> dict[str, float]:
    """validate_aus as it was, every entry through the full checks."""
    lo, hi = intensity_range(face_type)
    names = default_au_names(face_type)
    ranges = au_ranges(face_type)
    out: dict[str, float] = {}
    if len(aus) > MAX_AUS:
        raise FrameError(f"aus: {len(aus)} entries; an AU frame has at most {MAX_AUS}")
    for raw, value in aus.items():
        shown = raw if isinstance(raw, str) and raw.isprintable() and len(raw) <= 40 else _shown(raw)
        field = str(shown)
        name = raw if raw in names else canonical_au(raw, field=field)
        if name not in names:
            raise FrameError(f"{field}: {name} is not an AU of the {face_type} face; expected one of {_sample(names)}")
        if name in out:
            raise FrameError(f"{field}: {name} is given twice (names are case-insensitive)")
        kind = "DFACS intensity" if face_type == "dog" else "FACS intensity"
        a, b = ranges.get(name, (lo, hi))
        out[name] = check_intensity(value, field=field, lo=a, hi=b, what=kind)
    return out


def _sample(names: frozenset[str]) -> str:
    from servoface.controller.frame import _sample as sample

    return sample(names)


def _outcome(f: Any, aus: dict[Any, Any]) -> tuple[str, Any]:
    try:
        return "ok", list(f(aus).items())
    except FrameError as err:
        return "error", str(err)


@pytest.mark.parametrize("face_type", ["human", "dog"])
def test_fast_path_gives_what_the_full_checks_give(face_type: str) -> None:
    names: list[Any] = sorted(default_au_names(face_type))
    names += ["au12", "AU012", "AU12 ", "AU999", "", 12, "AU4L"]
    lo, hi = intensity_range(face_type)
    odd: list[Any] = [float("nan"), float("inf"), lo - 0.1, hi + 0.1, True, 1, np.float64(0.4), "0.3", None, -0.0]
    rng = np.random.default_rng(21)
    kinds = {"ok": 0, "error": 0}
    for _ in range(1500):
        aus: dict[Any, Any] = {}
        for _ in range(int(rng.integers(0, 7))):
            name = names[int(rng.integers(len(names)))]
            value = float(rng.uniform(lo - 0.05, hi + 0.05))
            aus[name] = odd[int(rng.integers(len(odd)))] if rng.random() < 0.1 else value
        got = _outcome(lambda a: validate_aus(a, face_type), aus)
        assert got == _outcome(lambda a: _reference(a, face_type), aus), aus
        kinds[got[0]] += 1
    assert kinds["ok"] > 200 and kinds["error"] > 200
