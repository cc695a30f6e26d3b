"""API key scopes: what a key may do (read, write, admin) and what each request needs.

A key holds a set of scopes. ``read`` lets it read, ``write`` lets it upload and change
ordinary data (runs, tracks, vehicles, limits, surveys), ``admin`` lets it destroy or
rewrite history: every DELETE, editing a vehicle's parameters (its runs are reprocessed),
calibrating a vehicle (a calibration may be applied as a new vehicle version) and storing a
track's centerline (it replaces the old line, kept nowhere, as a DELETE would, and decides
where every later run of the track is placed). The
scope a request needs is decided from its method and path alone, before its body is read
(see :mod:`app.api.access`).
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from typing import Literal, get_args

KeyScope = Literal["read", "write", "admin"]
SCOPES: tuple[KeyScope, ...] = get_args(KeyScope)
"""Every scope, from the least to the most powerful."""

ALL_SCOPES = " ".join(SCOPES)
"""The scopes of a key made before scopes existed (and the default of a new key)."""

READ_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})

ADMIN_WRITES: tuple[tuple[str, re.Pattern[str]], ...] = (
    ("PATCH", re.compile(r"^/api/v1/vehicles/[^/]+$")),
    ("POST", re.compile(r"^/api/v1/vehicles/[^/]+/calibrate$")),
    ("PUT", re.compile(r"^/api/v1/tracks/[^/]+/centerline$")),
)
"""Writes other than DELETE that need ``admin``: (method, path pattern)."""


def required_scope(method: str, path: str) -> KeyScope:
    """The scope a request with ``method`` on ``path`` needs."""
    if method in READ_METHODS:
        return "read"
    if method == "DELETE":
        return "admin"
    if any(m == method and p.match(path) for m, p in ADMIN_WRITES):
        return "admin"
    return "write"


def parse_scopes(text: str | Iterable[str]) -> frozenset[KeyScope]:
    """The scopes named in ``text`` (separated by commas or spaces).

    Raises
    ------
    ValueError
        For an unknown scope name, or none at all.
    """
    words = text.replace(",", " ").split() if isinstance(text, str) else list(text)
    unknown = [w for w in words if w not in SCOPES]
    if unknown:
        raise ValueError(f"unknown scope {unknown[0]!r}: scopes are {', '.join(SCOPES)}")
    if not words:
        raise ValueError(f"at least one scope is needed ({', '.join(SCOPES)})")
    return frozenset(w for w in SCOPES if w in words)


def format_scopes(scopes: Iterable[str]) -> str:
    """The stored form of a set of scopes: their names in :data:`SCOPES` order, spaced."""
    chosen = set(scopes)
    return " ".join(s for s in SCOPES if s in chosen)
