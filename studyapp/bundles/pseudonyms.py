"""Platform ids in a bundle: each replaced by a keyed hash, so the bundle names no person.

A participant's crowd-platform id (a Prolific or MTurk worker id) and the platform's other
values in their entry link (session, assignment and HIT ids) are replaced by
HMAC-SHA-256 under a key. With the researcher's own key the same id gets the same
pseudonym in every bundle they export (participants can be followed across studies by
whoever holds the key, and by no one else); without one, each export draws a random key
that is used once and never written anywhere, so the pseudonyms link nothing outside
that bundle. The key is never in the bundle.
"""

from __future__ import annotations

import hashlib
import hmac
import secrets

KEY_BYTES = 32


def export_key(given: str | None) -> bytes:
    """The researcher's key (a passphrase, at least 16 characters), or a fresh random key."""
    if given is None:
        return secrets.token_bytes(KEY_BYTES)
    if len(given) < 16:
        raise ValueError("a pseudonym key must be at least 16 characters long (a short key can be guessed)")
    return given.encode()


def pseudonym(key: bytes, value: str) -> str:
    """``value`` as HMAC-SHA-256 under ``key``, in hex."""
    return hmac.new(key, value.encode(), hashlib.sha256).hexdigest()


def pseudonymous_data(key: bytes, data: dict) -> dict:
    """A participant's platform values with every value replaced by its pseudonym."""
    return {name: pseudonym(key, str(value)) for name, value in data.items()}


__all__ = ["export_key", "pseudonym", "pseudonymous_data"]
