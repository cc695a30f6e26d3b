"""API keys: random tokens handed out once, stored only as their SHA-256 digest.

The keys are 256-bit random strings, so a plain SHA-256 (no salt, no key stretching) is enough
to make a stolen database useless for calling the API while lookups stay one indexed query.
"""

from __future__ import annotations

import hashlib
import secrets

KEY_PREFIX = "tp_"


def generate_key() -> str:
    """A new API key (shown to its owner once)."""
    return KEY_PREFIX + secrets.token_urlsafe(32)


def hash_key(key: str) -> str:
    """The stored form of an API key: hex SHA-256."""
    return hashlib.sha256(key.encode("utf-8")).hexdigest()


def key_prefix(key: str) -> str:
    """The first characters of a key, kept in clear to tell keys apart in listings."""
    return key[:10]
