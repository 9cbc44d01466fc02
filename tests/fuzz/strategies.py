"""Hypothesis strategies for malformed input: values a file, a message or a caller might really send."""

from __future__ import annotations

import copy
from typing import Any

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

HUGE = st.sampled_from([10**400, -(10**400), 2**63, 2**64 + 1, 10**20, -(10**20)])
weird_text = st.one_of(
    st.sampled_from(
        [
            "AU１２",  # full-width digits
            " AU12",
            "AU12\n",
            "AU12 ",
            "\x1b[31mAU12",
            "\ud800",
            "AU\u200b12",
            "AU12\u0301",
            "au12l",
            "AU0012",
            "AU١٢",  # Arabic-Indic digits
            "",
            "AU",
            "AU99999999999999999999",
            "𝐀𝐔12",
        ]
    ),
    st.text(max_size=12),
)
scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-5, 5),
    HUGE,
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(-2, 2),
    weird_text,
)
values = st.recursive(
    scalars,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4),
        st.dictionaries(weird_text, inner, max_size=4),
        st.frozensets(st.integers(0, 3), max_size=3),
    ),
    max_leaves=8,
)


def deep(depth: int, leaf: Any = 0) -> Any:
    out = leaf
    for _ in range(depth):
        out = [out]
    return out


def paths(data: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every key path into nested dicts/lists."""
    out = [prefix]
    if isinstance(data, dict):
        for k, v in data.items():
            out += paths(v, (*prefix, k))
    elif isinstance(data, list):
        for i, v in enumerate(data):
            out += paths(v, (*prefix, i))
    return out


def mutate(data: Any, path: tuple[Any, ...], value: Any, how: str) -> Any:
    """``data`` with the node at ``path`` replaced (``set``), deleted (``drop``) or given a stray key
    (``extra``). Only the containers along the path are copied (shallow): the rest is shared with ``data``,
    which is left as it was (a deep copy of a whole head profile per example cost more than checking it)."""
    if not path:
        return value
    out = copy.copy(data)
    node = out
    for key in path[:-1]:
        child = copy.copy(node[key])
        node[key] = child
        node = child
    last = path[-1]
    if how == "drop" and isinstance(node, dict):
        del node[last]
    elif how == "extra" and isinstance(node, dict):
        node[f"zz_{last}"] = value
    else:
        node[last] = value
    return out


_PATHS: dict[int, tuple[Any, list[tuple[Any, ...]]]] = {}


def _paths_of(base: Any) -> list[tuple[Any, ...]]:
    """`paths(base)`, computed once per base document."""
    hit = _PATHS.get(id(base))
    if hit is None or hit[0] is not base:
        hit = (base, paths(base))
        _PATHS[id(base)] = hit
    return hit[1]


@st.composite
def mutated(draw: st.DrawFn, base: Any, max_depth: int = 50_000, root: bool = True) -> Any:
    """``base`` with one node replaced by a random value, deleted, or given a stray key (``root``: the
    whole document may be replaced too — a parsed TOML file is always a table). ``base`` is never changed."""
    every = _paths_of(base)
    all_paths = every if root else every[1:]
    path = draw(st.sampled_from(all_paths))
    how = draw(st.sampled_from(["set", "set", "set", "drop", "extra"]))
    depths = [d for d in (50, 300, 2000, 50_000) if d <= max_depth]
    value = draw(st.one_of(values, st.builds(deep, st.sampled_from(depths))))
    return mutate(base, path, value, how)


# One named settings profile for every fuzz property: no deadline (a loaded CI machine), no example
# database (nothing carried between runs), derandomized (the same inputs on every CI run: a failure there
# reproduces here). Each test sets its own ``max_examples``.
settings.register_profile(
    "servoface-fuzz",
    deadline=None,
    suppress_health_check=list(HealthCheck),
    database=None,
    derandomize=True,
    print_blob=False,
)


def fuzz_settings(max_examples: int) -> settings:
    """The ``servoface-fuzz`` profile with ``max_examples``."""
    return settings(settings.get_profile("servoface-fuzz"), max_examples=max_examples)
