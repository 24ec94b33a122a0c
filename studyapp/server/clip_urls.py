"""Signed, expiring addresses of the clips, for a deployment whose proxy serves the files
(``MEDIA_ACCEL``): a clip's address carries when it stops working and a keyed hash of its
path and that time, so an address copied out of a participant's page stops working soon
after the page (``CLIP_URL_LIFETIME_S``), and no address can be made up from a token alone.

The time is rounded up to an eighth of the lifetime, so that the pages a participant goes
through within those minutes name each clip by one address, and the browser's copy of a
clip fetched ahead for the next page is the one that page plays. Without a proxy (the
embedded ``manage.py serve``) the addresses are the plain ones.

``answering_signed_clips`` wraps the WSGI application (``studyapp.server.wsgi``) so that a
current signed address is answered before Django sees it: a study asks for about as many
clips as it stores ratings, and the check needs no database, session or middleware.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from urllib.parse import parse_qsl, urlencode

from django.conf import settings
from django.http import Http404
from django.utils.crypto import constant_time_compare, salted_hmac

from studyapp.server.file_responses import ACCEL_MEDIA_PREFIX, accel_headers

_SALT = "studyapp.server.clip_urls"
UNTIL, SIGNATURE = "until", "sig"


def _signature(relative_path: str, until: int) -> str:
    return salted_hmac(_SALT, f"{relative_path}\0{until}", algorithm="sha256").hexdigest()[:32]


def address_until(now: float | None = None) -> int:
    """When a clip address made at ``now`` stops working: CLIP_URL_LIFETIME_S later, rounded up
    to an eighth of it (the rule of the proxy's addresses and of the bucket's)."""
    lifetime = settings.CLIP_URL_LIFETIME_S
    step = lifetime / 8
    return int(math.ceil(((now if now is not None else time.time()) + lifetime) / step) * step)


def signed_clip_url(relative_path: str, now: float | None = None) -> str:
    """The address of the clip at ``relative_path`` under MEDIA_ROOT, working for CLIP_URL_LIFETIME_S
    (and at most an eighth more)."""
    until = address_until(now)
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


WSGIApplication = Callable[[dict, Callable], Iterable[bytes]]


def answering_signed_clips(application: WSGIApplication) -> WSGIApplication:
    """``application`` with, behind the proxy and without a bucket, a GET or HEAD of a current
    signed clip address answered here with the media view's own empty X-Accel-Redirect answer.
    Anything else, a refusal included, goes on to ``application``: Django's media view answers
    it as it would have (404 for an address unsigned, altered, expired or naming no clip file)."""

    def answer(environ: dict, start_response: Callable) -> Iterable[bytes]:
        headers = _accel_answer(environ) if settings.MEDIA_ACCEL and not settings.MEDIA_BUCKET_URL else None
        if headers is None:
            return application(environ, start_response)
        start_response("200 OK", [("Content-Type", "text/html; charset=utf-8"), ("Content-Length", "0"), *headers])
        return [b""]

    return answer


def _accel_answer(environ: dict) -> list[tuple[str, str]] | None:
    """The accel headers for a request of a current signed clip address, else None."""
    if environ.get("REQUEST_METHOD") not in ("GET", "HEAD"):
        return None
    prefix = f"/{settings.MEDIA_URL.strip('/')}/"
    try:  # WSGI's path holds the URL's bytes as Latin-1; Django reads them as UTF-8, as here
        path = environ.get("PATH_INFO", "").encode("latin-1").decode("utf-8")
    except UnicodeError:
        return None
    relative_path = path[len(prefix):]
    if not path.startswith(prefix) or not relative_path.startswith("stimuli/"):
        return None
    query = dict(parse_qsl(environ.get("QUERY_STRING", "")))  # a repeated name: its last value, as Django's GET
    if not is_signed_and_current(relative_path, query):
        return None
    try:
        return accel_headers(relative_path, settings.MEDIA_ROOT, ACCEL_MEDIA_PREFIX, seconds_left(query))
    except Http404:
        return None
