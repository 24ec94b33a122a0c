"""Signed, expiring addresses of the clips, for a deployment whose proxy serves the files
(``MEDIA_ACCEL``): a clip's address carries when it stops working and a keyed hash of its
path and that time, so an address copied out of a participant's page stops working soon
after the page (``CLIP_URL_LIFETIME_S``), and no address can be made up from a token alone.

The time is rounded up to an eighth of the lifetime, so that the pages a participant goes
through within those minutes name each clip by one address, and the browser's copy of a
clip fetched ahead for the next page is the one that page plays. Without a proxy (the
embedded ``manage.py serve``) the addresses are the plain ones.
"""

from __future__ import annotations

import math
import time
from urllib.parse import urlencode

from django.conf import settings
from django.utils.crypto import constant_time_compare, salted_hmac

_SALT = "studyapp.server.clip_urls"
UNTIL, SIGNATURE = "until", "sig"


def _signature(relative_path: str, until: int) -> str:
    return salted_hmac(_SALT, f"{relative_path}\0{until}", algorithm="sha256").hexdigest()[:32]


def signed_clip_url(relative_path: str, now: float | None = None) -> str:
    """The address of the clip at ``relative_path`` under MEDIA_ROOT, working for CLIP_URL_LIFETIME_S
    (and at most an eighth more)."""
    lifetime = settings.CLIP_URL_LIFETIME_S
    step = lifetime / 8
    until = int(math.ceil(((now if now is not None else time.time()) + lifetime) / step) * step)
    query = urlencode({UNTIL: until, SIGNATURE: _signature(relative_path, until)})
    return f"/{settings.MEDIA_URL.strip('/')}/{relative_path}?{query}"


def seconds_left(query: dict[str, str], now: float | None = None) -> int:
    """How long the signed address of ``query`` still works (0 where it names no time): how
    long a browser may keep the clip it fetched, the address's lifetime being the clip's."""
    until = query.get(UNTIL, "")
    if not until.isdigit() or len(until) > 12:
        return 0
    return max(0, int(until) - int(now if now is not None else time.time()))


def is_signed_and_current(relative_path: str, query: dict[str, str], now: float | None = None) -> bool:
    """Whether a request's query signs ``relative_path`` and has not expired."""
    until, signature = query.get(UNTIL, ""), query.get(SIGNATURE, "")
    if not until.isdigit() or len(until) > 12:
        return False
    if int(until) < (now if now is not None else time.time()):
        return False
    return constant_time_compare(signature, _signature(relative_path, int(until)))
