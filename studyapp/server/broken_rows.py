"""A page for a stored row the study's code cannot read, instead of a server error.

Rows written in the admin, by an older version or by hand may hold data the code cannot
read; the readers raise ``StoredDataError`` naming the row and the field. A researcher's
page that meets one answers 409 (the study's data conflicts with the page) saying which
row and what is wrong, with the row's page in the admin, where it can be fixed or
removed. Participants' pages answer with a plain page of their own (``participants.views``).
"""

from __future__ import annotations

import logging
from collections.abc import Callable

from django.http import HttpRequest, HttpResponse
from django.shortcuts import render

from studyapp.models import StoredDataError

logger = logging.getLogger(__name__)


class BrokenRowMiddleware:
    def __init__(self, get_response: Callable[[HttpRequest], HttpResponse]) -> None:
        self.get_response = get_response

    def __call__(self, request: HttpRequest) -> HttpResponse:
        return self.get_response(request)

    def process_exception(self, request: HttpRequest, exception: Exception) -> HttpResponse | None:
        if not isinstance(exception, StoredDataError):
            return None
        logger.warning("%s: %s", request.path, exception)
        return render(request, "studyapp/broken_row.html", {"error": exception}, status=409)
