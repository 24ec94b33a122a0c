"""The researcher's platform credentials (Prolific's API token, MTurk's access key), kept
only in their login session and only encrypted.

Django keeps sessions in the database, so a token put in the session as it is would lie
there in plain text. It is encrypted first (Fernet: AES-128-CBC with an HMAC-SHA256)
under a key derived from SECRET_KEY, which production sets in the environment: a copy
of the database alone (a backup, a dump) reveals nothing. It is kept for the review it
was entered for and no longer: it ends with the login, and after ``CREDENTIALS_TTL_S``
it must be entered again. A Prolific token never expires and carries every permission
of the account, so it is worth less to keep than to ask for again. It never reaches a
log, a page or the action log.
"""

from __future__ import annotations

import base64
import json

from cryptography.fernet import Fernet, InvalidToken
from django.contrib.sessions.backends.base import SessionBase
from django.utils.crypto import salted_hmac

SESSION_KEY = "platform_credentials"
CREDENTIALS_TTL_S = 4 * 3600


def _fernet() -> Fernet:
    digest = salted_hmac("studyapp.platforms.credentials", "", algorithm="sha256").digest()
    return Fernet(base64.urlsafe_b64encode(digest))


def keep(session: SessionBase, platform: str, secret: dict[str, str | bool]) -> None:
    """Keep ``secret`` (a token, or a key pair and options) for ``platform``, encrypted."""
    sealed = _fernet().encrypt(json.dumps(secret).encode()).decode()
    session[SESSION_KEY] = {**session.get(SESSION_KEY, {}), platform: sealed}


def read(session: SessionBase, platform: str) -> dict | None:
    """The credentials kept for ``platform``, or None (none kept, or kept too long ago)."""
    sealed = session.get(SESSION_KEY, {}).get(platform)
    if sealed is None:
        return None
    try:
        return json.loads(_fernet().decrypt(sealed.encode(), ttl=CREDENTIALS_TTL_S))
    except InvalidToken:  # expired, or sealed under another SECRET_KEY
        forget(session, platform)
        return None


def forget(session: SessionBase, platform: str) -> None:
    kept = dict(session.get(SESSION_KEY, {}))
    if kept.pop(platform, None) is not None:
        session[SESSION_KEY] = kept


__all__ = ["CREDENTIALS_TTL_S", "forget", "keep", "read"]
