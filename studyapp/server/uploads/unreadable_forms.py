"""A posted body that Django cannot read as a form is a 400, before any view sees it.

Django parses a form's body the first time something reads ``request.POST`` (the CSRF
check, then the view) and raises MultiPartParserError on a multipart body it cannot
read: a part whose headers pass its size limit (a field name of thousands of
characters), a boundary that never ends. That error is no client error to Django, so
it would answer 500. Reading the form here, after the upload limit and before
anything else, answers such a body with the plain 400 page instead.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

from django.http import HttpRequest, HttpResponse
from django.http.multipartparser import MultiPartParserError
from django.views.defaults import bad_request

logger = logging.getLogger(__name__)


class UnreadableFormMiddleware:
    def __init__(self, get_response: Callable[[HttpRequest], HttpResponse]) -> None:
        self.get_response = get_response

    def __call__(self, request: HttpRequest) -> HttpResponse:
        if request.method == "POST":
            try:
                request.POST  # noqa: B018 (parsed here, once; the views read the same parse)
            except MultiPartParserError as error:
                logger.warning("%s: unreadable form body (%s)", request.path, error)
                return bad_request(request, error)
        return self.get_response(request)
