"""Refuse a request carrying a NUL character in any text it sends, before a view sees it.

PostgreSQL cannot hold NUL in text, nor even compare text with it, while SQLite stores
it: a link whose PROLIFIC_PID held ``%00`` enrolled a participant on the embedded database
and was a server error on the deployed one, and so was such a study key, rating token or
session cookie. No browser sends NUL in earnest, so the request is checked once here, on
every database alike: an address whose parts hold NUL names nothing (404, as a missing
file is), and a NUL in a query parameter, a form field (name or value), a cookie or a
header is a 400 naming where it was, in the study's language on a participant page. Text
read from an uploaded file is checked by the page that stores it (``null_character_in``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

from django.http import Http404, HttpRequest, HttpResponse
from django.template.loader import render_to_string
from django.utils import translation
from django.utils.text import capfirst
from django.utils.translation import gettext as _
from django.utils.translation import gettext_lazy

from studyapp.participants.language import language_before_view

NUL = "\x00"


def _shown(name: str) -> str:
    """A name as the refusal shows it: its NUL visible, and not too long."""
    return name.replace(NUL, "\\0")[:60]


# Where a text was, by the kind of text (_texts), said in the refusal's language.
_WHERE = {"query": gettext_lazy("the query parameter %(name)s"), "form": gettext_lazy("the form field %(name)s"),
          "cookie": gettext_lazy("the cookie %(name)s"), "header": gettext_lazy("the header %(name)s")}


def _texts(request: HttpRequest) -> Iterator[tuple[str, str, str]]:
    """(kind, name, text) of every piece of text the request sends besides its address."""
    for kind, data in (("query", request.GET), ("form", request.POST)):
        for name, values in data.lists():
            yield kind, name, name
            for value in values:
                yield kind, name, value
    for name, value in request.COOKIES.items():  # a quoted cookie may spell NUL as \000
        yield "cookie", name, name + value
    for key, value in request.META.items():
        if key.startswith("HTTP_"):
            yield "header", key, value


def null_character_at(request: HttpRequest) -> str | None:
    """Where the request's first NUL character is (in the language active), or None."""
    found = next(((kind, name) for kind, name, text in _texts(request) if NUL in text), None)
    if found is None:
        return None
    kind, name = found
    if kind == "header":  # HTTP_USER_AGENT: User-Agent
        name = name.removeprefix("HTTP_").replace("_", "-").title()
    return _WHERE[kind] % {"name": _shown(name)}


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
        if not any(NUL in text for _kind, _name, text in _texts(request)):
            return None
        with translation.override(language_before_view(view, kwargs)):
            explanation = _("%(where)s holds a NUL character (\\0), which no text here may contain. Please check "
                            "the link or what was typed.") % {"where": capfirst(null_character_at(request))}
            return HttpResponse(render_to_string("400.html", {"explanation": explanation}), status=400)
