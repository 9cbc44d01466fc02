"""Zenoh access control for a node: who may move the head, who may only watch it (and stop it).

With ``--operators USER[,USER...]`` (and ``--users-file``, so every peer has a user name) a node enables
Zenoh's access control (``access_control`` in its session config, enforced by Zenoh on every message that
enters or leaves the node), default **deny**, with these rules:

- ``servoface-read`` (every authenticated peer, both ways): declarations of subscribers, queryables and
  liveliness, queries and replies, on ``servoface/**`` and ``@servoface/**``;
- ``servoface-state`` (every authenticated peer, leaving the node): put on ``<base>/state/**``;
- ``servoface-estop`` (every authenticated peer, entering the node): put on ``servoface/*/*/cmd/estop``;
- ``servoface-control`` (the operators only, entering the node): put on ``<base>/aus/*``, ``<base>/cmd/*``
  and ``servoface/*/*/cmd/*`` (``<base>`` = ``servoface/<site>/<name>``).

So an operator streams AU frames and sends commands; any other authenticated peer (an *observer*: a
dashboard, a museum guard's tablet) sees presence, status and state and can press the e-stop, but its AU
frames and commands never reach the node (Zenoh drops them; nothing is counted, nothing moves). A peer
without credentials cannot open a session at all. Zenoh matches a rule's key expression only when it
*includes* the message's key, hence the ``servoface/*/*/...`` forms for commands sent to a pattern of heads
(``servoface cue --heads 'lobby/*' estop``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from servoface.controller.network.errors import NetworkError
from servoface.controller.network.keys import PRESENCE_ROOT, ROOT, HeadKeys, check_token

READ_MESSAGES = (
    "declare_subscriber",
    "declare_queryable",
    "query",
    "reply",
    "liveliness_token",
    "liveliness_query",
    "declare_liveliness_subscriber",
)


def parse_operators(text: str | Sequence[str] | None) -> tuple[str, ...]:
    """``"ada,bob"`` or ["ada", "bob"] -> the operator user names (plain tokens)."""
    if text is None:
        return ()
    items = text.split(",") if isinstance(text, str) else list(text)
    names = tuple(n.strip() for n in items if n.strip())
    if not names:
        raise NetworkError("--operators: expected one or more user names, e.g. --operators ada,bob")
    for n in names:
        check_token(n, field="--operators user name")
    return names


def node_acl(keys: HeadKeys, operators: Sequence[str]) -> dict[str, Any]:
    """The ``access_control`` section of a node's Zenoh config (see the module doc)."""
    ops = parse_operators(list(operators))
    base = keys.base
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": [
            {
                "id": "servoface-read",
                "permission": "allow",
                "flows": ["ingress", "egress"],
                "messages": list(READ_MESSAGES),
                "key_exprs": [f"{ROOT}/**", f"{PRESENCE_ROOT}/**"],
            },
            {
                "id": "servoface-state",
                "permission": "allow",
                "flows": ["egress"],
                "messages": ["put"],
                "key_exprs": [f"{base}/state/**"],
            },
            {
                "id": "servoface-estop",
                "permission": "allow",
                "flows": ["ingress"],
                "messages": ["put"],
                "key_exprs": [f"{ROOT}/*/*/cmd/estop"],
            },
            {
                "id": "servoface-control",
                "permission": "allow",
                "flows": ["ingress"],
                "messages": ["put"],
                "key_exprs": [f"{base}/aus/*", f"{base}/cmd/*", f"{ROOT}/*/*/cmd/*"],
            },
        ],
        "subjects": [
            {"id": "authenticated"},  # every peer that opened a session (it passed user/password)
            {"id": "operators", "usernames": list(ops)},
        ],
        "policies": [
            {"rules": ["servoface-read", "servoface-state", "servoface-estop"], "subjects": ["authenticated"]},
            {"rules": ["servoface-control"], "subjects": ["operators"]},
        ],
    }
