"""A study's files as downloads: a body the browser saves under a name, and the zips
(controls, clips, motion) that may not exist yet or may fail, said on the page they are asked from."""

from __future__ import annotations

from collections.abc import Callable
from typing import IO

from django.contrib import messages
from django.http import FileResponse, HttpRequest, HttpResponse
from django.shortcuts import redirect

from studyapp.models import Study


def download(body: bytes | str, content_type: str, filename: str) -> HttpResponse:
    """``body`` as a file the browser saves as ``filename``."""
    response = HttpResponse(body, content_type=content_type)
    response["Content-Disposition"] = f'attachment; filename="{filename}"'
    return response


def zip_download(request: HttpRequest, study: Study, filename: str, build: Callable[[], bytes | IO[bytes]],
                 back: str, refused: tuple[type[Exception], ...], not_yet: str = "") -> HttpResponse:
    """The zip ``build()`` makes (its bytes or an open file), saved as ``filename``; back on
    the study's page ``back`` with the message ``not_yet`` (nothing to put in it yet) or
    "No download: ..." naming what ``build`` refused (one of ``refused``)."""
    if not_yet:
        messages.error(request, not_yet)
        return redirect(back, pk=study.pk)
    try:
        archive = build()
    except refused as error:
        messages.error(request, f"No download: {error}")
        return redirect(back, pk=study.pk)
    if isinstance(archive, bytes):
        return download(archive, "application/zip", filename)
    return FileResponse(archive, as_attachment=True, filename=filename, content_type="application/zip")


__all__ = ["download", "zip_download"]
