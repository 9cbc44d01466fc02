"""`TwinGate`: the last check before the bus. Every command gets a `Verdict` (accept / clip / reject).

Per frame: validate the request -> narrow limits by servo health -> limits and rate caps (vectorised) ->
twin pose (calibration inverse, joint transforms, skin = rest + B @ pulls, skinning) -> coupling rules,
skin strain and flips, TSS broad phase, exact fcl test on flagged pairs. A failing request is clamped per
servo (limits, rates); if that still fails, the step from the last safe command is scaled back (batched
bisection on the step fraction, every candidate fully re-checked). Nothing safe but the last command ->
reject (hold it).

Contract: ``goals_tick`` may name a subset of servos (the rest keep their last goal); unknown ids,
non-integers (floats, bools, strings) and non-finite values give a ``reject`` verdict with an ``input``
finding. ``last_goals_tick`` is the gate's own previous output: if it misses a servo or holds a bad value
that is a `GateInputError` (the caller broke the contract), as is health for an unknown servo.
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.sim.gate import limits as lim
from servoface.sim.gate.collision import PairSpec, PartCollisions, auto_pairs
from servoface.sim.gate.coupling import CouplingCheck, CouplingLimit, limits_from_head, scaled_share, travel_scales
from servoface.sim.gate.errors import GateConfigError, GateInputError
from servoface.sim.gate.fk import JointTree
from servoface.sim.gate.health import HealthPolicy, ServoHealth, derate
from servoface.sim.gate.skin_proof import proven_static
from servoface.sim.gate.skin_source import RowsPart, face_model_source, falloff_source
from servoface.sim.gate.skin_static import build_static
from servoface.sim.gate.strain import FlipProbe, SkinTwin, StrainLimits, flip_probe, probe_dots_at, strain_findings
from servoface.sim.gate.tss_build import TssParams, default_cache_dir
from servoface.sim.gate.twin import TwinPoser
from servoface.sim.gate.verdict import Finding, Verdict

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class GateConfig:
    """Gate settings; explicit arguments win over the head profile."""

    speed_share: float = 0.8  # of the servo model's no-load speed
    accel_time_s: float = 0.05  # time to reach the allowed speed from rest
    max_step_tick: Mapping[str, int] = field(default_factory=dict)  # per-role overrides (tick/frame)
    max_speedup_tick: Mapping[str, int] = field(default_factory=dict)  # per-role overrides (tick/frame^2)
    strain: StrainLimits = StrainLimits()
    health: HealthPolicy = HealthPolicy()
    coupling: tuple[CouplingLimit, ...] | None = None  # None = the head's rules
    collision_pairs: tuple[PairSpec, ...] | None = None  # None = head.collision_pairs or automatic
    tss: TssParams = TssParams()
    cache_dir: Path | None = None  # None = ~/.cache/servoface/tss (SERVOFACE_TSS_CACHE overrides)
    use_cache: bool = True
    # clearance tables for pairs without a TSS table, axial and distance tables and plane proofs for pairs the
    # TSS keeps flagging (`clearance`, `axial`, `joint_tables`); False: the exact test whenever flagged
    clearance: bool = True
    bisection_rounds: int = 2  # 8 fractions per round: resolution 1/8**rounds of the step
    skin_proofs: bool = True  # leave out of the strain measure the joint-only skin proven safe (skin_proof)


@dataclass(frozen=True)
class BatchReport:
    """Per-command results of `TwinGate.check_batch` ((k,) bool each; ``ok`` = all of them)."""

    limit_ok: BoolArray
    speed_ok: BoolArray
    accel_ok: BoolArray
    coupling_ok: BoolArray
    broad_clear: BoolArray  # no TSS sphere pair overlaps (the exact test is not run in batches)

    @property
    def ok(self) -> BoolArray:
        return self.limit_ok & self.speed_ok & self.accel_ok & self.coupling_ok & self.broad_clear


@dataclass(frozen=True)
class GateMemory:
    """What `TwinGate.check` carries from one call to the next (`TwinGate.step_state`)."""

    last_sent: IntArray | None  # the last command it passed (None: none yet, or reset)
    last_step: IntArray  # that command's step
    last_fraction: float  # share of a frame period the last timed check's step was allowed (`limits.per_time`)

    def same(self, other: GateMemory) -> bool:
        """Equal memories (arrays compared by value)."""
        if (self.last_sent is None) != (other.last_sent is None) or self.last_fraction != other.last_fraction:
            return False
        if self.last_sent is not None and other.last_sent is not None:
            if not np.array_equal(self.last_sent, other.last_sent):
                return False
        return bool(np.array_equal(self.last_step, other.last_step))


class TwinGate:
    """The digital-twin gate of one head. Build once (TSS tables load from cache), call per frame."""

    def __init__(
        self,
        head: Any,
        calibration: Any,
        frame_period_s: float,
        config: GateConfig | None = None,
        face_model: Any = "auto",
    ) -> None:
        """``face_model``: "auto" (the head's `servoface.sim.face_model.FaceModel` when it has muscles, else the
        falloff skin), a FaceModel, or None (falloff skin: each anchor drags the skin around it)."""
        self.head = head
        self.config = cfg = config or GateConfig()
        self.frame_period_s = float(frame_period_s)
        self.tree = JointTree(head.joints)
        self.poser = TwinPoser(head, calibration, self.tree)
        step, speedup = lim.rate_caps_tick(self.poser.models, self.frame_period_s, cfg.speed_share, cfg.accel_time_s)
        for i, role in enumerate(self.poser.roles):
            step[i] = int(cfg.max_step_tick.get(role, step[i]))
            speedup[i] = int(cfg.max_speedup_tick.get(role, speedup[i]))
        self.table = lim.ServoTable(
            self.poser.ids,
            self.poser.roles,
            self.poser.min_tick,
            self.poser.max_tick,
            self.poser.neutral_tick,
            step,
            speedup,
        )
        self._index = self.table.index()
        self._travel = travel_scales(self.poser.target_lower, self.poser.target_upper, self.poser.target_neutral)
        rules = cfg.coupling if cfg.coupling is not None else tuple(limits_from_head(head))
        self.coupling = CouplingCheck(rules, self.poser.roles)
        self.skin = self._build_skin(face_model)
        self.static_skin = build_static(self.skin, self.poser, self.tree)
        self.skin_proven = (0, 0)  # (edges, triangles) left out of the per-frame strain measure by proof
        if self.static_skin is None and cfg.skin_proofs:
            proof = proven_static(self.skin, self.tree, cfg.strain)
            if proof is not None and (proof[0].any() or proof[1].any()):
                self.skin.measure_only(~proof[0], ~proof[1])
                self.skin_proven = (int(proof[0].sum()), int(proof[1].sum()))
        cache = (cfg.cache_dir or default_cache_dir()) if cfg.use_cache else None
        pairs = list(cfg.collision_pairs) if cfg.collision_pairs is not None else auto_pairs(head, self.tree)
        self.collisions = PartCollisions(head, self.tree, pairs, cfg.tss, cache, clearance=cfg.clearance)
        self._pair_index: dict[tuple[str, ...], list[int]] = {}  # (part a, part b) -> indices of their specs
        self._pair_columns: dict[tuple[str, ...], BoolArray] = {}  # (part a, part b) -> servos moving them
        self._skin_columns: BoolArray | None = None  # servos moving the skin (`_uninvolved`)
        for p, spec in enumerate(self.collisions.specs):
            self._pair_index.setdefault((spec.a, spec.b), []).append(p)
        self._last_sent: IntArray | None = None
        self._last_step: IntArray = np.zeros(self.table.n, dtype=np.int64)
        self._last_fraction = 1.0  # share of a frame period the previous check's step was allowed (per_time)
        self._memo: tuple[bytes, list[Finding]] = (b"", [])  # (command bytes, its state findings)
        # triangles a skin-first clip search probes first (`_skin_ok`): costs only, never answers
        # (the probe, its vertices' rows prepared for `SkinSource.offsets_part`)
        self._flip_probe: tuple[FlipProbe, RowsPart] | None = None

    # ---- set-up ---------------------------------------------------------------------------------------
    def _build_skin(self, face_model: Any) -> SkinTwin:
        """The skin source: the face model's twin (default when the head has muscles) or the falloff."""
        anchors = [self.poser.actuators[c] for c in self.poser.anchor_cols]
        if isinstance(face_model, str) and face_model == "auto":
            face_model = None
            if getattr(self.head, "muscles", ()):
                from servoface.sim.face_model import FaceModel

                try:
                    face_model = FaceModel(self.head)
                except Exception as err:  # the face model's own errors name the problem
                    raise GateConfigError(
                        f"head '{self.head.name}': cannot build its face model for the "
                        f"twin's skin ({err}); pass face_model=None for the falloff skin"
                    ) from err
        if face_model is None:
            self.skin_source = falloff_source(self.head.skin, anchors)
            self.skin_model = "falloff"
        else:
            self.skin_source = face_model_source(face_model, anchors)
            self.skin_model = "face_model"
        return SkinTwin(self.head.skin, self.tree, self.skin_source.movable)

    # ---- input ----------------------------------------------------------------------------------------
    def neutral_goals(self) -> dict[int, int]:
        return {sid: int(t) for sid, t in zip(self.table.ids, self.table.neutral_tick, strict=True)}

    def _vector(self, goals: Mapping[Any, Any], base: IntArray | None, what: str) -> tuple[IntArray, list[Finding]]:
        """(n,) ticks in table order from a goal map (``base`` fills servos it leaves out), and the input
        findings. A map of every servo, in table order, of plain ints in range takes a fast path (the
        usual frame, `_plain`): the same array, no findings."""
        fast = self._plain(goals)
        return (fast, []) if fast is not None else self._vector_checked(goals, base, what)

    def _plain(self, goals: Mapping[Any, Any]) -> IntArray | None:
        """The (n,) ticks of a map of every servo in table order whose keys and values are all plain ints
        (not bools, not numpy ints), the values in range; None for any other map (`_vector_checked`)."""
        if len(goals) != self.table.n or tuple(goals) != self.table.ids or set(map(type, goals)) != _INT:
            return None
        values = list(goals.values())
        if set(map(type, values)) == _INT and -_BIG < min(values) and max(values) < _BIG:
            return np.array(values, dtype=np.int64)
        return None

    def _vector_checked(
        self, goals: Mapping[Any, Any], base: IntArray | None, what: str
    ) -> tuple[IntArray, list[Finding]]:
        out = np.zeros(self.table.n, dtype=np.int64) if base is None else base.copy()
        bad: list[Finding] = []
        seen = set()
        for sid, tick in goals.items():
            i_or_none = self._index.get(sid) if _is_int(sid) else None
            if i_or_none is None:
                bad.append(Finding("input", f"{what}: unknown servo id {sid!r}; head servos {list(self.table.ids)}"))
                continue
            i = i_or_none
            if not _is_int(tick):
                desc = "non-finite" if isinstance(tick, float) and not np.isfinite(tick) else "not an integer"
                bad.append(
                    Finding(
                        "input",
                        f"{what}: {self.table.label(i)} goal {tick!r} is {desc} (ticks are ints)",
                        self.table.roles[i],
                        int(sid),
                    )
                )
                continue
            out[i] = int(tick)
            seen.add(i)
        if base is None and len(seen) < self.table.n:
            missing = [self.table.ids[i] for i in range(self.table.n) if i not in seen]
            bad.append(Finding("input", f"{what}: missing servo id(s) {missing}"))
        return out, bad

    # ---- the twin -------------------------------------------------------------------------------------
    def _pose_arrays(self, goals: IntArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """(targets (k, n), angles (k, J), world (k, J, 4, 4), pulls (k, a)) for (k, n) goals."""
        if len(goals) == 1:  # one command (the frame's request, a clip's clamped request): flat arrays
            target, angle, pull = self.poser.pose_one(goals[0])
            return target[None], angle[None], self.tree.world_one(angle)[None], pull[None]
        targets = self.poser.targets(goals)
        angles = self.poser.joint_angles(targets)
        return targets, angles, self.tree.world(angles), self.poser.pulls(targets)

    def _shares(self, targets: FloatArray) -> FloatArray:
        return scaled_share(targets, self.poser.target_neutral, *self._travel)

    def _static(self, goal: IntArray) -> tuple[float, float, int]:
        """The tabulated joint-only skin strain for one command (neutral values when not tabulated)."""
        return (0.0, np.inf, 0) if self.static_skin is None else self.static_skin.values(goal)

    def _hard_findings(self, goal: IntArray, stop_early: bool = False) -> list[Finding]:
        """Coupling, strain, flips and collisions (exact on flagged pairs) for one command."""
        targets, angles, world, pulls = self._pose_arrays(goal[None, :])
        out = self.coupling.findings(self._shares(targets)[0])
        if out and stop_early:
            return out
        active = self.skin.fast_vertices
        offsets = self.skin_source.offsets_rows(pulls[0], active)
        key = self.skin_source.rows_key(active)
        stretch, comp, flips = self.skin.measure_one(world[0], offsets, self._static(goal), key)
        out += strain_findings(stretch, comp, flips, self.config.strain)
        if out and stop_early:
            return out
        hits, _ = self.collisions.colliding(world[0], angles[0])
        out += [
            Finding("collision", f"parts '{s.a}' and '{s.b}' intersect (exact mesh test)", parts=(s.a, s.b))
            for s in hits
        ]
        return out

    def _last_ok(
        self,
        goals: IntArray,
        suspects: tuple[int, ...] = (),
        known: dict[bytes, bool] | None = None,
        skin_first: bool = False,
    ) -> int | None:
        """Index of the last of (k, n) candidates passing every state check, or None. Coupling is checked
        for all at once (cheap); collisions, then strain, one candidate at a time from the end, stopping at
        the first that passes. ``suspects``: pair indices the request collided on, tested exactly first
        (a contact found by the exact test fails the candidate whatever the broad phase says). ``known``:
        answers of commands already checked in this search (command bytes -> passed), used instead of
        checking them again and filled with the new ones (the state checks are pure functions of the command,
        so the index returned is the same). ``skin_first``: the request failed on the skin and not by
        contact, so the skin is measured before the contact tests (a candidate passes only if both do, so the
        order changes no answer, only what a failing candidate costs)."""
        # the joint transforms only of the candidates checked (`JointTree.world_one`'s: the batch's numbers)
        if len(goals) == 1:  # (`TwinPoser.pose_one`: the batch path's numbers)
            target, angle, pull = self.poser.pose_one(goals[0])
            targets, angles, pulls = target[None], angle[None], pull[None]
        else:
            targets = self.poser.targets(goals)
            angles, pulls = self.poser.joint_angles(targets), self.poser.pulls(targets)
        coupling_ok = np.flatnonzero(self.coupling.ok(self._shares(targets)))
        col = self.collisions
        tree = self.tree
        # a candidate's transforms along the suspects' chains first: most fail there, and need no others
        first = tree.ancestry(self._part_index(name) for p in suspects for name in (col.specs[p].a, col.specs[p].b))
        rest = [i for i in range(len(tree.names)) if i not in set(first)]
        memo: dict[bytes, bool] = {} if known is None else known
        order = [int(i) for i in coupling_ok[::-1]]
        worlds: dict[int, FloatArray] | None = None  # candidate -> its transforms, when batched (below)
        for n, k in enumerate(order):
            key = goals[k].tobytes()
            answer = memo.get(key)
            if answer is not None:
                if answer:
                    self._memo = (key, [])
                    return k
                continue
            memo[key] = False
            if worlds is None:
                unknown = [j for j in order[n:] if goals[j].tobytes() not in memo or j == k]
                if len(unknown) >= _BATCH_FK:  # several left to check: all their transforms in one batch
                    # (`JointTree.world`: the numbers of `world_one` and `fill_one`, a few calls for them all)
                    worlds = dict(zip(unknown, tree.world(angles[unknown]), strict=True))
            loc = None
            if worlds is not None:
                world = worlds[k]
            else:
                loc = tree.local_one(angles[k])
                world = np.empty_like(loc)  # filled in two parts: `world_one`'s numbers (`JointTree.fill_one`)
                tree.fill_one(world, loc, first)
            # contact first (broad phase, exact test on flagged pairs) unless the request failed on the skin
            # alone: where candidates fail it is mostly on what the request failed on, and a pass needs both
            if skin_first:
                if loc is not None:
                    tree.fill_one(world, loc, rest)
                if not self._skin_ok(goals[k], world, pulls[k], probe=True):
                    continue
            if any(col._collide(col.specs[p], world) for p in suspects):
                continue
            if not skin_first and loc is not None:
                tree.fill_one(world, loc, rest)
            flags = col.broad.flag(world, angles[k])  # one pose: the flat broad phase (fastest for one)
            if any(col._collide(col.specs[p], world) for p in np.flatnonzero(flags) if p not in suspects):
                continue
            if skin_first or self._skin_ok(goals[k], world, pulls[k]):
                memo[key] = True
                self._memo = (key, [])
                return k
        return None

    def _part_index(self, name: str) -> int:
        """The tree index of the joint carrying part ``name`` (-1: the head base)."""
        joint = self.collisions.part_joint[name]
        return -1 if joint is None else self.tree.index[joint]

    def _skin_ok(self, goal: IntArray, world: FloatArray, pulls: FloatArray, probe: bool = False) -> bool:
        """The strain and flip limits hold for one candidate ((n,) goal, its (J, 4, 4) pose and pulls).

        ``probe``: first count the flips among the triangles the last candidate that failed on flips had
        flipped (`strain.probe_dots`: the same numbers as the whole measure, on a few triangles): more of
        them flipped than the limit allows fails the candidate as the whole measure would (its count can
        only be larger), at a fraction of its cost. Which triangles are probed changes no answer."""
        s = self.config.strain
        static = self._static(goal)
        if probe and self._flip_probe is not None and self._flip_probe[0].subset == self.skin.subset:
            flip, part = self._flip_probe  # the probe's vertices' offsets only: the same numbers, gathered
            dots = probe_dots_at(self.skin, world, self.skin_source.offsets_part(pulls, part), flip)
            if int(np.count_nonzero(dots <= 0.0)) + self.skin.const_flips + static[2] > s.max_flipped:
                return False
        offsets = self.skin_source.offsets_rows(pulls, self.skin.fast_vertices)
        key = self.skin_source.rows_key(self.skin.fast_vertices)
        stretch, comp, flips, flipped = self.skin.measure_one_faces(world, offsets, static, key)
        if probe and flips > s.max_flipped:  # probe these triangles on the next candidates
            faces = np.flatnonzero(flipped)
            self._flip_probe = None
            if len(faces):
                made = flip_probe(self.skin, faces)
                self._flip_probe = (made, self.skin_source.rows_part(self.skin.fast_vertices[made.verts]))
        return stretch <= s.max_stretch and comp >= s.min_compression and flips <= s.max_flipped

    # ---- public ---------------------------------------------------------------------------------------
    def check(
        self,
        goals_tick: Mapping[int, int],
        last_goals_tick: Mapping[int, int],
        health: Mapping[int, ServoHealth] | None = None,
        elapsed_s: float | None = None,
    ) -> Verdict:
        """The verdict for sending ``goals_tick`` after ``last_goals_tick`` (see the module docstring).

        ``elapsed_s``: time since ``last_goals_tick`` went on the wire; when shorter than a frame period the
        rate caps shrink with it (`limits.per_time`), so the caps hold per second whatever the call pattern.
        None: one frame period (the per-frame caps)."""
        # a plain map (the usual frame) is copied as is: the same items as the dict rebuilt from its ticks
        last = self._plain(last_goals_tick)
        plain_last = last is not None
        if last is None:
            last, bad_last = self._vector_checked(last_goals_tick, None, "last_goals_tick")
            if bad_last:
                raise GateInputError("; ".join(f.message for f in bad_last))
        table, health_findings = derate(self.table, health, self.config.health)
        last_fraction = self._last_fraction  # the caps of this check follow the previous check's fraction
        if elapsed_s is not None:  # (a check without elapsed_s leaves the fraction alone)
            self._last_fraction = lim.time_fraction(elapsed_s, self.frame_period_s)
        req = self._plain(goals_tick)
        if req is None:
            req, bad = self._vector_checked(goals_tick, last, "goals_tick")
            requested = dict(zip(self.table.ids, req.tolist(), strict=True))
        else:
            bad, requested = [], dict(goals_tick)
        hold = dict(last_goals_tick) if plain_last else dict(zip(self.table.ids, last.tolist(), strict=True))
        if bad:
            return self._remember(Verdict("reject", hold, tuple(health_findings + bad), 0.0, requested), last, last)
        if _same_ticks(req, last) and self._at_rest_ok(req, table):
            # the servos sit at the request (the usual held frame): a zero step passes any rate caps (their
            # interval always holds 0), so only the position limits and the state checks could fire
            return self._remember(Verdict("accept", requested, tuple(health_findings), 1.0, requested), last, req)
        table, rate_last, last_step = self._rate_inputs(last, table, elapsed_s, last_fraction)
        findings = health_findings + lim.findings(req, rate_last, last_step, table)
        clamped = None
        known: dict[bytes, bool] = {}  # answers of the state checks in this call (see `_scale_back`)
        if len(findings) > len(health_findings):
            clamped = lim.clamp(req, rate_last, last_step, table)
            if not _same_ticks(clamped, req):
                # the limits and rate caps clamp the request: it is not what will be sent, so the clamped
                # command's state checks come first; the request's own only if that fails (the search's
                # hints). One state check where there were two on every rate clip (what a performance
                # faster than the servos clips on, a frame in four of the shipped one)
                clean = self._clamped_passes(clamped, known)
                if clean:
                    return self._clip_to(clamped, 1.0, clamped, last, plain_last, last_goals_tick, findings, requested)
        key = req.tobytes()
        if self._memo[0] != key:  # state checks depend on the command only: a held command is not redone
            self._memo = (key, self._hard_findings(req))
        hard = list(self._memo[1])
        findings += hard
        if len(findings) == len(health_findings):
            return self._remember(Verdict("accept", requested, tuple(findings), 1.0, requested), last, req)
        if clamped is None:
            clamped = lim.clamp(req, rate_last, last_step, table)
        if not hard and np.array_equal(clamped, req):  # only health notes fired
            return self._remember(Verdict("accept", requested, tuple(findings), 1.0, requested), last, req)
        hit = {f.parts for f in hard if f.check == "collision"}
        suspects = tuple(sorted(p for parts in hit for p in self._pair_index.get(parts, ())))  # in spec order
        skin_first = not hit and any(f.check in ("strain", "flip") for f in hard)
        best, frac = self._scale_back(
            req,
            last,
            last_step,
            table,
            skip_full=bool(hard),
            suspects=suspects,
            rate_last=rate_last,
            skin_first=skin_first,
            free=self._uninvolved(hard),
            known=known,
        )
        if best is None or (np.array_equal(best, last) and not np.array_equal(clamped, last)):
            findings.append(Finding("hold", "no safe command found between the last one and the request: holding"))
            return self._remember(Verdict("reject", hold, tuple(findings), 0.0, requested), last, last)
        return self._clip_to(best, frac, clamped, last, plain_last, last_goals_tick, findings, requested)

    def _clamped_passes(self, clamped: IntArray, known: dict[bytes, bool]) -> bool:
        """Whether the clamped request passes every state check (the memo of the last command checked, else
        `_last_ok`, whose answer goes into ``known`` for a search that follows)."""
        key = clamped.tobytes()
        if self._memo[0] == key:
            known[key] = not self._memo[1]
            return not self._memo[1]
        return self._last_ok(clamped[None, :], (), known) == 0

    def _clip_to(
        self,
        best: IntArray,
        frac: float,
        clamped: IntArray,
        last: IntArray,
        plain_last: bool,
        last_goals_tick: Mapping[int, int],
        findings: list[Finding],
        requested: dict[int, int],
    ) -> Verdict:
        """The clip verdict sending ``best`` (a command that passed every check; not the last one unless
        the per-servo clamp is the last command itself: e.g. a servo held at its narrowed limit while the
        others have arrived, a clip at the limits, not a refusal)."""
        if np.array_equal(best, last) and np.array_equal(clamped, last):
            hold = dict(last_goals_tick) if plain_last else dict(zip(self.table.ids, last.tolist(), strict=True))
            return self._remember(Verdict("clip", hold, tuple(findings), 1.0, requested), last, last)
        goals = dict(zip(self.table.ids, best.tolist(), strict=True))
        return self._remember(Verdict("clip", goals, tuple(findings), frac, requested), last, best)

    def _uninvolved(self, hard: list[Finding]) -> BoolArray | None:
        """The servos that cannot move what the request's state checks failed on, as a (n,) mask (None when
        none can be told apart): for a collision, every servo but those driving a joint on either part's
        chain; for strain and flips, every servo but those driving a skinning joint's chain and the anchors
        (the eyes and lids of the built-in heads). A coupling rule or any other finding, or a head whose
        calibration couples servos, frees none (freeing the servos a coupling rule does not name was tried:
        the human's walk then moved further and its gate time per frame rose ~15 %, p99 included). The
        scale-back keeps the free servos at their whole clamped step (`_scale_back`)."""
        if not hard or self.poser.coupled:
            return None
        involved = np.zeros(self.table.n, dtype=bool)
        for f in hard:
            if f.check == "collision" and f.parts:
                key = tuple(f.parts)
                cols = self._pair_columns.get(key)
                if cols is None:
                    joints = self.tree.ancestry(self._part_index(name) for name in key)
                    cols = self._pair_columns[key] = self.poser.columns_driving(joints)
                involved |= cols
            elif f.check in ("strain", "flip"):
                if self._skin_columns is None:
                    cols = self.poser.columns_driving(self.tree.ancestry(self.skin.joints_used))
                    cols[self.poser.anchor_cols] = True
                    self._skin_columns = cols
                involved |= self._skin_columns
            else:
                return None
        free = ~involved
        return free if free.any() else None

    def _scale_back(
        self,
        req: IntArray,
        last: IntArray,
        last_step: IntArray,
        table: lim.ServoTable,
        skip_full: bool = False,
        suspects: tuple[int, ...] = (),
        rate_last: IntArray | None = None,
        skin_first: bool = False,
        free: BoolArray | None = None,
        known: dict[bytes, bool] | None = None,
    ) -> tuple[IntArray | None, float]:
        """The largest step fraction whose clamped command passes every check (batched bisection).
        ``skip_full``: ``req`` itself failed a state check, so its clamp is not re-checked if equal.
        ``skin_first``: measure each candidate's skin before its contact tests (`_last_ok`).
        ``rate_last``: where the rate caps measure the step from (default ``last``; see `limits.per_time`).
        ``free``: servos that cannot move what the request failed on (`_uninvolved`): the search first scales
        only the others, these keeping their whole clamped step (a jaw that would hit the teeth does not
        slow the eyes); if no such candidate passes, every servo is scaled. Every candidate is fully
        checked either way, so this changes which safe command is found, never whether it is safe.
        ``known``: answers `check` found already (the clamped request's, checked first on a rate clip)."""
        step = req - last
        base = last if rate_last is None else rate_last
        # answers already known in this search (command bytes -> passed), from every candidate checked: a
        # round's last candidate is always one (round 1's is the clamped request, a later round's the failed
        # top end of the previous round), and truncation makes neighbouring candidates repeat
        known = {} if known is None else known
        cand_1 = lim.clamp(req, base, last_step, table)
        if skip_full and np.array_equal(cand_1, req):
            known[cand_1.tobytes()] = False  # the request itself failed a state check
        elif self._last_ok(cand_1[None, :], suspects, known, skin_first) == 0:
            return cand_1, 1.0
        if free is not None and not np.array_equal(cand_1[free], last[free]):
            best, frac = self._bisect(step, last, base, last_step, table, cand_1, free, suspects, known, skin_first)
            if best is not None:
                return best, frac
        return self._bisect(step, last, base, last_step, table, cand_1, None, suspects, known, skin_first)

    def _bisect(
        self,
        step: IntArray,
        last: IntArray,
        base: IntArray,
        last_step: IntArray,
        table: lim.ServoTable,
        cand_1: IntArray,
        free: BoolArray | None,
        suspects: tuple[int, ...],
        known: dict[bytes, bool],
        skin_first: bool,
    ) -> tuple[IntArray | None, float]:
        """`_scale_back`'s search on the step fraction: 8 candidates a round, every one fully checked; the
        ``free`` servos at ``cand_1`` (the clamped request) in every candidate."""
        lo, hi = 0.0, 1.0
        best: IntArray | None = None
        best_frac = 0.0
        for _ in range(max(1, self.config.bisection_rounds)):
            fracs = lo + (hi - lo) * np.arange(1, 9) / 8.0
            raw = last + np.trunc(fracs[:, None] * step[None, :]).astype(np.int64)
            cands = lim.clamp(raw, base, last_step, table)
            if free is not None:
                cands[:, free] = cand_1[free]
            found = self._last_ok(cands, suspects, known, skin_first)
            if found is None:
                hi = fracs[0]
                continue
            g = found
            best, best_frac = cands[g], float(fracs[g])
            lo = float(fracs[g])
            hi = float(fracs[g + 1]) if g + 1 < len(fracs) else hi
            if g + 1 >= len(fracs):
                break
        return best, best_frac

    def step_state(self) -> GateMemory:
        """What `check` carries from one call to the next (the last command it passed, that step, the
        per-time fraction), for a caller that checks a command speculatively and puts the
        state back (`restore_step_state`)."""
        sent = None if self._last_sent is None else self._last_sent.copy()
        return GateMemory(sent, self._last_step.copy(), self._last_fraction)

    def restore_step_state(self, state: GateMemory) -> None:
        self._last_sent = None if state.last_sent is None else state.last_sent.copy()
        self._last_step = state.last_step.copy()
        self._last_fraction = state.last_fraction

    def rate_key(
        self,
        last_goals_tick: Mapping[int, int],
        health: Mapping[int, ServoHealth] | None = None,
        elapsed_s: float | None = None,
    ) -> bytes:
        """Everything of the rate checks that ``elapsed_s`` changes in `check` with this memory, last command
        and health: the caps after `limits.per_time`, the step's origin and the previous step. Two checks of
        one command from one memory, last command and health whose keys are equal give equal verdicts (the
        other checks are pure functions of the command); a speculative verdict checked for one elapsed time
        is good for another with the same key. Leaves the memory alone."""
        last, bad_last = self._vector(last_goals_tick, None, "last_goals_tick")
        if bad_last:
            raise GateInputError("; ".join(f.message for f in bad_last))
        table, _ = derate(self.table, health, self.config.health)
        caps, rate_last, last_step = self._rate_inputs(last, table, elapsed_s, self._last_fraction)
        parts = [getattr(caps, f.name) for f in fields(caps)] + [rate_last, last_step]  # every cap array
        return b"|".join(
            b"-" if a is None else np.asarray(a, dtype=np.int64).tobytes()
            for a in parts
            if a is None or isinstance(a, np.ndarray)
        )

    def remember_check(
        self,
        verdict: Verdict,
        last_goals_tick: Mapping[int, int],
        health: Mapping[int, ServoHealth] | None = None,
        elapsed_s: float | None = None,
    ) -> None:
        """Note ``verdict`` as `check` would have after checking it with these inputs (a speculative verdict
        a caller uses instead of checking again: see `rate_key`): the memory ends exactly as that check's."""
        last, bad_last = self._vector(last_goals_tick, None, "last_goals_tick")
        if bad_last:
            raise GateInputError("; ".join(f.message for f in bad_last))
        derate(self.table, health, self.config.health)  # (raises as the check would for unknown servos)
        if elapsed_s is not None:
            self._last_fraction = lim.time_fraction(elapsed_s, self.frame_period_s)
        self._remember(verdict, last)

    def _rate_inputs(
        self, last: IntArray, table: lim.ServoTable, elapsed_s: float | None, last_fraction: float
    ) -> tuple[lim.ServoTable, IntArray, IntArray]:
        """(caps, the step's origin, the previous step) for a check after ``last`` from this memory (the
        previous check's fraction ``last_fraction``): the per-frame caps without ``elapsed_s``, else
        `limits.per_time`'s (the fraction to note is `limits.time_fraction`)."""
        last_step = (
            self._last_step
            if self._last_sent is not None and _same_ticks(self._last_sent, last)
            else np.zeros(self.table.n, dtype=np.int64)
        )
        if elapsed_s is None:
            return table, last, last_step
        caps, scaled_last = lim.per_time(table, last_step, elapsed_s, self.frame_period_s, last_fraction)
        return caps, last, scaled_last

    def _at_rest_ok(self, goal: IntArray, table: lim.ServoTable) -> bool:
        """Whether a command equal to the last one passes: inside the position limits and every state
        check (the memo of the last command's state checks, filled if it is another command)."""
        key = goal.tobytes()
        if self._memo[0] != key:
            self._memo = (key, self._hard_findings(goal))
        return not self._memo[1] and bool(((goal >= table.min_tick) & (goal <= table.max_tick)).all())

    def reset(self) -> None:
        """Forget the previous step (the next check assumes the servos start from rest)."""
        self._last_sent = None
        self._last_step = np.zeros(self.table.n, dtype=np.int64)

    def _remember(self, verdict: Verdict, last: IntArray, sent: IntArray | None = None) -> Verdict:
        """Note what ``verdict`` sends; ``sent``: its goals as (n,) ticks already (the same numbers)."""
        if sent is None:
            sent = np.array([verdict.goals_tick[sid] for sid in self.table.ids], dtype=np.int64)
        else:
            sent = np.array(sent, dtype=np.int64)  # a copy: the caller's array stays its own
        self._last_step = sent - last
        self._last_sent = sent
        return verdict

    def check_batch(
        self,
        goals: IntArray,
        last: IntArray,
        last_step: IntArray | None = None,
        health: Mapping[int, ServoHealth] | None = None,
    ) -> BatchReport:
        """Cheap checks for (k, n) goal arrays (columns in ``self.table.ids`` order) after ``last`` ((n,) or
        (k, n)): limits, rates, coupling and the TSS broad phase. No exact test, no skin strain."""
        g = np.asarray(goals)
        if g.ndim != 2 or g.shape[1] != self.table.n or not np.issubdtype(g.dtype, np.integer):
            raise GateInputError(
                f"check_batch: goals must be an integer array (k, {self.table.n}), got {g.dtype} {g.shape}"
            )
        table, _ = derate(self.table, health, self.config.health)
        ls = np.zeros(self.table.n, dtype=np.int64) if last_step is None else last_step
        limit_ok, speed_ok, accel_ok = lim.rate_ok(g, np.asarray(last), ls, table)
        targets, angles, world, _ = self._pose_arrays(g)
        coupling_ok = self.coupling.ok(self._shares(targets))
        broad = ~self.collisions.broad.flag(world, angles).any(axis=-1)
        return BatchReport(
            np.asarray(limit_ok.all(axis=1)),
            np.asarray(speed_ok.all(axis=1)),
            np.asarray(accel_ok.all(axis=1)),
            coupling_ok,
            np.asarray(broad),
        )

    def audit(self, goals_tick: Mapping[int, int]) -> list[Finding]:
        """Every state check of one full command without shortcuts: limits, coupling, strain, flips and
        the exact mesh test on *every* checked pair (no broad phase). Slow; for tests and audits."""
        vec, bad = self._vector(goals_tick, None, "goals_tick")
        if bad:
            raise GateInputError("; ".join(f.message for f in bad))
        out = [f for f in lim.findings(vec, vec, np.zeros_like(vec), self.table) if f.check == "limit"]
        targets, _, world, pulls = self._pose_arrays(vec[None, :])
        out += self.coupling.findings(self._shares(targets)[0])
        stretch, comp, flips = self.skin.measure(world[0], self.skin_source.offsets(pulls[0]))
        out += strain_findings(float(stretch), float(comp), int(flips), self.config.strain)
        out += [
            Finding("collision", f"parts '{s.a}' and '{s.b}' intersect (exact mesh test)", parts=(s.a, s.b))
            for s in self.collisions.colliding_exhaustive(world[0])
        ]
        return out

    # ---- for callers that need the twin's pose ----------------------------------------------------------
    def twin_pose(self, goals_tick: Mapping[int, int]) -> tuple[dict[str, float], FloatArray, dict[str, float]]:
        """(joint_deg, skin_offset_mm (n, 3), actuator targets) the twin sees for a full command."""
        vec, bad = self._vector(goals_tick, None, "goals_tick")
        if bad:
            raise GateInputError("; ".join(f.message for f in bad))
        targets, angles, _, pulls = self._pose_arrays(vec[None, :])
        offsets = self.skin_source.offsets(pulls[0])
        joint_deg = {n: float(a) for n, a in zip(self.tree.names, angles[0], strict=True)}
        return joint_deg, offsets, {r: float(t) for r, t in zip(self.poser.roles, targets[0], strict=True)}


_BATCH_FK = 3  # candidates left to check in a clip search from which their transforms are batched
_BIG = 2**62  # plain ints inside this fit int64 (outside, the checked path raises as it always did)
_INT = {int}


def _same_ticks(a: IntArray, b: IntArray) -> bool:
    """`np.array_equal` for tick arrays, by their bytes when dtype and shape agree (then the same answer)."""
    if a.dtype == b.dtype and a.shape == b.shape:
        return a.tobytes() == b.tobytes()
    return bool(np.array_equal(a, b))


def _is_int(value: Any) -> bool:
    """An integer and not a bool (Python int, numpy integer, other Integral); concrete types first (fast)."""
    kind = type(value)
    if kind is int or isinstance(value, np.integer):
        return True
    return kind is not bool and isinstance(value, numbers.Integral)
