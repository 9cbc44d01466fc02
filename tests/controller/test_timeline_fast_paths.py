"""The timeline's cheap paths give what the straightforward ones gave: `BlendPolicy.blend` (rules looked
up in the cache, one contribution not sorted, in-range values not clamped) against the previous blend on
random contributions; `Timeline.is_playing` with its track list kept against a scan of every layer."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pytest
from servoface.controller.timeline import Timeline
from servoface.controller.timeline.blend import DEFAULT_PRIORITY, HUMAN_DIRECTION_PAIRS, BlendPolicy, BlendRule
from servoface.controller.timeline.envelope import Envelope, EnvelopeClip
from servoface.controller.timeline.track import Track


def _blend_reference(
    policy: BlendPolicy, contributions: Sequence[tuple[str, Mapping[str, float]]], lo: float, hi: float
) -> dict[str, float]:
    """The blend as it was."""
    ranked = sorted(
        ((policy.rank(name, i), aus) for i, (name, aus) in enumerate(contributions)), key=lambda item: item[0]
    )
    out: dict[str, float] = {}
    seen: set[str] = set()
    for _, aus in ranked:
        for au, value in aus.items():
            rule = policy.rule_for(au)
            if au not in seen:
                out[au] = value
                seen.add(au)
            elif rule is BlendRule.SUM:
                out[au] += value
            elif rule is BlendRule.MAX and abs(value) > abs(out[au]):
                out[au] = value
    for pos, neg in policy.antagonists:
        if pos in out and neg in out:
            net = out[pos] - out[neg]
            out[pos], out[neg] = max(net, 0.0), max(-net, 0.0)
    return {au: min(hi, max(lo, v)) for au, v in out.items()}


@pytest.mark.parametrize("face_type", ["human", "dog"])
def test_blend_equals_the_previous_blend_on_random_contributions(face_type: str) -> None:
    policy = BlendPolicy.for_face(face_type, rules={"AU12": "override"} if face_type == "human" else None)  # type: ignore[arg-type]
    pairs = [a for pair in HUMAN_DIRECTION_PAIRS for a in pair] if face_type == "human" else []
    aus = [f"AU{n}" for n in (1, 2, 4, 6, 7, 10, 12, 25, 26, 51, 53, 61)] + ["AU12L", "AU12R"] + pairs
    tracks = [*DEFAULT_PRIORITY, "blink", "idle", "custom"]
    rng = np.random.default_rng(31)
    odd = [float("nan"), 1.5, -1.5, -0.0, 0.0]
    for _ in range(800):
        contributions = []
        for _ in range(int(rng.integers(1, 5))):
            names = rng.choice(aus, size=int(rng.integers(0, 8)), replace=False)
            values = {
                str(a): odd[int(rng.integers(len(odd)))] if rng.random() < 0.05 else float(rng.uniform(-1.2, 1.2))
                for a in names
            }
            contributions.append((str(rng.choice(tracks)), values))
        lo, hi = (-1.0, 1.0) if rng.random() < 0.8 else (0.0, 1.0)
        got, want = policy.blend(contributions, lo, hi), _blend_reference(policy, contributions, lo, hi)
        assert list(got) == list(want)
        assert all(g == w or (g != g and w != w) for g, w in zip(got.values(), want.values(), strict=True))


def test_is_playing_with_the_kept_track_list_equals_a_scan_of_every_layer() -> None:
    timeline = Timeline("human")

    class Alive:
        def sample(self, t_s: float, below: Mapping[str, float]) -> dict[str, float]:
            return {}

    def scan(t: float) -> bool:
        return any(isinstance(x, Track) and x.is_playing(t) for x in timeline._layers.values())

    rng = np.random.default_rng(32)
    for k in range(40):
        if k % 7 == 3:
            timeline.add_layer(f"alive{k}", Alive())
        elif k % 5 == 0:
            timeline.add_layer(f"extra{k}", Track(f"extra{k}"))  # a track added as a layer
        at = float(rng.uniform(0, 20))
        d = float(rng.uniform(0.05, 1.0))
        clip = EnvelopeClip({"AU12": 0.5}, Envelope(d, d, d))
        timeline.play(clip, at, track=str(rng.choice(["face", "gesture", "head", f"t{k % 3}"])))
        if f"extra{k}" in timeline.layer_names:
            timeline.layer(f"extra{k}").add(at + 1.0, clip, None)  # type: ignore[attr-defined]
        for t in rng.uniform(0, 25, size=30):
            assert timeline.is_playing(float(t)) == scan(float(t))
