"""The server's own pages: its health (a page for researchers, JSON for load balancers)
and the media and static files it serves when no proxy does."""

from django.conf import settings
from django.contrib.auth.decorators import login_required
from django.contrib.auth.views import redirect_to_login
from django.http import Http404, HttpRequest, HttpResponse, HttpResponseBase, JsonResponse
from django.shortcuts import redirect, render
from django.templatetags.static import static
from django.views.decorators.cache import never_cache
from django.views.decorators.http import require_safe

from studyapp.researchers.results.reports import REPORTS_FOLDER, report_owner
from studyapp.server.celery import app as celery_app
from studyapp.server.clip_urls import is_signed_and_current, seconds_left
from studyapp.server.file_responses import ACCEL_MEDIA_PREFIX, accel_redirect, serve_with_ranges
from studyapp.server.health import HealthReport, collect_health
from studyapp.server.media_bucket import clip_redirect, in_bucket
from studyapp.stimuli.gallery import GALLERY_FOLDER

RESEARCHER_FILES_MAX_AGE_S = 3600  # the gallery and reports behind the proxy: an hour in the browser


def current_health() -> HealthReport:
    return collect_health(celery_app, settings.HEALTH_TIMEOUT_S)


def _http_status(report: HealthReport) -> int:
    # Without its database the web process cannot serve anything, so load
    # balancers and compose should see it as down; a missing broker or worker
    # only degrades it (pages still render, background work waits).
    return 200 if report.database.ok else 503


@require_safe
def favicon(request: HttpRequest) -> HttpResponse:
    """The site's icon for a browser that asks at /favicon.ico (every page links it too)."""
    return redirect(static("studyapp/favicon.svg"), permanent=True)


@never_cache
@login_required  # /health.json stays public for the container health checks
@require_safe
def health_page(request: HttpRequest) -> HttpResponse:
    report = current_health()
    return render(request, "studyapp/health.html", {"health": report}, status=_http_status(report))


@never_cache
@require_safe
def health_json(request: HttpRequest) -> JsonResponse:
    """ok or not for anyone (load balancers, compose); the checks' details for researchers.

    The details name the broker's address and the workers' host names, which are
    nobody else's business.
    """
    report = current_health()
    answer = report.as_dict() if request.user.is_authenticated else {"status": report.status}
    return JsonResponse(answer, status=_http_status(report))


def media_file(request: HttpRequest, path: str) -> HttpResponseBase:
    """A file under MEDIA_ROOT, seekable through range requests, to whoever may see it.

    Stimuli are for anyone with their random token (participants); the gallery is a
    researcher's (its natural clips could be recognised among a study's NAT stimuli);
    an analysis report holds a researcher's ratings and is for its owner alone.
    Anything else under MEDIA_ROOT is not served. With MEDIA_ACCEL the proxy in front sends
    the file once this view has allowed it; with MEDIA_BUCKET_URL a stimulus is answered with
    a redirect to the bucket's expiring address of it.
    """
    folder, _, rest = path.partition("/")
    if folder in (GALLERY_FOLDER, REPORTS_FOLDER) and not request.user.is_authenticated:
        return redirect_to_login(request.get_full_path())
    if folder == REPORTS_FOLDER:
        owner = report_owner(settings.MEDIA_ROOT, rest.partition("/")[0])
        if owner is None or owner != request.user.pk:
            raise Http404("No such file")
    elif folder not in ("stimuli", GALLERY_FOLDER):
        raise Http404("No such file")
    # Behind the proxy a clip's address is signed and expires (``clip_urls``).
    if settings.MEDIA_ACCEL and folder == "stimuli" and not is_signed_and_current(path, request.GET):
        raise Http404("No such file")
    if folder == "stimuli" and in_bucket():
        return clip_redirect(request, rest)  # the bucket sends the bytes
    if settings.MEDIA_ACCEL:  # the proxy sends the bytes, a clip's kept while its address works
        max_age = seconds_left(request.GET) if folder == "stimuli" else RESEARCHER_FILES_MAX_AGE_S
        return accel_redirect(request, path, settings.MEDIA_ROOT, ACCEL_MEDIA_PREFIX, max_age)
    return serve_with_ranges(request, path, settings.MEDIA_ROOT, reveal_mtime=folder != "stimuli")


def static_file(request: HttpRequest, path: str) -> HttpResponseBase:
    """A collected static file, for when no proxy or runserver serves them."""
    return serve_with_ranges(request, path, settings.STATIC_ROOT)
