"""Who reaches a study's pages: the researcher who owns it, after logging in.

``researcher_study`` guards a view of ``studies/<pk>/...``: it asks for a login, finds
the study of the URL's ``pk`` among the researcher's own and hands the view that study;
another researcher's study answers 404, as if it did not exist.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import wraps

from django.contrib.auth.decorators import login_required
from django.http import HttpRequest, HttpResponse
from django.shortcuts import get_object_or_404

from studyapp.models import Study

StudyView = Callable[..., HttpResponse]


def owned_study(request: HttpRequest, pk: int) -> Study:
    """The logged-in researcher's study ``pk``, or 404 (another's study as one that does not exist)."""
    return get_object_or_404(Study, pk=pk, owner=request.user)


def researcher_study(view: StudyView) -> Callable[..., HttpResponse]:
    """``view(request, study, ...)`` as a view of ``(request, pk, ...)``: behind the login,
    for the owner's study only (404 for another's)."""

    @login_required
    @wraps(view)
    def guarded(request: HttpRequest, pk: int, *args, **kwargs) -> HttpResponse:
        return view(request, owned_study(request, pk), *args, **kwargs)

    return guarded


__all__ = ["owned_study", "researcher_study"]
