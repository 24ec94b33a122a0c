"""Refuse a request body over the upload limit before reading any of it.

Django would stream a large upload to a temporary file and only then let a form see
its size, so a 600 MB file cost 600 MB of disk and the time to receive it before the
refusal. The declared length (``Content-Length``) is checked first instead; Django
never reads past it, so a body cannot be longer than it claims. On a participant page the
refusal is in the study's language.
"""

from __future__ import annotations

from collections.abc import Callable

from django.conf import settings
from django.http import HttpRequest, HttpResponse
from django.template.loader import render_to_string
from django.urls import Resolver404, ResolverMatch, resolve
from django.utils import translation
from django.utils.formats import number_format
from django.utils.translation import gettext as _

from studyapp.definitions.reading import MAX_DEFINITION_BYTES
from studyapp.participants.language import language_before_view

# Room for a form's other fields and the multipart boundaries around its file.
FORM_MARGIN_BYTES = 1_000_000


def _page(path: str) -> ResolverMatch | None:
    try:
        return resolve(path)
    except Resolver404:
        return None


def request_limit(path: str) -> int:
    """The most bytes a request to ``path`` may carry: the systems page takes checkpoints
    and videos, the import page a study bundle, the definition page a definition, every
    other page at most a ratings table or a control file."""
    return _limit(_page(path))


def _limit(page: ResolverMatch | None) -> int:
    name = page.url_name if page else None
    if name == "study-systems":
        return max(settings.MAX_CHECKPOINT_UPLOAD_BYTES, settings.MAX_VIDEO_UPLOAD_BYTES) + FORM_MARGIN_BYTES
    if name == "study-import":
        return settings.MAX_BUNDLE_UPLOAD_BYTES + FORM_MARGIN_BYTES
    if name == "study-from-definition":
        return MAX_DEFINITION_BYTES + FORM_MARGIN_BYTES
    return settings.DATA_UPLOAD_MAX_MEMORY_SIZE + FORM_MARGIN_BYTES


def _megabytes(size: int, decimals: int) -> str:
    """``size`` bytes in MB, written as the active language writes numbers."""
    return number_format(size / 1e6, decimal_pos=decimals, force_grouping=True)


class UploadLimitMiddleware:
    """Answers 413 to a request whose declared body exceeds its page's `request_limit`."""

    def __init__(self, get_response: Callable[[HttpRequest], HttpResponse]) -> None:
        self.get_response = get_response

    def __call__(self, request: HttpRequest) -> HttpResponse:
        declared = request.META.get("CONTENT_LENGTH") or "0"
        # A length that is no number, or one thousands of digits long, is no upload either.
        size = int(declared) if declared.isdigit() and len(declared) <= 18 else None
        page = _page(request.path_info)
        limit = _limit(page)
        if size is not None and size <= limit:
            return self.get_response(request)
        with translation.override(language_before_view(page.func, page.kwargs) if page else settings.LANGUAGE_CODE):
            what = (_("%(size)s MB") % {"size": _megabytes(size, 1)} if size is not None
                    else _("of unreadable length %(length)s") % {"length": repr(declared[:20])})
            explanation = _("The upload is %(what)s; this page takes at most %(limit)s MB in one request. Upload "
                            "fewer or smaller files at a time.") % {"what": what, "limit": _megabytes(limit, 0)}
            return HttpResponse(render_to_string("413.html", {"explanation": explanation}), status=413)
