"""Heads of any shape, brought up as a builder would: written by hand (or by `servoface new`), calibrated
from a CSV, checked, previewed and played on the emulated chain.

- three non-built-in heads (tests/integration/own_heads.py): each passes `check`, previews, plays library
  expressions on the emulator, and its `check` report lists exactly the AUs it cannot show;
- the default preview of a head whose servos cannot smile does not show a smile (its mouth corners are
  where the achievable pose puts them, not where the muscle model wants them);
- `servoface new` -> `calibrate --csv` -> `check` -> `play` from an empty folder, each step naming the next.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from servoface.controller.cli import main
from servoface.controller.new_head import TEMPLATE_CSV, write_template_csv

from tests.integration import own_heads as oh

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

HEADS = {
    "mechanical": (oh.write_mechanical, oh.MECH_CAN_SHOW, ["happiness", "surprise"]),
    "few_anchors": (oh.write_skin, oh.SKIN_CAN_SHOW, ["surprise", "happiness"]),
    "metres": (oh.write_dog_in_metres, oh.DOG_CAN_SHOW, ["fear", "attention"]),
}


def _calibrated(tmp_path: Path, kind: str) -> Path:
    writer = HEADS[kind][0]
    folder = writer(tmp_path / kind)
    csv = write_template_csv(folder)
    assert main(["calibrate", "--head", str(folder), "--csv", str(csv)]) == 0
    return folder


@pytest.mark.parametrize("kind", sorted(HEADS))
def test_own_head_checks_previews_and_plays(kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _calibrated(tmp_path, kind)
    capsys.readouterr()
    report = tmp_path / "report.json"
    status = main(["check", str(folder), "--json", str(report)])
    out, err = capsys.readouterr()
    assert status == 0, out + err
    assert "Traceback" not in err and out.splitlines()[-1].startswith("ok: next")
    data = json.loads(report.read_text())
    cases = {a["name"] for a in data["aus"]}
    expected = sorted(cases - HEADS[kind][1], key=lambda n: [a["name"] for a in data["aus"]].index(n))
    assert data["cannot_show"] == expected  # exactly the AUs it cannot show
    assert f"cannot show ({len(expected)}): {', '.join(expected)}" in out
    for entry in data["aus"]:
        if entry["cannot_show"]:
            assert entry["reasons"], entry  # each with its reason
    for row in data["expressions"]:  # an expression is scored as a whole: the AUs a head lacks count against it
        assert row["shown_overall"] == pytest.approx(row["shown"] * row["au_share"], abs=2e-3), row
        assert (row["au_share"] < 1.0) == bool(row["aus_it_cannot_show"]), row
    if kind == "mechanical":  # no smile on this head: its happiness is not "100 %"
        happiness = next(r for r in data["expressions"] if r["name"] == "happiness")
        assert happiness["aus_it_cannot_show"] == ["AU6", "AU12"] and happiness["shown_overall"] < 0.25
    # preview: a still and the sheet, the achievable face by default
    still = tmp_path / "still.png"
    assert main(["preview", HEADS[kind][2][0], "--head", str(folder), "-o", str(still)]) == 0
    img = np.asarray(Image.open(still).convert("RGB"))
    assert img.shape == (480, 640, 3) and img.std() > 5
    sheet = tmp_path / "sheet.png"
    assert main(["preview", "--all", "--head", str(folder), "-o", str(sheet), "--quiet", "--size", "160x120"]) == 0
    # play library expressions on the emulated chain
    for name in HEADS[kind][2]:
        trace = tmp_path / f"{name}.jsonl"
        capsys.readouterr()
        status = main(["play", name, "--head", str(folder), "--emulate", "--hold", "0.3", "--trace", str(trace)])
        out, err = capsys.readouterr()
        assert status == 0, out + err
        frames = [json.loads(line) for line in trace.read_text().splitlines()]
        assert frames and all(f["verdict"] in ("accept", "clip") for f in frames)
        moved = {sid for f in frames for sid, tick in f["goals_sent"].items() if tick != frames[0]["goals_sent"][sid]}
        if name == HEADS[kind][2][0]:  # the first one moves this head (the second may be one it cannot show)
            assert moved, f"{name} moved no servo of {kind}"


def test_the_mechanical_brows_follow_the_direct_table(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _calibrated(tmp_path, "mechanical")
    trace = tmp_path / "surprise.jsonl"
    assert main(["play", "surprise", "--head", str(folder), "--emulate", "--hold", "0.4", "--trace", str(trace)]) == 0
    frames = [json.loads(line) for line in trace.read_text().splitlines()]
    brow_l = [f["targets"]["brow_l"] for f in frames]
    assert max(brow_l) > 10.0  # AU1 + AU2 of surprise: 10 + 14 deg, clamped to the brow's 18 deg stop
    assert max(brow_l) <= 18.0 + 1e-6


def test_default_preview_of_a_head_that_cannot_smile_shows_no_smile(tmp_path: Path) -> None:
    from servoface.sim.achievable import AchievableFace
    from servoface.sim.heads import load_head
    from servoface.sim.kinematics import neutral_pose, posed_skin_vertices
    from servoface.sim.render.renderer import HeadRenderer
    from servoface.sim.render.twin import face_model

    folder = _calibrated(tmp_path, "few_anchors")
    head = load_head(folder)
    smile = {"AU12": 1.0}
    rest = posed_skin_vertices(head, neutral_pose(head))
    corners = [int(np.argmin(np.linalg.norm(rest - np.array(head.landmarks_mm[n]), axis=1))) for n in
               ("mouth_corner_l", "mouth_corner_r")]  # fmt: skip
    target = face_model(head).solve(smile)
    achieved = AchievableFace(head).still(smile).pose
    lift_target = posed_skin_vertices(head, target)[corners] - rest[corners]
    lift_achieved = posed_skin_vertices(head, achieved)[corners] - rest[corners]
    assert np.linalg.norm(lift_target, axis=1).min() > 3.0  # the muscle model smiles ...
    assert lift_target[:, 1].min() > 1.0
    assert np.linalg.norm(lift_achieved, axis=1).max() < 0.05  # ... the servos cannot

    shown = tmp_path / "default.png"
    wish = tmp_path / "target.png"
    assert main(["preview", "happiness", "--head", str(folder), "-o", str(shown), "--size", "320x240"]) == 0
    assert main(["preview", "happiness", "--head", str(folder), "-o", str(wish), "--size", "320x240",
                 "--show", "target"]) == 0  # fmt: skip
    with HeadRenderer(320, 240) as renderer:
        from servoface.sim.expressions import load_library

        apex = load_library("human")["happiness"].apex()
        want_achieved = renderer.render(head, AchievableFace(head).still(apex).pose)
        want_target = renderer.render(head, face_model(head).solve(apex))
    got = np.asarray(Image.open(shown).convert("RGB")).astype(int)
    got_target = np.asarray(Image.open(wish).convert("RGB")).astype(int)
    assert np.abs(got - want_achieved).mean() < 0.5  # the default preview draws the achievable pose
    assert np.abs(got - want_target).mean() > 2 * np.abs(got - want_achieved).mean() + 0.3
    assert np.abs(got_target - want_target).mean() < 0.5  # --show target still draws the wish


def test_new_calibrate_check_play_from_an_empty_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "my_head"
    folder.mkdir()
    assert main(["new", str(folder), "--from", "mechanical"]) == 0
    out = capsys.readouterr().out
    assert f"servoface calibrate --head {folder} --csv {folder / TEMPLATE_CSV}" in out  # names the next step
    assert (folder / "head.toml").is_file() and (folder / TEMPLATE_CSV).is_file()
    assert main(["new", str(folder), "--from", "mechanical"]) == 2  # never overwrites silently
    assert "--force" in capsys.readouterr().err

    assert main(["check", str(folder)]) == 1  # not calibrated yet: says how
    out = capsys.readouterr().out
    assert "no calibration file" in out and f"servoface calibrate --head {folder}" in out

    assert main(["calibrate", "--head", str(folder), "--csv", str(folder / TEMPLATE_CSV)]) == 0
    out = capsys.readouterr().out
    assert f"next: servoface check {folder}" in out and (folder / "calibration.json").is_file()

    assert main(["check", str(folder)]) == 0
    out = capsys.readouterr().out
    assert "cannot show (" in out and out.splitlines()[-1].startswith("ok: next")

    assert main(["play", "happiness", "--head", str(folder), "--emulate", "--hold", "0.3"]) == 0
    out = capsys.readouterr().out
    assert "frames; verdicts" in out
    assert "this head cannot show AU6, AU12" in out  # happiness without its smile: said, not hidden


def test_new_from_human_keeps_the_builtin_face_and_derives_a_direct_table(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from servoface.sim.au.direct import load_direct_table
    from servoface.sim.face_model import FaceModel
    from servoface.sim.heads import load_head

    folder = tmp_path / "copy"
    assert main(["new", str(folder), "--from", "human"]) == 0
    head = load_head(folder)
    assert head.name == "copy" and head.au_direct_path is None
    assert [a.role for a in head.actuators] == [a.role for a in load_head("human").actuators]
    table = load_direct_table(folder / "direct.toml")
    assert {1, 12, 26, 51} <= set(table.rows)
    # switched on, the derived table reproduces the muscle model's actuator targets for one AU alone
    muscle = FaceModel(head).solve({"AU26": 1.0, "AU1L": 1.0}).actuator_targets
    direct = FaceModel(head, direct=table).solve({"AU26": 1.0, "AU1L": 1.0}).actuator_targets
    for role, value in muscle.items():
        assert direct[role] == pytest.approx(value, abs=0.02), role


def test_a_copy_of_the_human_head_without_lower_lids_needs_no_dummy_parts(tmp_path: Path) -> None:
    """The builder's first wall (issue 10): removing joints the built-in AU table names is not an error."""
    from servoface.sim.face_model import FaceModel
    from servoface.sim.heads import load_head

    folder = tmp_path / "lidless"
    assert main(["new", str(folder), "--from", "human"]) == 0
    blocks = (folder / "head.toml").read_text().split("\n\n")

    def code(block: str) -> str:
        return "\n".join(line for line in block.splitlines() if not line.lstrip().startswith("#"))

    kept = [b for b in blocks if "lower_lid" not in code(b)]  # the lower-lid joints, parts and servos
    (folder / "head.toml").write_text("\n\n".join(kept))
    head = load_head(folder)
    assert not any("lower_lid" in j.name for j in head.joints)
    model = FaceModel(head)
    assert {"lower_lid_l", "lower_lid_r"} <= model.mapping.missing
    assert "joints lower_lid_l, lower_lid_r are not in the head" in " ".join(model.mapping.notes[6])
    assert np.abs(model.solve({"AU6": 1.0}).skin_offset_mm).max() > 0.5  # the cheek still rises


def test_demo_plays_any_head_and_draws_what_the_servos_make(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import functools

    import servoface.controller.demo as demo

    folder = _calibrated(tmp_path, "mechanical")
    quick = functools.partial(demo.head_performance, onset_s=0.15, apex_s=0.2, offset_s=0.15, limit=3)
    monkeypatch.setattr(demo, "head_performance", quick)
    out_dir = tmp_path / "demo"
    capsys.readouterr()
    status = main(["demo", "--head", str(folder), "--out", str(out_dir), "--format", "gif"])
    out, err = capsys.readouterr()
    assert status == 0, out + err
    report = json.loads((out_dir / "report.json").read_text())
    assert report["head"] == "tinbot" and report["shown"] == "achievable"
    assert "3 of 13 library expressions it can show" in report["title"]
    assert report["frames"] > 20 and report["verdicts"].get("reject", 0) == 0
    gif = Image.open(out_dir / "twin.gif")
    assert gif.size[0] == 360  # one face per frame (the servos'), not target | gated side by side
    sheet = np.asarray(Image.open(out_dir / "sheet.png").convert("RGB"))
    assert sheet.std() > 5
