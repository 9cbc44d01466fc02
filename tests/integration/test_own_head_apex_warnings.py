"""`servoface check` warns of a library expression whose apex the twin gate refuses as a pose: played on the
head, the gate would hold the face short of it (a coupling rule, skin strain, a collision)."""

from __future__ import annotations

from pathlib import Path

import pytest
from servoface.controller.cli import main


def _edit(file: Path, old: str, new: str) -> None:
    text = file.read_text()
    assert old in text, f"test setup: {old!r} not in {file.name}"
    file.write_text(text.replace(old, new, 1))


def test_a_derived_direct_table_that_breaks_a_coupling_rule_is_named(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The human copy's direct table (derived one AU at a time, its rows summed) pulls a smile's mouth corner
    up and down harder than the head's own coupling rule allows: `play happiness` is held by the gate, and
    `check` now says so, naming the expression and the rule, before a run shows it."""
    folder = tmp_path / "head"
    assert main(["new", "--from", "human", str(folder)]) == 0
    _edit(folder / "head.toml", '# au_direct = "direct.toml"', 'au_direct = "direct.toml"')
    assert main(["calibrate", "--head", str(folder), "--builtin"]) == 0
    capsys.readouterr()
    assert main(["check", str(folder)]) == 0  # a warning, not a problem: the gate keeps the head safe
    out = capsys.readouterr().out
    warnings = [line for line in out.splitlines() if line.startswith("warning: library expression")]
    assert any(
        "'happiness' at its apex breaks [coupling] rule 'one mouth corner cannot be pulled up and down hard at "
        "once'" in w
        for w in warnings
    ), out
    assert all("the twin gate holds the face short of it" in w for w in warnings)

    # the same folder without the direct table: the muscle model's smile keeps to the rule, no warning
    _edit(folder / "head.toml", 'au_direct = "direct.toml"', '# au_direct = "direct.toml"')
    assert main(["check", str(folder)]) == 0
    assert "warning: library expression" not in capsys.readouterr().out


@pytest.mark.parametrize("head", ["human", "dog"])
def test_the_built_in_libraries_pass_the_gate_at_their_apex(head: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", head]) == 0
    assert "warning: library expression" not in capsys.readouterr().out
