"""Phoneme -> viseme tables and the viseme -> AU recipes (no synthesis needed)."""

from __future__ import annotations

import pytest
from servoface.controller.au_names import builtin_au_names
from servoface.controller.speech.visemes import (
    ARPABET_TO_VISEME,
    ESPEAK_TO_VISEME,
    RECIPES,
    VISEME_SHAPES,
    VISEMES,
    mouth_aus,
    shape_to_aus,
    viseme_of,
)


def test_every_table_entry_is_one_of_the_15_visemes() -> None:
    assert len(VISEMES) == 15 and set(VISEME_SHAPES) == set(VISEMES)
    assert set(ESPEAK_TO_VISEME.values()) <= set(VISEMES)
    assert set(ARPABET_TO_VISEME.values()) <= set(VISEMES)


@pytest.mark.parametrize(
    ("phoneme", "alphabet", "viseme"),
    [
        ("p", "espeak", "PP"),
        ("'m", "espeak", "PP"),
        ("f", "espeak", "FF"),
        ("tS", "espeak", "CH"),
        ("'aI", "espeak", "aa"),
        ("u:", "espeak", "ou"),
        ("_:", "espeak", "sil"),
        ("B", "arpabet", "PP"),
        ("OW1", "arpabet", "oh"),
        ("SIL", "arpabet", "sil"),
        ("TH", "arpabet", "TH"),
    ],
)
def test_phonemes_map_to_their_visemes(phoneme: str, alphabet: str, viseme: str) -> None:
    assert viseme_of(phoneme, alphabet) == viseme


def test_bilabials_close_the_lips_and_open_vowels_open_the_jaw() -> None:
    pp = shape_to_aus(VISEME_SHAPES["PP"].shape, "human")
    aa = shape_to_aus(VISEME_SHAPES["aa"].shape, "human")
    ou = shape_to_aus(VISEME_SHAPES["ou"].shape, "human")
    assert pp["AU26"] == 0 and pp["AU25"] == 0 and pp["AU24"] > 0.5
    assert aa["AU26"] > 0.7 and aa["AU25"] > 0.8
    assert ou["AU18"] > 0.6 and ou["AU26"] < aa["AU26"]
    dog = shape_to_aus(VISEME_SHAPES["aa"].shape, "dog")
    assert dog["AU7"] > 0.5


@pytest.mark.parametrize("face_type", ["human", "dog"])
def test_recipes_use_only_aus_the_face_has(face_type: str) -> None:
    assert mouth_aus(face_type) <= builtin_au_names(face_type)  # type: ignore[arg-type]
    assert set(RECIPES[face_type]) <= {"open", "part", "spread", "round", "press", "upper", "tongue"}
