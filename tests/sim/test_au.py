"""AU tables: data files with a source per row, L/R handling, counters, validation and antagonists."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
from servoface.sim.au import AU_DIR, AUMapping, canonical_au_name, load_au_table
from servoface.sim.errors import ActionUnitValueError, HeadProfileError, UnknownActionUnitError

HUMAN_REQUIRED = {1, 2, 4, 5, 6, 7, 9, 10, 12, 14, 15, 16, 17, 20, 23, 24, 25, 26, 27, 43, 45}
HUMAN_REQUIRED |= set(range(51, 59)) | set(range(61, 65))

# TEAM.md "Face contract"
HUMAN_MUSCLES = {
    f"{base}_{s}"
    for base in (
        "frontalis_medial", "frontalis_lateral", "corrugator", "orbicularis_oculi", "levator_labii_alaeque",
        "levator_labii", "zygomatic_major", "buccinator", "depressor_anguli", "depressor_labii", "risorius",
    )
    for s in "lr"
} | {"procerus", "mentalis", "orbicularis_oris"}  # fmt: skip
HUMAN_JOINTS = {"neck_pan", "neck_tilt", "neck_roll", "jaw"} | {
    f"{b}_{s}" for b in ("eye_pan", "eye_tilt", "upper_lid", "lower_lid") for s in "lr"
}
DOG_MUSCLES = {
    f"{b}_{s}"
    for b in ("levator_nasolabialis", "zygomaticus", "nostril_dilator", "levator_anguli_oculi", "frontalis",
              "auricularis_rostralis")
    for s in "lr"
} | {"levator_nasi", "orbicularis_oris"}  # fmt: skip
DOG_JOINTS = {"neck_pitch", "neck_yaw", "neck_roll", "jaw", "jaw_lateral", "tongue_extend", "tongue_tip"} | {
    f"{b}_{s}" for b in ("eye_pan", "eye_tilt", "upper_lid", "ear_pan", "ear_tilt") for s in "lr"
}


def _mapping(face_type: str) -> AUMapping:
    muscles, joints = (HUMAN_MUSCLES, HUMAN_JOINTS) if face_type == "human" else (DOG_MUSCLES, DOG_JOINTS)
    return AUMapping(load_au_table(face_type), sorted(muscles), sorted(joints))


def _muscle(mapping: AUMapping, aus: dict[str, float], name: str) -> float:
    return float(mapping.evaluate(aus)[0][mapping.muscle_names.index(name)])


def _joint(mapping: AUMapping, aus: dict[str, float], name: str) -> float:
    return float(mapping.evaluate(aus)[1][mapping.joint_names.index(name)])


@pytest.mark.parametrize("face_type", ["human", "dog"])
def test_every_row_of_the_data_file_has_a_source(face_type: str) -> None:
    raw = tomllib.loads((AU_DIR / f"{face_type}.toml").read_text(encoding="utf-8"))
    rows = {k: v for k, v in raw.items() if k.startswith("AU")}
    assert len(rows) >= 19
    for key, row in rows.items():
        assert isinstance(row.get("source"), str) and len(row["source"]) > 10, key
        assert "§" in row["source"] or "Table" in row["source"], key


def test_the_human_table_covers_the_required_aus_with_sides() -> None:
    table = load_au_table("human")
    assert HUMAN_REQUIRED <= set(table.entries)
    names = table.names()
    assert {"AU12L", "AU12R", "AU1L", "AU4R", "AU45L"} <= names
    assert "AU26L" not in names and "AU51L" not in names
    assert table.intensity == (0.0, 1.0)


def test_the_dog_table_has_dfacs_1_to_19_and_its_counters() -> None:
    table = load_au_table("dog")
    assert set(table.entries) == set(range(1, 20))
    assert table.intensity == (-1.0, 1.0)
    no_counter = {n for n, e in table.entries.items() if e.range[0] >= 0.0}
    assert no_counter == {15, 16}  # blink and lick (dfacs-dog.md §1)
    assert table.entries[5].counter is not None and table.entries[5].counter.name == "Backward ears"


@pytest.mark.parametrize(("face_type", "muscles", "joints"), [("human", HUMAN_MUSCLES, HUMAN_JOINTS),
                                                               ("dog", DOG_MUSCLES, DOG_JOINTS)])  # fmt: skip
def test_tables_name_only_face_contract_muscles_and_joints(face_type: str, muscles: set[str], joints: set[str]) -> None:
    mapping = _mapping(face_type)  # raises HeadProfileError on any unknown name
    used_muscles = {mapping.muscle_names[i] for i in np.nonzero(np.abs(mapping.to_muscles).sum(axis=1))[0]}
    used_joints = {mapping.joint_names[i] for i in np.nonzero(np.abs(mapping.to_joints).sum(axis=1))[0]}
    assert used_muscles == muscles  # every contract muscle is driven by some AU
    assert used_joints == joints


def test_bilateral_au_drives_both_sides_and_a_sided_au_one() -> None:
    m = _mapping("human")
    assert _muscle(m, {"AU12": 0.6}, "zygomatic_major_l") == pytest.approx(0.6)
    assert _muscle(m, {"AU12": 0.6}, "zygomatic_major_r") == pytest.approx(0.6)
    assert _muscle(m, {"AU12L": 0.6}, "zygomatic_major_r") == 0.0
    assert _muscle(m, {"AU12L": 0.6}, "zygomatic_major_l") == pytest.approx(0.6)
    # a centre muscle in a sided AU takes half from each side
    assert _muscle(m, {"AU4L": 1.0}, "procerus") == pytest.approx(0.4)
    assert _muscle(m, {"AU4": 1.0}, "procerus") == pytest.approx(0.8)


def test_antagonists_sum_then_clamp() -> None:
    m = _mapping("human")
    assert _joint(m, {"AU5": 1.0}, "upper_lid_l") == pytest.approx(-15.0)
    assert _joint(m, {"AU5": 1.0, "AU45": 1.0}, "upper_lid_l") == pytest.approx(55.0)  # clamp happens in FaceModel
    assert _joint(m, {"AU51": 1.0, "AU52": 0.5}, "neck_pan") == pytest.approx(22.5)
    assert _muscle(m, {"AU12": 1.0, "AU13": 1.0}, "zygomatic_major_l") == 1.0  # contraction limit
    assert _muscle(m, {"AU12": 0.5, "AU12L": 0.3}, "zygomatic_major_l") == pytest.approx(0.8)


def test_dog_counter_aus_use_their_own_row_or_mirror() -> None:
    m = _mapping("dog")
    assert _joint(m, {"AU5": 1.0}, "ear_pan_l") == pytest.approx(30.0)
    assert _joint(m, {"AU5": -1.0}, "ear_pan_l") == pytest.approx(-50.0)  # issue 11: about x, back and flat
    assert _joint(m, {"AU5R": -0.5}, "ear_pan_r") == pytest.approx(-25.0)
    assert _joint(m, {"AU5R": -0.5}, "ear_pan_l") == 0.0
    assert _muscle(m, {"AU1": -1.0}, "levator_nasolabialis_l") == pytest.approx(-0.3)
    assert _joint(m, {"AU19": -1.0}, "tongue_tip") == pytest.approx(35.0)  # mirrored counter (name lost)
    assert _joint(m, {"AU5": 1.0, "AU5L": -1.0}, "ear_pan_l") == 0.0  # signed channel sums to zero


@pytest.mark.parametrize(
    ("face_type", "aus", "error", "words"),
    [
        ("human", {"AU3": 0.5}, UnknownActionUnitError, ["AU3", "known", "AU12"]),
        ("human", {"AU26R": 0.5}, UnknownActionUnitError, ["AU26R", "left/right"]),
        ("human", {"-AU7": 0.5}, UnknownActionUnitError, ["-AU7", "negative value"]),
        ("human", {"AU12": float("inf")}, ActionUnitValueError, ["AU12", "[0.0, 1.0]"]),
        ("human", {"AU12": None}, ActionUnitValueError, ["AU12"]),
        ("dog", {"AU20": 0.5}, UnknownActionUnitError, ["AU20", "dog"]),
        ("dog", {"AU7": -1.2}, ActionUnitValueError, ["AU7", "[-1.0, 1.0]"]),
        ("dog", {"AU15": -0.5}, ActionUnitValueError, ["AU15", "no counter"]),
        ("dog", {"AU16": float("nan")}, ActionUnitValueError, ["AU16"]),
    ],
)
def test_bad_aus_raise_typed_errors(face_type: str, aus: dict[str, object], error: type, words: list[str]) -> None:
    m = _mapping(face_type)
    with pytest.raises(error) as info:
        m.evaluate(aus)  # type: ignore[arg-type]
    for word in words:
        assert word in str(info.value)


def test_au_names_are_canonicalised() -> None:
    assert canonical_au_name("AU12") == (12, "")
    assert canonical_au_name("au12l") == (12, "L")
    assert canonical_au_name(" AU01R ") == (1, "R")
    m = _mapping("human")
    assert _muscle(m, {"au01": 1.0}, "frontalis_medial_l") == pytest.approx(1.0)


def _write(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "table.toml"
    head = 'schema_version = 1\nface_type = "human"\nintensity = [0.0, 1.0]\ncontraction = [0.0, 1.0]\n'
    path.write_text(head + body, encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("body", "words"),
    [
        ('[AU1]\nmuscles = { "x" = 1.0 }\n', ["AU1.source"]),
        ('[AU1]\nsource = "s"\nmusles = {}\n', ["AU1", "musles"]),
        ('[AU1]\nsource = "s"\nmuscles = { "x_{side}" = 1.0 }\n', ["AU1", "{side}", "not sided"]),
        ('[AU1]\nsource = "s"\nmuscles = { "x" = "big" }\n', ["AU1.muscles.x", "finite number"]),
        ('[AU1]\nsource = "s"\nrange = [1.0, 0.0]\n', ["AU1.range"]),
        ('[AU1]\nsource = "s"\n[AU1.counter]\njoints = { "jaw" = 1.0 }\n', ["AU1.counter", "negative range"]),
        ('[smile]\nsource = "s"\n', ["'smile'", "AU row"]),
        ("", ["no AU rows"]),
    ],
)
def test_table_file_errors_name_the_file_and_key(tmp_path: Path, body: str, words: list[str]) -> None:
    path = _write(tmp_path, body)
    with pytest.raises(HeadProfileError) as info:
        load_au_table(path)
    assert str(path) in str(info.value)
    for word in words:
        assert word in str(info.value)


def test_a_table_naming_a_missing_muscle_is_noted_or_strictly_refused(tmp_path: Path) -> None:
    table = load_au_table(_write(tmp_path, '[AU1]\nsource = "s"\nmuscles = { "nasalis" = 1.0 }\n'))
    with pytest.raises(HeadProfileError, match="nasalis.*known muscles"):
        AUMapping(table, ["procerus"], [], allow_missing=False)
    mapping = AUMapping(table, ["procerus"], [])
    assert mapping.missing == {"nasalis"}
    assert mapping.unreachable == {1: "muscle nasalis is not in the head"}
    with pytest.raises(HeadProfileError, match="not found"):
        load_au_table(tmp_path / "nope.toml")


@pytest.mark.parametrize("face_type", ["human", "dog"])
def test_table_names_match_the_controllers_fallback_sets(face_type: str) -> None:
    """The controller validates frames with these names when it cannot load a table: keep them equal."""
    from servoface.controller.au_names import builtin_au_names

    assert load_au_table(face_type).names() == builtin_au_names(face_type)  # type: ignore[arg-type]
