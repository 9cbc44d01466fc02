"""Blending parallel tracks, with a declared rule per AU.

Rules:
- ``max``: the contribution of largest magnitude wins, keeping its sign (for FACS 0..1 that is the plain
  max; for DFACS a counter AU at -0.8 beats +0.2). Ties go to the higher-priority track.
- ``sum``: contributions add, clamped to the face's range (head and eye turns: gaze + idle + expression).
- ``override``: the highest-priority track that provides the AU wins outright (e.g. speech owns the jaw).

A track "provides" an AU when its sample contains that name (a track before its first clip provides
nothing). A rule for ``AU26`` also covers ``AU26L`` / ``AU26R`` unless those have their own rule.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from enum import StrEnum

from servoface.controller.au_names import au_number, canonical_au
from servoface.controller.errors import FrameError, TimelineError
from servoface.sim.rig import FaceType


class BlendRule(StrEnum):
    MAX = "max"
    SUM = "sum"
    OVERRIDE = "override"


DEFAULT_PRIORITY: tuple[str, ...] = ("speech", "blink", "gaze", "gesture", "face", "head", "idle")

#: AUs summed by default: human head 51-58 and eyes 61-66 plus jaw 25-27; dog jaw 7-8, head 9-11, eyes 12-13.
_SUM_NUMBERS: dict[str, frozenset[int]] = {
    "human": frozenset({25, 26, 27, *range(51, 59), *range(61, 67)}),
    "dog": frozenset({7, 8, 9, 10, 11, 12, 13}),
}


#: Human head/eye AUs that are two directions of one joint; after blending they are netted (AU61 0.3 with
#: AU62 0.02 -> AU61 0.28), so one joint never gets two opposite commands. Dog AUs are signed already.
HUMAN_DIRECTION_PAIRS: tuple[tuple[str, str], ...] = (
    ("AU51", "AU52"), ("AU53", "AU54"), ("AU55", "AU56"),
    ("AU57", "AU58"), ("AU61", "AU62"), ("AU63", "AU64"),
)  # fmt: skip


def parse_rule(value: object, *, field: str = "blend rule") -> BlendRule:
    try:
        return BlendRule(str(value).lower())
    except ValueError:
        raise TimelineError(f"{field}: unknown blend rule {value!r}; expected max, sum or override") from None


@dataclass(frozen=True)
class BlendPolicy:
    """Per-AU blend rules plus a track priority (highest first) for ties and ``override``."""

    default: BlendRule = BlendRule.MAX
    rules: Mapping[str, BlendRule] = field(default_factory=dict)
    priority: tuple[str, ...] = DEFAULT_PRIORITY
    antagonists: tuple[tuple[str, str], ...] = ()

    @classmethod
    def for_face(
        cls,
        face_type: FaceType,
        rules: Mapping[str, BlendRule | str] | None = None,
        priority: Sequence[str] | None = None,
        default: BlendRule | str = BlendRule.MAX,
    ) -> BlendPolicy:
        """The default policy of a face (sum on head/eyes/jaw, max elsewhere) with ``rules`` on top."""
        table: dict[str, BlendRule] = {}
        for n in _SUM_NUMBERS.get(face_type, frozenset()):
            table[f"AU{n}"] = BlendRule.SUM
        for name, rule in (rules or {}).items():
            try:
                au = canonical_au(name, field=f"blend.{name}")
            except FrameError as err:
                raise TimelineError(str(err)) from err
            table[au] = parse_rule(rule, field=f"blend.{name}")
        pairs = HUMAN_DIRECTION_PAIRS if face_type == "human" else ()
        return cls(parse_rule(default, field="blend.default"), table, tuple(priority or DEFAULT_PRIORITY), pairs)

    def rule_for(self, au: str) -> BlendRule:
        cache: dict[str, BlendRule] = self.__dict__.setdefault("_rule_cache", {})
        rule = cache.get(au)
        if rule is None:
            rule = self.rules.get(au) or self.rules.get(f"AU{au_number(au)}", self.default)
            cache[au] = rule
        return rule

    def rank(self, track: str, order: int) -> tuple[int, int]:
        """Sort key: listed tracks by their priority, then unlisted tracks in layer order."""
        if track in self.priority:
            return (0, self.priority.index(track))
        return (1, order)

    def blend(
        self,
        contributions: Sequence[tuple[str, Mapping[str, float]]],
        lo: float = -1.0,
        hi: float = 1.0,
        only: frozenset[str] | None = None,
    ) -> dict[str, float]:
        """Blend ``[(track_name, aus), ...]`` (in layer order) into one pose clamped to [lo, hi].

        ``only``: just these AUs of that pose (and both AUs of an antagonist pair with one in it), for a
        layer that reads only them of the blend below it. `blend_plain` is the straightforward form; this
        one keeps the priority order per sequence of track names and does the same arithmetic in the same
        order."""
        if len(contributions) > 1:
            names = tuple([name for name, _ in contributions])
            orders: dict[tuple[str, ...], list[int]] = self.__dict__.setdefault("_order_cache", {})
            order = orders.get(names)
            if order is None:
                order = sorted(range(len(names)), key=lambda i: self.rank(names[i], i))  # stable, as plain
                if len(orders) >= 256:  # (callers with ever new track names: keep it bounded)
                    orders.clear()
                orders[names] = order
            ranked = [contributions[i][1] for i in order]
        else:
            ranked = [aus for _, aus in contributions]
        cache: dict[str, BlendRule] = self.__dict__.setdefault("_rule_cache", {})
        if only is not None:
            wanted = self._with_antagonists(only)
            ranked = [{au: v for au, v in aus.items() if au in wanted} for aus in ranked]
        if not ranked:
            return {}
        for au in ranked[0]:  # every name through rule_for once (it parses, and raises for a bad one)
            if au not in cache:
                self.rule_for(au)
        out: dict[str, float] = dict(ranked[0])  # the highest-priority values: each AU's first
        for aus in ranked[1:]:
            for au, value in aus.items():
                rule = cache.get(au) or self.rule_for(au)  # (every name through rule_for once: it parses)
                if au not in out:  # the first (highest-priority) value of an AU
                    out[au] = value
                elif rule is BlendRule.SUM:
                    out[au] += value
                elif rule is BlendRule.MAX and abs(value) > abs(out[au]):
                    out[au] = value
        for pos, neg in self.antagonists:
            if pos in out and neg in out:
                net = out[pos] - out[neg]
                out[pos], out[neg] = max(net, 0.0), max(-net, 0.0)
        return {au: v if lo <= v <= hi else min(hi, max(lo, v)) for au, v in out.items()}

    def _with_antagonists(self, only: frozenset[str]) -> frozenset[str]:
        cache: dict[frozenset[str], frozenset[str]] = self.__dict__.setdefault("_only_cache", {})
        wanted = cache.get(only)
        if wanted is None:
            extra = {au for pair in self.antagonists if only & set(pair) for au in pair}
            wanted = cache[only] = only | extra
        return wanted

    def blend_plain(
        self, contributions: Sequence[tuple[str, Mapping[str, float]]], lo: float = -1.0, hi: float = 1.0
    ) -> dict[str, float]:
        """`blend` the straightforward way (tests compare the two)."""
        if len(contributions) > 1:
            ranked = [
                aus
                for _, aus in sorted(
                    ((self.rank(name, i), aus) for i, (name, aus) in enumerate(contributions)),
                    key=lambda item: item[0],
                )
            ]
        else:
            ranked = [aus for _, aus in contributions]
        cache: dict[str, BlendRule] = self.__dict__.setdefault("_rule_cache", {})
        out: dict[str, float] = {}
        for aus in ranked:  # highest priority first
            for au, value in aus.items():
                rule = cache.get(au) or self.rule_for(au)  # (every name through rule_for once: it parses)
                if au not in out:  # the first (highest-priority) value of an AU
                    out[au] = value
                elif rule is BlendRule.SUM:
                    out[au] += value
                elif rule is BlendRule.MAX and abs(value) > abs(out[au]):
                    out[au] = value
        for pos, neg in self.antagonists:
            if pos in out and neg in out:
                net = out[pos] - out[neg]
                out[pos], out[neg] = max(net, 0.0), max(-net, 0.0)
        return {au: v if lo <= v <= hi else min(hi, max(lo, v)) for au, v in out.items()}
