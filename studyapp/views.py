"""Pages of the study app: the clip gallery and the health report."""

from django.conf import settings
from django.http import HttpRequest, HttpResponse, HttpResponseBase, JsonResponse
from django.shortcuts import render
from django.views.decorators.cache import never_cache
from django.views.decorators.http import require_safe

from studyapp.celery import app as celery_app
from studyapp.gallery import GalleryIndexError, index_path, load_gallery
from studyapp.health import HealthReport, collect_health
from studyapp.ranged_files import serve_with_ranges


def _health() -> HealthReport:
    return collect_health(celery_app, settings.HEALTH_TIMEOUT_S)


def _http_status(report: HealthReport) -> int:
    # Without its database the web process cannot serve anything, so load
    # balancers and compose should see it as down; a missing broker or worker
    # only degrades it (pages still render, background work waits).
    return 200 if report.database.ok else 503


@require_safe
def gallery(request: HttpRequest) -> HttpResponse:
    """The rendered natural clips, or how to build them, under the health summary."""
    report = _health()
    clips, index_error = None, None
    try:
        clips = load_gallery(settings.MEDIA_ROOT)
    except GalleryIndexError as exc:
        index_error = str(exc)
    context = {
        "health": report,
        "clips": clips,
        "index_error": index_error,
        "index_path": index_path(settings.MEDIA_ROOT),
    }
    return render(request, "studyapp/gallery.html", context)


@never_cache
@require_safe
def health_page(request: HttpRequest) -> HttpResponse:
    report = _health()
    return render(request, "studyapp/health.html", {"health": report}, status=_http_status(report))


@never_cache
@require_safe
def health_json(request: HttpRequest) -> JsonResponse:
    report = _health()
    return JsonResponse(report.as_dict(), status=_http_status(report))


def media_file(request: HttpRequest, path: str) -> HttpResponseBase:
    """A file under MEDIA_ROOT (rendered clips), seekable through range requests."""
    return serve_with_ranges(request, path, settings.MEDIA_ROOT)


def static_file(request: HttpRequest, path: str) -> HttpResponseBase:
    """A collected static file, for when no proxy or runserver serves them."""
    return serve_with_ranges(request, path, settings.STATIC_ROOT)
