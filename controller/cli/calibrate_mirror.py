"""`servoface calibrate --mirror SRC:DST[,SRC:DST]`: derive servos as mirror images of measured ones
(DST = SRC reflected about its neutral tick) instead of measuring them."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from servoface.calibration.spec import ServoSpec


def parse_mirror(text: str, specs: list[ServoSpec]) -> list[tuple[str, str]]:
    """``"a_l:a_r,b_l:b_r"`` -> [("a_l", "a_r"), ...]; both roles must be servos of the head."""
    known = {s.role for s in specs}
    pairs = []
    for part in filter(None, (p.strip() for p in text.split(","))):
        src, sep, dst = (x.strip() for x in part.partition(":"))
        if not sep or not src or not dst or src == dst:
            raise ValueError(f"{part!r}: expected SRC:DST with two different roles")
        for role in (src, dst):
            if role not in known:
                raise ValueError(f"unknown role {role!r}; the head has {sorted(known)}")
        pairs.append((src, dst))
    if len({d for _, d in pairs}) != len(pairs) or {d for _, d in pairs} & {s for s, _ in pairs}:
        raise ValueError(f"{text!r}: each DST once, and never also a SRC")
    return pairs


def apply_mirror(cal: Any, pairs: list[tuple[str, str]], specs: list[ServoSpec]) -> Any:
    """Add/replace each DST servo by the mirror image of its SRC; servos ordered as in the head."""
    from servoface.calibration.head import HeadCalibration
    from servoface.calibration.mirror import mirror_servo

    by_role = {s.role: s for s in cal.servos}
    spec_of = {s.role: s for s in specs}
    for src, dst in pairs:
        by_role[dst] = mirror_servo(cal[src], dst, spec_of[dst].servo_id, spec_of[dst].model)
    order = [s.role for s in specs if s.role in by_role] + [r for r in by_role if r not in spec_of]
    return HeadCalibration(cal.head, [by_role[r] for r in order], cal.metadata)
