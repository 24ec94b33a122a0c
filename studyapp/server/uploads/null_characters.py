"""Refuse a request carrying a NUL character in any text it sends, before a view sees it.

PostgreSQL cannot hold NUL in text, nor even compare text with it, while SQLite stores
it: a link whose PROLIFIC_PID held ``%00`` enrolled a participant on the embedded database
and was a server error on the deployed one, and so was such a study key, rating token or
session cookie. No browser sends NUL in earnest, so the request is checked once here, on
every database alike: an address whose parts hold NUL names nothing (404, as a missing
file is), and a NUL in a query parameter, a form field (name or value), a cookie or a
header is a 400 naming where it was. Text read from an uploaded file is checked by the
page that stores it (``null_character_in``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

from django.http import Http404, HttpRequest, HttpResponse
from django.template.loader import render_to_string

NUL = "\x00"


def _shown(name: str) -> str:
    """A name as the refusal shows it: its NUL visible, and not too long."""
    return name.replace(NUL, "\\0")[:60]


def _texts(request: HttpRequest) -> Iterator[tuple[str, str]]:
    """(where, text) of every piece of text the request sends besides its address."""
    for what, data in (("query parameter", request.GET), ("form field", request.POST)):
        for name, values in data.lists():
            yield f"the {what} {_shown(name)}", name
            for value in values:
                yield f"the {what} {_shown(name)}", value
    for name, value in request.COOKIES.items():  # a quoted cookie may spell NUL as \000
        yield f"the cookie {_shown(name)}", name + value
    for key, value in request.META.items():
        if key.startswith("HTTP_"):
            yield f"the header {key.removeprefix('HTTP_').replace('_', '-').title()}", value


def null_character_at(request: HttpRequest) -> str | None:
    """Where the request's first NUL character is, or None."""
    return next((where for where, text in _texts(request) if NUL in text), None)


def null_character_in(value: Any, where: str = "") -> str | None:
    """Where a NUL character is in JSON-like data (text, and dicts and lists of it, keys
    included), as a dotted path such as ``features.labels.2``; None if nowhere."""
    if isinstance(value, str):
        return (where or "the text") if NUL in value else None
    if isinstance(value, dict):
        entries = value.items()
    elif isinstance(value, (list, tuple)):
        entries = enumerate(value)
    else:
        return None
    for key, item in entries:
        at = f"{where}.{_shown(str(key))}" if where else _shown(str(key))
        if NUL in str(key):
            return at
        found = null_character_in(item, at)
        if found is not None:
            return found
    return None


class RefuseNullCharactersMiddleware:
    """Answers 404 to an address with a NUL character in its parts, and 400 to a request
    with one in its other text (``null_character_at``).

    It looks once the view is known (``process_view``), after the CSRF check, so that a
    forged form is refused as forged whatever it holds.
    """

    def __init__(self, get_response: Callable[[HttpRequest], HttpResponse]) -> None:
        self.get_response = get_response

    def __call__(self, request: HttpRequest) -> HttpResponse:
        return self.get_response(request)

    def process_view(self, request: HttpRequest, view, args, kwargs) -> HttpResponse | None:
        if any(NUL in str(part) for part in (*args, *kwargs.values())):
            raise Http404("an address with a NUL character")
        where = null_character_at(request)
        if where is None:
            return None
        explanation = (f"{where[0].upper()}{where[1:]} holds a NUL character (\\0), which no text here may "
                       "contain. Please check the link or what was typed.")
        return HttpResponse(render_to_string("400.html", {"explanation": explanation}), status=400)
