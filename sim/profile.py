"""Head profiles: read ``head.toml`` (+ meshes) and validate it into a frozen :class:`servoface.sim.head.Head`.

Every error is a :class:`servoface.sim.errors.HeadProfileError` whose message starts with the file and the key path
(``head.toml: actuator[3].servo.id: ...``) and says what was expected. The schema is documented in
``sim/heads/README.md``; the built-in profiles ``sim/heads/human`` and ``sim/heads/dog`` use all of it.
"""

from __future__ import annotations

import difflib
import math
import sys
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
from servoface.sim.errors import HeadProfileError
from servoface.sim.head import Head
from servoface.sim.heads.binding import BindRule, HalfSpace, bind_weights
from servoface.sim.heads.sizes import COORD_LIMIT_MM
from servoface.sim.rig import (
    SERVO_MODEL_ALIASES,
    SERVO_MODELS,
    Actuator,
    AnchorActuator,
    CouplingRule,
    Joint,
    JointActuator,
    LinearMuscle,
    Muscle,
    RigidPart,
    ServoRef,
    SheetMuscle,
    Skin,
    SphincterMuscle,
    Vec3,
)
from servoface.sim.textfile import read_utf8

_FLOAT_MAX = sys.float_info.max

SCHEMA_VERSION = 1
ANCHOR_MAX_GAP_MM = 10.0  # an anchor's near_mm must be this close to the skin
FACE_TYPES = ("human", "dog")
_TOP_KEYS = {
    "schema_version", "name", "face_type", "description", "calibration", "au_table", "expressions", "au_direct",
    "skin", "joint", "part", "muscle", "anchors", "actuator", "coupling", "landmarks",
}  # fmt: skip


def _shown(value: Any, limit: int = 60) -> str:
    try:
        text = repr(value)
    except (RecursionError, ValueError):
        text = f"<{type(value).__name__} nested too deeply>"
    return text if len(text) <= limit else text[: limit - 3] + "..."


class _Reader:
    """Typed access to a TOML table with errors naming the file and key path."""

    def __init__(self, file: Path) -> None:
        self.file = file

    def fail(self, key: str, expected: str, got: Any = None, cause: BaseException | None = None) -> HeadProfileError:
        got_s = "" if got is None else f", got {_shown(got)}"
        return HeadProfileError(f"{self.file}: {key}: expected {expected}{got_s}")

    def table(self, d: Any, key: str) -> dict[str, Any]:
        if not isinstance(d, dict):
            raise self.fail(key, "a table", d)
        return d

    def keys(self, d: dict[str, Any], key: str, allowed: set[str]) -> None:
        extra = sorted(set(d) - allowed)
        if extra:
            near = difflib.get_close_matches(extra[0], sorted(allowed), n=1)
            hint = f" (did you mean {near[0]!r}?)" if near else ""
            raise self.fail(
                f"{key}.{extra[0]}" if key else extra[0],
                f"one of the known keys {sorted(allowed)}{hint}",
                extra[0],
            )

    def req(self, d: dict[str, Any], name: str, key: str) -> Any:
        if name not in d:
            raise self.fail(f"{key}.{name}" if key else name, "this key (required)", None)
        return d[name]

    def string(self, d: dict[str, Any], name: str, key: str, default: str | None = None) -> str:
        if name not in d and default is not None:
            return default
        v = self.req(d, name, key)
        if not isinstance(v, str) or not v:
            raise self.fail(f"{key}.{name}" if key else name, "a non-empty string", v)
        return v

    def number(self, d: dict[str, Any], name: str, key: str, default: float | None = None) -> float:
        if name not in d and default is not None:
            return default
        v = self.req(d, name, key)
        return self.num(v, f"{key}.{name}" if key else name, mm=name.endswith("_mm"))

    def num(self, v: Any, key: str, mm: bool = False) -> float:
        """A finite number; with ``mm`` (a position or length: every ``*_mm`` field, the landmarks) also
        within ``COORD_LIMIT_MM`` of zero."""
        if isinstance(v, bool) or not isinstance(v, int | float) or not (v == v and abs(v) <= _FLOAT_MAX):
            raise self.fail(key, "a finite number", v)  # an int beyond a float's range too: not converted
        if mm and not abs(v) <= COORD_LIMIT_MM:
            raise self.fail(
                key, f"a length within +-{COORD_LIMIT_MM:g} mm (positions and lengths in head.toml are in mm)", v
            )
        return float(v)

    def vec(self, d: dict[str, Any], name: str, key: str, n: int = 3, unit: bool = False) -> tuple[float, ...]:
        v = self.req(d, name, key)
        k = f"{key}.{name}" if key else name
        if not isinstance(v, list) or len(v) != n:
            raise self.fail(k, f"a list of {n} finite numbers", v)
        mm = name.endswith("_mm") or key == "landmarks"
        out = tuple(self.num(x, f"{k}[{i}]", mm=mm) for i, x in enumerate(v))
        if unit:
            norm = math.hypot(*out)  # no overflow for a huge component (its square would be inf)
            if not norm >= 1e-9 or not math.isfinite(norm):
                raise self.fail(k, "a non-zero direction vector", v)
            out = tuple(x / norm for x in out)
        return out

    def vec3(self, d: dict[str, Any], name: str, key: str, unit: bool = False) -> Vec3:
        a, b, c = self.vec(d, name, key, 3, unit)
        return (a, b, c)

    def interval(self, d: dict[str, Any], name: str, key: str) -> tuple[float, float]:
        lo, hi = self.vec(d, name, key, 2)
        if not lo < hi:
            raise self.fail(f"{key}.{name}", "[lower, upper] with lower < upper (limits reversed or empty)", [lo, hi])
        return lo, hi

    def rgba(
        self, d: dict[str, Any], key: str, default: tuple[float, float, float, float]
    ) -> tuple[float, float, float, float]:
        if "color_rgba" not in d:
            return default
        r, g, b, a = self.vec(d, "color_rgba", key, 4)
        if not all(0.0 <= x <= 1.0 for x in (r, g, b, a)):
            raise self.fail(f"{key}.color_rgba", "four numbers in 0..1", d["color_rgba"])
        return (r, g, b, a)

    def array(self, d: dict[str, Any], name: str) -> list[dict[str, Any]]:
        v = d.get(name, [])
        if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
            raise self.fail(name, f"an array of tables ([[{name}]])", v)
        return v


def load_profile(path: Path) -> Head:
    """Load and validate a profile: ``path`` is a folder holding ``head.toml`` or the TOML file itself."""
    path = Path(path)
    file = path / "head.toml" if path.is_dir() else path
    if not file.is_file():
        raise HeadProfileError(f"{file}: expected a head profile file (head.toml), none found")
    try:
        data = tomllib.loads(read_utf8(file, HeadProfileError, what="a head profile"))
    except tomllib.TOMLDecodeError as err:
        raise HeadProfileError(f"{file}: not valid TOML: {err}") from err
    except RecursionError as err:
        raise HeadProfileError(f"{file}: nested too deeply to be a head profile") from err
    return build_checked(_Reader(file), data, file.parent)


def build_checked(r: _Reader, data: dict[str, Any], folder: Path, *, bind_skin: bool = True) -> Head:
    """`_build`, with any value of the wrong shape that slipped past a field check (a list where a name
    was expected, a number too large for a float) reported as `HeadProfileError` naming the file.

    ``bind_skin=False``: every field is parsed and checked, meshes loaded, but the skin's bind weights (a
    computation over every vertex that cannot fail, ~0.3 s) are left at "all on the skin's own joint": a
    head only good for validating a profile (the fuzz tests), not for driving or rendering."""
    try:
        return _build(r, data, folder, bind_skin)
    except HeadProfileError:
        raise
    except (TypeError, ValueError, KeyError, IndexError, AttributeError, OverflowError, RecursionError) as err:
        raise HeadProfileError(f"{r.file}: a value has the wrong type or size ({type(err).__name__}: {err})") from err


def _build(r: _Reader, data: dict[str, Any], folder: Path, bind_skin: bool = True) -> Head:
    from servoface.sim.heads.meshes import load_part_mesh, load_skin_mesh

    r.keys(data, "", _TOP_KEYS)
    version = data.get("schema_version", SCHEMA_VERSION)
    if version != SCHEMA_VERSION:
        raise r.fail("schema_version", f"{SCHEMA_VERSION}", version)
    name = r.string(data, "name", "")
    face_type = r.string(data, "face_type", "")
    if face_type not in FACE_TYPES:
        raise r.fail("face_type", f"one of {list(FACE_TYPES)}", face_type)

    joints = _joints(r, data)
    jnames = {j.name for j in joints}

    parts: list[RigidPart] = []
    seen: set[str] = set()
    for i, p in enumerate(r.array(data, "part")):
        key = f"part[{i}]"
        r.keys(p, key, {"name", "joint", "mesh", "color_rgba", "collides", "scale"})
        pname = r.string(p, "name", key)
        if pname in seen:
            raise r.fail(f"{key}.name", "a part name not used before", pname)
        seen.add(pname)
        pj = p.get("joint")
        if pj is not None and pj not in jnames:
            raise r.fail(f"{key}.joint", f"a joint of this head {sorted(jnames)}", pj)
        scale = _scale(r, p, key)
        mesh = load_part_mesh(r.string(p, "mesh", key), folder, f"{r.file}: {key}.mesh", scale)
        collides = p.get("collides", True)
        if not isinstance(collides, bool):
            raise r.fail(f"{key}.collides", "true or false", collides)
        parts.append(RigidPart(pname, pj, mesh, r.rgba(p, key, (0.8, 0.8, 0.8, 1.0)), collides))

    skin, skin_joint = _skin(r, data, folder, jnames, load_skin_mesh, bind_skin)
    n_vert = len(skin.vertices_mm)
    muscles = _muscles(r, data)
    if n_vert == 0:
        _needs_skin(r, data)
    anchors = _anchors(r, data, skin.vertices_mm)
    range_sources: dict[str, str] = {}
    actuators = _actuators(r, data, {j.name: j for j in joints}, anchors, n_vert, range_sources)
    if not actuators:
        raise r.fail("actuator", "at least one [[actuator]] table (one per servo: role, servo, kind)", None)
    couplings = _couplings(r, data, {a.role for a in actuators})
    landmarks: dict[str, Vec3] = {}
    lm = r.table(data.get("landmarks", {}), "landmarks")
    for k in lm:
        landmarks[k] = r.vec3(lm, k, "landmarks")
    return Head(
        name=name,
        face_type=face_type,  # type: ignore[arg-type]
        joints=joints,
        parts=tuple(parts),
        skin=skin,
        muscles=muscles,
        actuators=actuators,
        coupling_rules=couplings,
        skin_joint=skin_joint,
        au_table_path=_data_file(r, data, "au_table", folder),
        expressions_path=_data_file(r, data, "expressions", folder),
        au_direct_path=_data_file(r, data, "au_direct", folder),
        calibration_path=_inside(r, "calibration", r.string(data, "calibration", ""), folder)
        if "calibration" in data
        else None,
        profile_dir=folder,
        landmarks_mm=landmarks,
        range_sources=range_sources,
    )


def _data_file(r: _Reader, data: dict[str, Any], name: str, folder: Path) -> Path | None:
    """``"builtin"`` (or absent) -> None: the library's table for the face type; else an existing file."""
    if name not in data:
        return None
    v = r.string(data, name, "")
    if v == "builtin" or v.startswith("builtin:"):
        return None
    p = _inside(r, name, v, folder)
    if not p.is_file():
        raise r.fail(name, f'an existing file relative to {folder} (or "builtin")', v)
    return p


def _inside(r: _Reader, name: str, value: str, folder: Path) -> Path:
    """``folder / value``, refused when it leaves the profile folder (``../``, an absolute path, a symlink
    out): a profile must not make servoface read or overwrite files elsewhere (``calibrate --builtin``
    writes the calibration file the profile names). Pass ``--calibration`` / ``--out`` for a file elsewhere."""
    if not value or "\x00" in value:
        raise r.fail(name, "a file name inside the profile folder", value)
    p = folder / value
    try:
        p.resolve().relative_to(folder.resolve())
    except ValueError:
        raise r.fail(
            name, f"a path inside the profile folder {folder} (pass the file on the command line instead)", value
        ) from None
    return p


def _joints(r: _Reader, data: dict[str, Any]) -> tuple[Joint, ...]:
    raw: dict[str, Joint] = {}
    keys: dict[str, str] = {}
    for i, j in enumerate(r.array(data, "joint")):
        key = f"joint[{i}]"
        r.keys(j, key, {"name", "parent", "pivot_mm", "axis", "limits_deg", "neutral_deg"})
        name = r.string(j, "name", key)
        if name in raw:
            raise r.fail(f"{key}.name", "a joint name not used before", name)
        parent = j.get("parent") or None
        if parent is not None and not isinstance(parent, str):
            raise r.fail(f"{key}.parent", 'a joint name or "" for the head base', parent)
        lo, hi = r.interval(j, "limits_deg", key)
        neutral = r.number(j, "neutral_deg", key, 0.0)
        if not lo <= neutral <= hi:
            raise r.fail(f"{key}.neutral_deg", f"a value within limits_deg [{lo}, {hi}]", neutral)
        raw[name] = Joint(name, parent, r.vec3(j, "pivot_mm", key), r.vec3(j, "axis", key, unit=True), lo, hi, neutral)
        keys[name] = key
    for name, jt in raw.items():
        if jt.parent is not None and jt.parent not in raw:
            raise r.fail(f"{keys[name]}.parent", f"a joint of this head {sorted(raw)}", jt.parent)
    ordered: list[Joint] = []
    placed: set[str] = set()
    pending = list(raw.values())
    while pending:
        progress = [j for j in pending if j.parent is None or j.parent in placed]
        if not progress:
            raise r.fail(f"{keys[pending[0].name]}.parent", "a joint tree (no cycles)", pending[0].parent)
        for jt in progress:
            ordered.append(jt)
            placed.add(jt.name)
        pending = [jt for jt in pending if jt.name not in placed]
    return tuple(ordered)


def empty_skin() -> Skin:
    """The skin of a purely mechanical head: no vertices, no faces (every consumer sees empty arrays)."""
    verts = np.zeros((0, 3), dtype=np.float64)
    faces = np.zeros((0, 3), dtype=np.int64)
    weights = np.zeros((0, 1), dtype=np.float64)
    colours = np.zeros((0, 4), dtype=np.float64)
    for arr in (verts, faces, weights, colours):
        arr.flags.writeable = False
    return Skin(verts, faces, (), weights, (0.86, 0.70, 0.60, 1.0), colours)


def _scale(r: _Reader, d: dict[str, Any], key: str) -> float:
    scale = r.number(d, "scale", key, 1.0)
    if scale <= 0:
        raise r.fail(
            f"{key}.scale",
            "a positive factor to millimetres (1 for a mesh in mm, 1000 for metres, 25.4 for inches)",
            scale,
        )
    return scale


def _skin(
    r: _Reader, data: dict[str, Any], folder: Path, jnames: set[str], loader: Any, bind: bool = True
) -> tuple[Skin, str | None]:
    if "skin" not in data:
        return empty_skin(), None
    s = r.table(data["skin"], "skin")
    r.keys(
        s,
        "skin",
        {"mesh", "joint", "color_rgba", "smooth_iterations", "slit_corner_blend_mm", "bind", "scale"},
    )
    joint = s.get("joint") or None
    if joint is not None and joint not in jnames:
        raise r.fail("skin.joint", f"a joint of this head {sorted(jnames)}", joint)
    verts, faces, colours = loader(r.string(s, "mesh", "skin"), folder, f"{r.file}: skin.mesh", _scale(r, s, "skin"))
    iters = s.get("smooth_iterations", 0)
    if isinstance(iters, bool) or not isinstance(iters, int) or not 0 <= iters <= 200:
        raise r.fail("skin.smooth_iterations", "an integer in 0..200", iters)
    rules: list[BindRule] = []
    binds = s.get("bind", [])
    if not isinstance(binds, list):
        raise r.fail("skin.bind", "an array of tables ([[skin.bind]])", binds)
    for i, b in enumerate(binds):
        key = f"skin.bind[{i}]"
        b = r.table(b, key)
        r.keys(b, key, {"joint", "halfspaces", "sphere_centre_mm", "sphere_radius_mm", "falloff_mm", "weight"})
        bj = r.string(b, "joint", key)
        if bj not in jnames:
            raise r.fail(f"{key}.joint", f"a joint of this head {sorted(jnames)}", bj)
        hs = []
        for k, h in enumerate(b.get("halfspaces", [])):
            hk = f"{key}.halfspaces[{k}]"
            h = r.table(h, hk)
            r.keys(h, hk, {"point_mm", "normal", "falloff_mm"})
            hf = r.number(h, "falloff_mm", hk) if "falloff_mm" in h else None
            if hf is not None and hf <= 0:
                raise r.fail(f"{hk}.falloff_mm", "a positive distance", hf)
            hs.append(HalfSpace(r.vec3(h, "point_mm", hk), r.vec3(h, "normal", hk, unit=True), hf))
        centre = r.vec3(b, "sphere_centre_mm", key) if "sphere_centre_mm" in b else None
        radius = r.number(b, "sphere_radius_mm", key, 0.0)
        if centre is not None and radius <= 0:
            raise r.fail(f"{key}.sphere_radius_mm", "a positive radius with sphere_centre_mm", radius)
        fall = r.number(b, "falloff_mm", key, 2.0)
        weight = r.number(b, "weight", key, 1.0)
        if fall <= 0 or not 0 <= weight <= 1:
            raise r.fail(key, "falloff_mm > 0 and weight in 0..1", {"falloff_mm": fall, "weight": weight})
        rules.append(BindRule(bj, tuple(hs), centre, radius, fall, weight))
    blend = r.number(s, "slit_corner_blend_mm", "skin", 0.0)
    if blend < 0:
        raise r.fail("skin.slit_corner_blend_mm", "a distance >= 0", blend)
    if bind:
        names, w = bind_weights(verts, faces, tuple(rules), iters, blend)
    else:  # validation only (see build_checked): the weights' shape, every vertex on the skin's own joint
        names = tuple(dict.fromkeys(rule.joint for rule in rules))
        w = np.zeros((len(verts), len(names) + 1))
        w[:, 0] = 1.0
    if joint is not None:
        names = (joint, *names)
        w = np.concatenate([np.zeros((len(w), 1)), w], axis=1)
    elif names:
        pass  # column 0 (rest) is the head base already
    for arr in (verts, faces, w, colours):
        arr.flags.writeable = False
    skin = Skin(verts, faces, tuple(names), w, r.rgba(s, "skin", (0.86, 0.70, 0.60, 1.0)), colours)
    return skin, joint


def _needs_skin(r: _Reader, data: dict[str, Any]) -> None:
    """Muscles and skin anchors move skin: a head without ``[skin]`` may not name them."""
    hint = "a [skin] table (muscles and anchors move skin; this head has none): add [skin] or remove this"
    if r.array(data, "muscle"):
        raise r.fail("muscle[0]", hint, None)
    if data.get("anchors"):
        raise r.fail("anchors", hint, None)
    for i, a in enumerate(r.array(data, "actuator")):
        if a.get("kind") == "anchor":
            raise r.fail(f"actuator[{i}].kind", hint.replace("remove this", 'use kind = "joint"'), "anchor")


def _mirror(p: Vec3) -> Vec3:
    return (-p[0], p[1], p[2])


def _muscles(r: _Reader, data: dict[str, Any]) -> tuple[Muscle, ...]:
    out: list[Muscle] = []
    names: set[str] = set()
    common = {"name", "type", "max_contraction", "mirror"}
    for i, m in enumerate(r.array(data, "muscle")):
        key = f"muscle[{i}]"
        name = r.string(m, "name", key)
        mtype = r.string(m, "type", key)
        mc = r.number(m, "max_contraction", key, 0.25)
        if not 0.0 < mc <= 1.0:
            raise r.fail(f"{key}.max_contraction", "a number in (0, 1]", mc)
        muscle: Muscle
        if mtype == "linear":
            r.keys(m, key, common | {"attachment_mm", "insertion_mm", "zone_deg", "rs_mm", "rf_mm"})
            zone = r.number(m, "zone_deg", key)
            rs, rf = r.number(m, "rs_mm", key), r.number(m, "rf_mm", key)
            if not 0 < zone < 180:
                raise r.fail(f"{key}.zone_deg", "a half-angle in (0, 180) degrees", zone)
            if not 0 < rs < rf:
                raise r.fail(f"{key}.rf_mm", "0 < rs_mm < rf_mm", [rs, rf])
            a, ins = r.vec3(m, "attachment_mm", key), r.vec3(m, "insertion_mm", key)
            if math.dist(a, ins) < 1e-6:
                raise r.fail(f"{key}.insertion_mm", "a point distinct from attachment_mm", list(ins))
            muscle = LinearMuscle(name, a, ins, zone, rs, rf, mc)
        elif mtype == "sphincter":
            r.keys(m, key, common | {"centre_mm", "semi_axes_mm", "normal", "major_axis", "falloff"})
            axes = m.get("semi_axes_mm")
            if not isinstance(axes, list) or len(axes) not in (2, 3):
                raise r.fail(f"{key}.semi_axes_mm", "[lx, ly] or [lx, ly, lz] in mm", axes)
            ax = tuple(r.num(v, f"{key}.semi_axes_mm[{k}]", mm=True) for k, v in enumerate(axes))
            if min(ax) <= 0:
                raise r.fail(f"{key}.semi_axes_mm", "positive semi-axes", axes)
            nrm = r.vec3(m, "normal", key, unit=True) if "normal" in m else (0.0, 0.0, 1.0)
            maj = r.vec3(m, "major_axis", key, unit=True) if "major_axis" in m else (1.0, 0.0, 0.0)
            form = r.string(m, "falloff", key) if "falloff" in m else "corrected"
            if form not in ("corrected", "printed", "ring"):
                raise r.fail(f"{key}.falloff", "one of 'corrected', 'printed', 'ring'", form)
            muscle = SphincterMuscle(name, r.vec3(m, "centre_mm", key), ax, mc, nrm, maj, form)
        elif mtype == "sheet":
            r.keys(
                m,
                key,
                common | {"attachment_mm", "attachment_end_mm", "insertion_mm", "insertion_end_mm", "width_mm"},
            )
            width = r.number(m, "width_mm", key)
            if width <= 0:
                raise r.fail(f"{key}.width_mm", "a positive width", width)
            muscle = SheetMuscle(
                name,
                r.vec3(m, "attachment_mm", key),
                r.vec3(m, "attachment_end_mm", key),
                r.vec3(m, "insertion_mm", key),
                r.vec3(m, "insertion_end_mm", key),
                width,
                mc,
            )
        else:
            raise r.fail(f"{key}.type", "one of ['linear', 'sphincter', 'sheet']", mtype)
        batch = [muscle]
        if "mirror" in m:
            twin = r.string(m, "mirror", key)
            batch.append(_mirrored(muscle, twin))
        for mm in batch:
            if mm.name in names:
                raise r.fail(f"{key}.name", "a muscle name not used before", mm.name)
            names.add(mm.name)
            out.append(mm)
    return tuple(out)


def _mirrored(m: Muscle, name: str) -> Muscle:
    if isinstance(m, LinearMuscle):
        return LinearMuscle(
            name,
            _mirror(m.attachment_mm),
            _mirror(m.insertion_mm),
            m.zone_deg,
            m.rs_mm,
            m.rf_mm,
            m.max_contraction,
        )
    if isinstance(m, SphincterMuscle):
        return SphincterMuscle(
            name,
            _mirror(m.centre_mm),
            m.semi_axes_mm,
            m.max_contraction,
            _mirror(m.normal),
            _mirror(m.major_axis),
        )
    return SheetMuscle(
        name, _mirror(m.attachment_mm), _mirror(m.attachment_end_mm), _mirror(m.insertion_mm),
        _mirror(m.insertion_end_mm), m.width_mm, m.max_contraction,
    )  # fmt: skip


def _anchors(r: _Reader, data: dict[str, Any], verts: np.ndarray) -> dict[str, int]:
    table = r.table(data.get("anchors", {}), "anchors")
    out: dict[str, int] = {}
    n = len(verts)
    for name, a in table.items():
        key = f"anchors.{name}"
        a = r.table(a, key)
        r.keys(a, key, {"vertex", "near_mm", "mirror"})
        if "vertex" in a:
            v = a["vertex"]
            if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v < n:
                raise r.fail(f"{key}.vertex", f"a skin vertex index in 0..{n - 1}", v)
            idx = [(name, v)]
            if "mirror" in a:
                p = verts[v] * np.array([-1.0, 1.0, 1.0])
                idx.append((r.string(a, "mirror", key), int(np.argmin(np.linalg.norm(verts - p, axis=1)))))
        elif "near_mm" in a:
            p = np.asarray(r.vec3(a, "near_mm", key))
            dist = np.linalg.norm(verts - p, axis=1)
            if float(dist.min()) > ANCHOR_MAX_GAP_MM:
                raise r.fail(
                    f"{key}.near_mm",
                    f"a point within {ANCHOR_MAX_GAP_MM} mm of the skin (the nearest vertex is "
                    f"{float(dist.min()):.1f} mm away)",
                    list(p),
                )
            idx = [(name, int(np.argmin(dist)))]
            if "mirror" in a:
                q = p * np.array([-1.0, 1.0, 1.0])
                idx.append((r.string(a, "mirror", key), int(np.argmin(np.linalg.norm(verts - q, axis=1)))))
        else:
            raise r.fail(key, "a table with vertex = <index> or near_mm = [x, y, z]", a)
        for nm, vi in idx:
            if nm in out:
                raise r.fail(key, "an anchor name not used before", nm)
            out[nm] = vi
    return out


def _actuators(
    r: _Reader,
    data: dict[str, Any],
    joints: dict[str, Joint],
    anchors: dict[str, int],
    n_vert: int,
    range_sources: dict[str, str],
) -> tuple[Actuator, ...]:
    """The ``[[actuator]]`` tables; ``range_sources`` is filled with role -> the key that sets its range."""
    out: list[Actuator] = []
    joint_keys = {j.get("name"): f"joint[{i}]" for i, j in enumerate(r.array(data, "joint"))}
    ids: dict[int, str] = {}
    driven: dict[str, str] = {}
    roles: set[str] = set()
    for i, a in enumerate(r.array(data, "actuator")):
        key = f"actuator[{i}]"
        role = r.string(a, "role", key)
        if role in roles:
            raise r.fail(f"{key}.role", "a role not used before", role)
        roles.add(role)
        servo = _servo(r, r.table(r.req(a, "servo", key), f"{key}.servo"), f"{key}.servo")
        if servo.id in ids:
            raise r.fail(
                f"{key}.servo.id",
                f"a servo id not used before (id {servo.id} is {ids[servo.id]!r})",
                servo.id,
            )
        ids[servo.id] = role
        kind = r.string(a, "kind", key)
        if kind == "joint":
            r.keys(a, key, {"role", "servo", "kind", "joints", "range_deg", "neutral_deg"})
            js = a.get("joints", [role])
            if not isinstance(js, list) or not js or not all(isinstance(j, str) for j in js):
                raise r.fail(f"{key}.joints", "a non-empty list of joint names", js)
            for k, jn in enumerate(js):
                if jn not in joints:
                    raise r.fail(f"{key}.joints[{k}]", f"a joint of this head {sorted(joints)}", jn)
                if jn in driven:
                    raise r.fail(f"{key}.joints[{k}]", f"a joint no other actuator drives ({driven[jn]!r} does)", jn)
                driven[jn] = role
            lo_j = max(joints[j].lower_deg for j in js)
            hi_j = min(joints[j].upper_deg for j in js)
            lo, hi = r.interval(a, "range_deg", key) if "range_deg" in a else (lo_j, hi_j)
            if lo < lo_j - 1e-9 or hi > hi_j + 1e-9:
                raise r.fail(f"{key}.range_deg", f"a range within the joints' limits [{lo_j}, {hi_j}]", [lo, hi])
            neutral = r.number(a, "neutral_deg", key, float(np.clip(0.0, lo, hi)))
            if not lo <= neutral <= hi:
                raise r.fail(f"{key}.neutral_deg", f"a value within [{lo}, {hi}]", neutral)
            if "range_deg" in a:
                range_sources[role] = f"{r.file}: {key}.range_deg"
            else:  # the joint(s) whose limits bound the range
                bound = [joint_keys[j] for j in js if joints[j].lower_deg == lo or joints[j].upper_deg == hi]
                range_sources[role] = f"{r.file}: " + ", ".join(f"{k}.limits_deg" for k in bound)
            out.append(JointActuator(role, servo, tuple(js), lo, hi, neutral))
        elif kind == "anchor":
            r.keys(
                a,
                key,
                {"role", "servo", "kind", "anchor", "vertex", "line", "range_mm", "neutral_mm", "radius_mm"},
            )
            if "anchor" in a:
                an = r.string(a, "anchor", key)
                if an not in anchors:
                    raise r.fail(f"{key}.anchor", f"an anchor named in [anchors] {sorted(anchors)}", an)
                vertex = anchors[an]
            else:
                raw_vertex = a.get("vertex")
                if isinstance(raw_vertex, bool) or not isinstance(raw_vertex, int) or not 0 <= raw_vertex < n_vert:
                    raise r.fail(
                        f"{key}.vertex",
                        f"a skin vertex index in 0..{n_vert - 1} (or anchor = <name>)",
                        raw_vertex,
                    )
                vertex = raw_vertex
            lo, hi = r.interval(a, "range_mm", key)
            range_sources[role] = f"{r.file}: {key}.range_mm"
            neutral = r.number(a, "neutral_mm", key, float(np.clip(0.0, lo, hi)))
            if not lo <= neutral <= hi:
                raise r.fail(f"{key}.neutral_mm", f"a value within [{lo}, {hi}]", neutral)
            radius = r.number(a, "radius_mm", key, 15.0)
            if radius <= 0:
                raise r.fail(f"{key}.radius_mm", "a positive radius", radius)
            out.append(AnchorActuator(role, servo, vertex, r.vec3(a, "line", key, unit=True), lo, hi, neutral, radius))
        else:
            raise r.fail(f"{key}.kind", '"joint" or "anchor"', kind)
    return tuple(out)


def _servo(r: _Reader, s: dict[str, Any], key: str) -> ServoRef:
    r.keys(s, key, {"id", "model"})
    sid = r.req(s, "id", key)
    if isinstance(sid, bool) or not isinstance(sid, int) or not 0 <= sid <= 252:
        raise r.fail(f"{key}.id", "an integer Dynamixel id in 0..252", sid)
    model = r.string(s, "model", key)
    model = SERVO_MODEL_ALIASES.get(model, model)
    if model not in SERVO_MODELS:
        near = difflib.get_close_matches(model.upper(), SERVO_MODELS, n=1, cutoff=0.9)  # not W210 -> W350
        hint = f" (did you mean {near[0]!r}?)" if near else ""
        raise r.fail(f"{key}.model", f"one of the known servo models {list(SERVO_MODELS)}{hint}", model)
    return ServoRef(sid, model)


def _couplings(r: _Reader, data: dict[str, Any], roles: set[str]) -> tuple[CouplingRule, ...]:
    out = []
    for i, c in enumerate(r.array(data, "coupling")):
        key = f"coupling[{i}]"
        r.keys(c, key, {"roles", "max_sum_share", "note"})
        rl = r.req(c, "roles", key)
        if not isinstance(rl, list) or len(rl) < 2 or not all(isinstance(x, str) for x in rl):
            raise r.fail(f"{key}.roles", "a list of at least two actuator roles", rl)
        for k, role in enumerate(rl):
            if role not in roles:
                raise r.fail(f"{key}.roles[{k}]", f"an actuator role of this head {sorted(roles)}", role)
        share = r.number(c, "max_sum_share", key)
        if not 0 < share <= len(rl):
            raise r.fail(f"{key}.max_sum_share", f"a number in (0, {len(rl)}]", share)
        note = c.get("note", "")
        if not isinstance(note, str):
            raise r.fail(f"{key}.note", "a string", note)
        out.append(CouplingRule(tuple(rl), share, note))
    return tuple(out)
