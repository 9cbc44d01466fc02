"""The shipped sample files are the generator's output, byte for byte (so a user can regenerate them)."""

from __future__ import annotations

from pathlib import Path

import pytest
from servoface.controller.inputs.samples import generate


def test_the_generator_writes_the_shipped_samples_into_a_folder_of_ones_choosing(tmp_path: Path) -> None:
    out = tmp_path / "new" / "samples"
    generate.main([str(out)])
    written = sorted(p.name for p in out.iterdir())
    assert written == [
        "arkit_smile.jsonl",
        "greeting.fap",
        "mediapipe_blink.csv",
        "openface_smile.csv",
        "pyfeat_surprise.csv",
    ]
    for name in written:
        assert (out / name).read_bytes() == (generate.HERE / name).read_bytes(), name


def test_the_generator_says_how_to_call_it() -> None:
    with pytest.raises(SystemExit, match="usage"):
        generate.main(["a", "b"])
