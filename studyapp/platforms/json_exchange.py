"""One request to a platform's JSON API over HTTP(S), and its answer believed only as far
as it shows (``exchange``).

- Only http(s) addresses are asked, and no redirect is followed: urllib's would send the
  request's ``Authorization`` header to wherever the ``Location`` points, and a redirect
  to a page that answers 200 is no sign that the API did anything.
- The answer is read within the call's deadline and up to ``MAX_ANSWER_BYTES``.
- A 2xx answer is JSON in content type and text, with no NaN or infinity (which no JSON
  column stores and no API means); a 4xx is the platform's refusal, returned with its
  words; anything else (a redirect, a server error, an answer that is not HTTP or is cut
  short, a timeout once the request went out) raises ``UnconfirmedAnswer``: the platform
  may or may not have done it. A request that never went out raises ``PlatformError``.
- A 429 is asked again after its ``Retry-After`` (whole seconds or an HTTP date, within
  0 to ``LONGEST_WAIT_S``; anything else waits ``DEFAULT_WAIT_S``), up to
  ``RATE_LIMIT_RETRIES`` times and never past the deadline.

Messages quote the answer's text with its control characters replaced, so that nothing
the platform sends can forge a line of the log.
"""

from __future__ import annotations

import http.client
import json
import math
import re
import time
import urllib.error
import urllib.request
from dataclasses import dataclass
from datetime import datetime, timezone
from email.utils import parsedate_to_datetime
from urllib.parse import urlsplit

from studyapp.platforms.calls import PlatformError, UnconfirmedAnswer
from studyapp.server.uploads.bounded_reading import finite_float

TIMEOUT_S = 30.0  # the longest wait for the platform to answer at all
MAX_ANSWER_BYTES = 8 * 1024 * 1024
RATE_LIMIT_RETRIES, DEFAULT_WAIT_S, LONGEST_WAIT_S = 2, 1.0, 10.0
TEXT_SHOWN = 300  # characters of an answer quoted in a message
CHUNK = 64 * 1024
CONTROL_CHARACTERS = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029]+")


@dataclass(frozen=True)
class Answer:
    status: int  # 2xx, or 4xx: the platform's refusal
    json: object  # the answer's JSON (None for a refusal that is not JSON)
    text: str  # the answer as text, as messages quote it (TEXT_SHOWN characters at most, no control characters)


class _EveryStatus(urllib.request.HTTPErrorProcessor):
    """Every answer as it came: no HTTPError, so no error handler, and no redirect followed."""

    def http_response(self, request, response):
        return response

    https_response = http_response


_OPENER = urllib.request.build_opener(_EveryStatus)


def shown(text: str) -> str:
    """``text`` as a message may quote it: on one line, at most TEXT_SHOWN characters."""
    return CONTROL_CHARACTERS.sub(" ", text[:TEXT_SHOWN]).strip()


def retry_after_s(value: str | None, now: datetime | None = None) -> float:
    """The wait a ``Retry-After`` header asks for, bounded; DEFAULT_WAIT_S when it says nothing usable."""
    text = (value or "").strip()
    if text.isascii() and text.isdigit():
        return min(float(text), LONGEST_WAIT_S) if len(text) <= 6 else LONGEST_WAIT_S  # 5000 digits: no int
    try:
        when = parsedate_to_datetime(text)
    except (TypeError, ValueError, IndexError, OverflowError):
        return DEFAULT_WAIT_S
    if when.tzinfo is None:  # an HTTP date is in GMT
        when = when.replace(tzinfo=timezone.utc)
    wait = (when - (now or datetime.now(timezone.utc))).total_seconds()
    return min(max(wait, 0.0), LONGEST_WAIT_S) if math.isfinite(wait) else DEFAULT_WAIT_S


def exchange(name: str, method: str, url: str, body: dict | None, headers: dict[str, str],
             deadline: float) -> Answer:
    """Send one request (``deadline``: by ``time.monotonic()``) and return its 2xx or 4xx answer."""
    if urlsplit(url).scheme not in ("http", "https"):
        raise PlatformError(f"{name}'s address {shown(url)!r} is not an http(s) address")
    data = json.dumps(body).encode() if body is not None else None
    request = urllib.request.Request(url, data=data, method=method, headers=headers)
    for attempt in range(RATE_LIMIT_RETRIES + 1):
        status, answer_headers, raw = _sent(name, request, deadline)
        if status == 429 and attempt < RATE_LIMIT_RETRIES:
            wait = retry_after_s(answer_headers.get("Retry-After"))
            if time.monotonic() + wait < deadline:
                time.sleep(wait)
                continue
        return _believed(name, status, answer_headers, raw)
    raise AssertionError("unreachable")


def _sent(name: str, request: urllib.request.Request, deadline: float) -> tuple[int, http.client.HTTPMessage, bytes]:
    remaining = deadline - time.monotonic()
    if remaining <= 0:
        raise UnconfirmedAnswer(f"{name} gave no answer in time: this request may wait no longer")
    timeout = min(TIMEOUT_S, remaining)
    try:
        response = _OPENER.open(request, timeout=timeout)
    except TimeoutError:  # sent, and no answer came in time
        raise UnconfirmedAnswer(f"{name} gave no answer in time ({timeout:.1f} s); it may have done it or "
                                f"not") from None
    except urllib.error.URLError as error:  # the request did not go out (urllib wraps what sending raised)
        origin = urlsplit(request.full_url)
        raise PlatformError(f"{name} could not be reached at {origin.scheme}://{shown(origin.netloc)}: "
                            f"{shown(str(error.reason))}") from None
    except (http.client.HTTPException, OSError) as error:  # it went out; the answer is missing or not HTTP
        raise UnconfirmedAnswer(f"{name} gave no answer that is HTTP ({type(error).__name__}: "
                                f"{shown(str(error))}); it may have done it or not") from None
    with response:
        try:
            return response.status, response.headers, _read(name, response, deadline)
        except TimeoutError:
            raise UnconfirmedAnswer(f"{name} gave no answer in time ({timeout:.1f} s); it may have done it or "
                                    f"not") from None
        except (http.client.HTTPException, OSError) as error:
            raise UnconfirmedAnswer(f"{name}'s answer was cut short ({type(error).__name__}); it may have done it "
                                    f"or not") from None


def _read(name: str, response: http.client.HTTPResponse, deadline: float) -> bytes:
    chunks, size = [], 0
    while chunk := response.read1(CHUNK):
        size += len(chunk)
        if size > MAX_ANSWER_BYTES:
            raise UnconfirmedAnswer(f"{name}'s answer is longer than {MAX_ANSWER_BYTES // 2 ** 20} MiB")
        if time.monotonic() > deadline:
            raise UnconfirmedAnswer(f"{name} gave no answer in time (it was still sending it)")
        chunks.append(chunk)
    declared = response.headers.get("Content-Length", "")
    if declared.isdigit() and int(declared) != size:
        raise UnconfirmedAnswer(f"{name}'s answer was cut short ({size} of {declared} bytes)")
    return b"".join(chunks)


def _believed(name: str, status: int, headers: http.client.HTTPMessage, raw: bytes) -> Answer:
    text = shown(raw.decode("utf-8", errors="replace"))
    if 400 <= status < 500:
        return Answer(status, _json(raw) if _is_json(headers) else None, text)
    if not 200 <= status < 300:
        where = f" to {shown(headers.get('Location', ''))!r}" if 300 <= status < 400 else ""
        raise UnconfirmedAnswer(f"{name} answered {status}{where}, which confirms nothing"
                                f"{f': {text}' if text else ''}", status)
    if not _is_json(headers):
        raise UnconfirmedAnswer(f"{name} answered {status} with {shown(headers.get_content_type())}, not JSON, "
                                f"which confirms nothing{f': {text}' if text else ''}", status)
    answer = _json(raw)
    if answer is None:
        raise UnconfirmedAnswer(f"{name} answered {status} with broken or cut JSON, which confirms nothing"
                                f"{f': {text}' if text else ''}", status)
    return Answer(status, answer, text)


def _is_json(headers: http.client.HTTPMessage) -> bool:
    kind = headers.get_content_type()
    return kind == "application/json" or kind.endswith("+json")


def _json(raw: bytes) -> object | None:
    """The JSON of ``raw``, or None if it is not JSON (or holds NaN or an infinity)."""
    try:
        return json.loads(raw, parse_constant=_no_constant, parse_float=finite_float)
    except (ValueError, RecursionError):
        return None


def _no_constant(name: str) -> None:
    raise ValueError(f"{name} is not JSON")


__all__ = ["Answer", "exchange", "retry_after_s", "shown"]
