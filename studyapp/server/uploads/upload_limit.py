"""Refuse a request body over the upload limit before reading any of it.

Django would stream a large upload to a temporary file and only then let a form see
its size, so a 600 MB file cost 600 MB of disk and the time to receive it before the
refusal. The declared length (``Content-Length``) is checked first instead; Django
never reads past it, so a body cannot be longer than it claims.
"""

from __future__ import annotations

from collections.abc import Callable

from django.conf import settings
from django.http import HttpRequest, HttpResponse
from django.template.loader import render_to_string
from django.urls import Resolver404, resolve

from studyapp.definitions.reading import MAX_DEFINITION_BYTES

# Room for a form's other fields and the multipart boundaries around its file.
FORM_MARGIN_BYTES = 1_000_000


def request_limit(path: str) -> int:
    """The most bytes a request to ``path`` may carry: the systems page takes checkpoints
    and videos, the import page a study bundle, the definition page a definition, every
    other page at most a ratings table or a control file."""
    try:
        name = resolve(path).url_name
    except Resolver404:
        name = None
    if name == "study-systems":
        return max(settings.MAX_CHECKPOINT_UPLOAD_BYTES, settings.MAX_VIDEO_UPLOAD_BYTES) + FORM_MARGIN_BYTES
    if name == "study-import":
        return settings.MAX_BUNDLE_UPLOAD_BYTES + FORM_MARGIN_BYTES
    if name == "study-from-definition":
        return MAX_DEFINITION_BYTES + FORM_MARGIN_BYTES
    return settings.DATA_UPLOAD_MAX_MEMORY_SIZE + FORM_MARGIN_BYTES


class UploadLimitMiddleware:
    """Answers 413 to a request whose declared body exceeds its page's `request_limit`."""

    def __init__(self, get_response: Callable[[HttpRequest], HttpResponse]) -> None:
        self.get_response = get_response

    def __call__(self, request: HttpRequest) -> HttpResponse:
        declared = request.META.get("CONTENT_LENGTH") or "0"
        # A length that is no number, or one thousands of digits long, is no upload either.
        size = int(declared) if declared.isdigit() and len(declared) <= 18 else None
        limit = request_limit(request.path_info)
        if size is None or size > limit:
            what = f"{size / 1e6:,.1f} MB" if size is not None else f"of unreadable length {declared[:20]!r}"
            explanation = (f"The upload is {what}; this page takes at most {limit / 1e6:,.0f} MB in one request. "
                           "Upload fewer or smaller files at a time.")
            page = render_to_string("413.html", {"explanation": explanation})
            return HttpResponse(page, status=413)
        return self.get_response(request)
