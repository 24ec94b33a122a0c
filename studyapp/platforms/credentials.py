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

A token or key is kept only if it is printable ASCII without spaces, as the platforms
give them (``validate_secret_text``): each goes into an HTTP header (MTurk's into its
signature), where a CR or LF would split the header, and http.client refuses such a
value with an error that quotes it, the token, into the traceback and the log.
"""

from __future__ import annotations

import base64
import json
import re

from cryptography.fernet import Fernet, InvalidToken
from django.contrib.sessions.backends.base import SessionBase
from django.core.exceptions import ValidationError
from django.utils.crypto import salted_hmac

SESSION_KEY = "platform_credentials"
CREDENTIALS_TTL_S = 4 * 3600
SECRET_TEXT = re.compile(r"[!-~]+")


def is_secret_text(value: object) -> bool:
    """Whether ``value`` may be sent as a token or key: printable ASCII, no spaces."""
    return isinstance(value, str) and SECRET_TEXT.fullmatch(value) is not None


def validate_secret_text(value: str) -> None:
    """A form field's validator; the message never repeats the value."""
    if not is_secret_text(value):
        raise ValidationError("This holds a space, a control character (such as a line break) or a character "
                              "outside ASCII, which no platform's token or key has: copy it again from the "
                              "platform.", code="secret_text")


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
        secret = json.loads(_fernet().decrypt(sealed.encode(), ttl=CREDENTIALS_TTL_S))
    except InvalidToken:  # expired, or sealed under another SECRET_KEY
        forget(session, platform)
        return None
    if not all(is_secret_text(value) for value in secret.values() if not isinstance(value, bool)):
        forget(session, platform)  # kept before tokens were checked: asked for again
        return None
    return secret


def forget(session: SessionBase, platform: str) -> None:
    kept = dict(session.get(SESSION_KEY, {}))
    if kept.pop(platform, None) is not None:
        session[SESSION_KEY] = kept


__all__ = ["CREDENTIALS_TTL_S", "forget", "is_secret_text", "keep", "read", "validate_secret_text"]
