"""Phoneme -> viseme -> mouth shape -> AUs.

**Visemes**: the 15 of the Oculus Lipsync set (sil, PP, FF, TH, DD, kk, CH, SS, nn, RR, aa, E, ih, oh, ou),
which refine the 14 MPEG-4 visemes of ISO/IEC 14496-2 Annex C (Pandzic & Forchheimer, *MPEG-4 Facial
Animation*, 2002, table 2.3; seed: the Deformable Avatars proceedings' MPEG-4 chapter) by one silence class.
**Phonemes**: espeak-ng's English mnemonics (``espeak-ng/phsource/ph_english``: ``p b m``, ``tS dZ``,
``aI``, ``3:``...; stress marks ``'`` and ``,`` are dropped) and ARPAbet (pocketsphinx's dictionary), both
mapped here.

**Mouth shape**: each viseme is a small vector of articulatory features (0..1) — jaw ``open``, lips
``part``, ``spread`` (risorius), ``round`` (protrusion + pucker), ``press`` (lips together), ``upper``
(upper lip raised: labiodentals), ``tongue`` (visible tongue: dentals) — after the viseme descriptions of
MPEG-4 Annex C and King's muscle-based lip model (seed: King & Parent, speech-synchronised animation).
A face type's recipe turns features into its own AUs, so the same plan drives a human and a dog head, and
a head's AU table decides which of them it can show.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

VISEMES: tuple[str, ...] = ("sil", "PP", "FF", "TH", "DD", "kk", "CH", "SS", "nn", "RR", "aa", "E", "ih", "oh", "ou")
FEATURES: tuple[str, ...] = ("open", "part", "spread", "round", "press", "upper", "tongue")


@dataclass(frozen=True)
class Viseme:
    """A viseme's mouth shape and how strongly it holds against its neighbours (coarticulation)."""

    name: str
    shape: Mapping[str, float]
    dominance: float  # Cohen-Massaro dominance: high = the neighbours bend to it (bilabial closure)
    closes_lips: bool = False


def _v(name: str, dominance: float, closes: bool = False, **shape: float) -> Viseme:
    return Viseme(name, {f: float(shape.get(f, 0.0)) for f in FEATURES}, dominance, closes)


VISEME_SHAPES: dict[str, Viseme] = {
    v.name: v
    for v in (
        _v("sil", 0.6),
        _v("PP", 3.0, True, press=0.8),
        _v("FF", 1.6, upper=0.6, part=0.35, open=0.1),
        _v("TH", 1.2, open=0.22, part=0.55, tongue=0.6),
        _v("DD", 0.7, open=0.25, part=0.5),
        _v("kk", 0.5, open=0.3, part=0.5),
        _v("CH", 1.4, open=0.2, part=0.45, round=0.6),
        _v("SS", 1.1, open=0.1, part=0.45, spread=0.45),
        _v("nn", 0.6, open=0.2, part=0.4),
        _v("RR", 0.9, open=0.2, part=0.4, round=0.45),
        _v("aa", 1.0, open=0.85, part=0.95),
        _v("E", 1.0, open=0.5, part=0.8, spread=0.35),
        _v("ih", 1.0, open=0.3, part=0.65, spread=0.55),
        _v("oh", 1.0, open=0.55, part=0.7, round=0.7),
        _v("ou", 1.1, open=0.25, part=0.4, round=1.0),
    )
}

#: espeak-ng English phoneme mnemonics -> viseme
ESPEAK_TO_VISEME: dict[str, str] = {
    # pauses
    "_": "sil",
    "_:": "sil",
    "_!": "sil",
    "_^_": "sil",
    "": "sil",
    # consonants
    "p": "PP",
    "b": "PP",
    "m": "PP",
    "f": "FF",
    "v": "FF",
    "T": "TH",
    "D": "TH",
    "t": "DD",
    "d": "DD",
    "t#": "DD",
    "d#": "DD",
    "t2": "DD",
    "d2": "DD",
    "?": "DD",
    "k": "kk",
    "g": "kk",
    "N": "kk",
    "x": "kk",
    "h": "kk",
    "tS": "CH",
    "dZ": "CH",
    "S": "CH",
    "Z": "CH",
    "S;": "CH",
    "s": "SS",
    "z": "SS",
    "n": "nn",
    "l": "nn",
    "n-": "nn",
    "l-": "nn",
    "L": "nn",
    "@L": "nn",
    "j": "ih",
    "r": "RR",
    "r-": "RR",
    "3": "RR",
    "3:": "RR",
    "R": "RR",
    "*": "DD",
    "w": "ou",
    # vowels
    "a": "aa",
    "a#": "aa",
    "a:": "aa",
    "A:": "aa",
    "A@": "aa",
    "aI": "aa",
    "aU": "aa",
    "aI@": "aa",
    "aU@": "aa",
    "V": "aa",
    "A": "aa",
    "aa": "aa",
    "e": "E",
    "e@": "E",
    "eI": "E",
    "E": "E",
    "E2": "E",
    "E@": "E",
    "@": "E",
    "@-": "E",
    "@2": "E",
    "@5": "E",
    "a2": "E",
    "i": "ih",
    "i:": "ih",
    "i@": "ih",
    "i@3": "ih",
    "I": "ih",
    "I#": "ih",
    "I2": "ih",
    "IR": "ih",
    "0": "oh",
    "O": "oh",
    "O:": "oh",
    "O@": "oh",
    "o@": "oh",
    "oU": "oh",
    "OI": "oh",
    "o": "oh",
    "u:": "ou",
    "U": "ou",
    "U@": "ou",
    "u": "ou",
    "u@": "ou",
}

#: ARPAbet (CMU dictionary, pocketsphinx) -> viseme
ARPABET_TO_VISEME: dict[str, str] = {
    "SIL": "sil",
    "SP": "sil",
    "+NSN+": "sil",
    "+SPN+": "sil",
    "P": "PP",
    "B": "PP",
    "M": "PP",
    "F": "FF",
    "V": "FF",
    "TH": "TH",
    "DH": "TH",
    "T": "DD",
    "D": "DD",
    "K": "kk",
    "G": "kk",
    "NG": "kk",
    "HH": "kk",
    "CH": "CH",
    "JH": "CH",
    "SH": "CH",
    "ZH": "CH",
    "S": "SS",
    "Z": "SS",
    "N": "nn",
    "L": "nn",
    "Y": "ih",
    "R": "RR",
    "ER": "RR",
    "W": "ou",
    "AA": "aa",
    "AE": "aa",
    "AY": "aa",
    "AW": "aa",
    "AH": "E",  # AH: mostly schwa in running speech (espeak @)
    "EH": "E",
    "EY": "E",
    "IH": "ih",
    "IY": "ih",
    "AO": "oh",
    "OW": "oh",
    "OY": "oh",
    "UH": "ou",
    "UW": "ou",
}


def viseme_of(phoneme: str, alphabet: str = "espeak") -> str:
    """The viseme of one phoneme (``espeak`` mnemonic or ``arpabet``); unknown phonemes map by their first
    letter's class, pauses to ``sil``."""
    if alphabet == "arpabet":
        p = phoneme.upper().rstrip("012")
        return ARPABET_TO_VISEME.get(p, "sil" if not p or p.startswith("+") else "DD")
    p = phoneme.replace("'", "").replace(",", "").strip()
    if p in ESPEAK_TO_VISEME:
        return ESPEAK_TO_VISEME[p]
    if p.startswith("_") or not p:
        return "sil"
    for n in (2, 1):
        if p[:n] in ESPEAK_TO_VISEME:
            return ESPEAK_TO_VISEME[p[:n]]
    return "DD"


# -- recipes: mouth features -> AUs per face type --------------------------------------------------------

#: Human (FACS): jaw drop AU26 with lips part AU25, lip stretcher AU20 for spread, lip funneler AU22 and
#: lip pucker AU18 for rounding, lip presser AU24, upper lip raiser AU10 (labiodentals: the lower lip
#: under the upper teeth), tongue show AU19. facs-human.md §1 names each AU's muscle.
HUMAN_RECIPE: dict[str, dict[str, float]] = {
    "open": {"AU26": 1.0},
    "part": {"AU25": 1.0},
    "spread": {"AU20": 0.8},
    "round": {"AU22": 0.6, "AU18": 0.7},
    "press": {"AU24": 1.0},
    "upper": {"AU10": 0.6},
    "tongue": {"AU19": 0.5},
}

#: Dog (DFACS, signed): open mandible AU7 (the counter -AU7 closes), contract mouth corner AU2 for spread
#: and its counter (relax) for rounding, lip raise AU1 for the labiodental lift. dfacs-dog.md §1.
DOG_RECIPE: dict[str, dict[str, float]] = {
    "open": {"AU7": 0.8},
    "spread": {"AU2": 0.4},
    "round": {"AU2": -0.25},
    "upper": {"AU1": 0.3},
}

RECIPES: dict[str, dict[str, dict[str, float]]] = {"human": HUMAN_RECIPE, "dog": DOG_RECIPE}


def mouth_aus(face_type: str) -> frozenset[str]:
    """The AUs speech takes on a face of this type (the speech track owns them while it speaks)."""
    return frozenset(au for row in RECIPES[face_type].values() for au in row)


def shape_to_aus(shape: Mapping[str, float], face_type: str, allowed: frozenset[str] | None = None) -> dict[str, float]:
    """Mouth features -> AU intensities (clamped to the face's range; only ``allowed`` AUs when given)."""
    lo = -1.0 if face_type == "dog" else 0.0
    out: dict[str, float] = {}
    for feature, value in shape.items():
        for au, gain in RECIPES[face_type].get(feature, {}).items():
            if allowed is not None and au not in allowed:
                continue
            out[au] = out.get(au, 0.0) + gain * value
    return {au: min(1.0, max(lo, v)) for au, v in out.items()}


def recipe_matrix(face_type: str, allowed: frozenset[str] | None = None) -> tuple[list[str], NDArray[np.float64]]:
    """(AU names, matrix (len(FEATURES), len(names))): features @ matrix = AU intensities (unclamped)."""

    if face_type not in RECIPES:
        raise ValueError(f"face type {face_type!r}: expected one of {sorted(RECIPES)}")
    recipe = RECIPES[face_type]
    names = sorted({au for row in recipe.values() for au in row if allowed is None or au in allowed})
    matrix = np.zeros((len(FEATURES), len(names)))
    for i, feature in enumerate(FEATURES):
        for au, gain in recipe.get(feature, {}).items():
            if au in names:
                matrix[i, names.index(au)] += gain
    return names, matrix
