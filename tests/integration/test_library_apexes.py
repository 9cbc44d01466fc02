"""Every shipped expression at full intensity, through muscle model and calibration, is a command the twin
gate accepts (`TwinGate.audit`: limits, coupling rules, skin strain, exact collisions on every pair).

Known refusals are strict xfails naming the rule, so the list shrinks (and this file fails) when they are
fixed. Both heads are checked with every part pair (the dog's TSS tables take ~15 s to build cold)."""

from __future__ import annotations

import pytest
from servoface.controller.face import Face
from servoface.controller.pipeline import Pipeline
from servoface.sim.expressions import load_library

KNOWN_REFUSED: dict[tuple[str, str], str] = {}  # (head, expression) -> why; all pass since the 13:41 tuning

_PIPELINES: dict[str, Pipeline] = {}


def _pipeline(head_name: str) -> Pipeline:
    if head_name not in _PIPELINES:
        _PIPELINES[head_name] = Face.offline(head_name).pipeline
    return _PIPELINES[head_name]


CASES = [
    pytest.param(
        head,
        name,
        marks=[pytest.mark.xfail(strict=True, reason=KNOWN_REFUSED[(head, name)])]
        if (head, name) in KNOWN_REFUSED
        else [],
        id=f"{head}-{name}",
    )
    for head in ("human", "dog")
    for name in sorted(load_library(head))
]


@pytest.mark.parametrize("head_name, name", CASES)
def test_expression_apex_passes_the_gate(head_name: str, name: str) -> None:
    p = _pipeline(head_name)
    apex = load_library(p.head.expressions_path or p.head.face_type)[name].apex()
    targets, clamps = p.clamp_targets(p.targets_for(apex))
    assert not clamps, clamps
    findings = p.gate.audit(p.calibration.targets_to_goals(targets))
    assert not findings, [f.message for f in findings]
