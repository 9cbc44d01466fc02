"""Zenoh arguments shared by `node`, `cue` and `heads`: endpoints, credentials, TLS, --insecure."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any


def add_network_arguments(parser: argparse.ArgumentParser, *, node: bool) -> None:
    if node:
        parser.add_argument(
            "--listen",
            action="append",
            default=None,
            help="Zenoh endpoint to listen on (repeatable; default tcp/127.0.0.1:7447)",
        )
    parser.add_argument(
        "--connect", action="append", default=[], help="Zenoh endpoint (a node or a router) to connect to (repeatable)"
    )
    parser.add_argument("--user", help="user name for Zenoh user/password authentication")
    parser.add_argument("--password", help="its password")
    if node:
        parser.add_argument("--users-file", type=Path, help="accept only peers in this file (lines user:password)")
        parser.add_argument(
            "--operators",
            default=None,
            help="USER[,USER...]: only these users (of --users-file) may move the head; every other "
            "authenticated peer may watch it and press the e-stop (Zenoh access control)",
        )
    parser.add_argument("--tls-ca", type=Path, help="TLS root CA certificate (PEM)")
    parser.add_argument("--tls-cert", type=Path, help="TLS certificate (PEM) for listening")
    parser.add_argument("--tls-key", type=Path, help="TLS private key (PEM) for listening")
    parser.add_argument(
        "--insecure",
        action="store_true",
        help="allow a non-loopback endpoint without TLS and credentials (anyone reaching it can drive the head)",
    )


def open_from_args(args: argparse.Namespace, *, node: bool, keys: Any = None) -> Any:
    """The session of a node (``keys``: its head, for the access-control rules) or of a client."""
    from servoface.controller.network.acl import node_acl, parse_operators
    from servoface.controller.network.zconfig import DEFAULT_LISTEN, Credentials, TlsFiles, open_session

    listen = (args.listen or [DEFAULT_LISTEN]) if node else []
    creds = Credentials(args.user, args.password, getattr(args, "users_file", None))
    tls = TlsFiles(args.tls_ca, args.tls_cert, args.tls_key)
    operators = parse_operators(getattr(args, "operators", None))
    acl = node_acl(keys, operators) if operators and keys is not None else None
    return open_session(listen=listen, connect=args.connect, creds=creds, tls=tls, insecure=args.insecure, acl=acl)
