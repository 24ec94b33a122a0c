"""Pages of the study app: the clip gallery, the health report and analysis reports."""

from django import forms
from django.conf import settings
from django.contrib.auth.decorators import login_required
from django.contrib.auth.views import redirect_to_login
from django.http import Http404, HttpRequest, HttpResponse, HttpResponseBase, JsonResponse
from django.shortcuts import redirect, render
from django.views.decorators.cache import never_cache
from django.views.decorators.http import require_safe

from studyapp.celery import app as celery_app
from studyapp.gallery import GALLERY_FOLDER, GalleryIndexError, index_path, load_gallery
from studyapp.health import HealthReport, collect_health
from studyapp.ranged_files import serve_with_ranges
from studyapp.reports import REPORTS_FOLDER, AnalysisInputError, create_report, report_owner, report_page


def _health() -> HealthReport:
    return collect_health(celery_app, settings.HEALTH_TIMEOUT_S)


def _http_status(report: HealthReport) -> int:
    # Without its database the web process cannot serve anything, so load
    # balancers and compose should see it as down; a missing broker or worker
    # only degrades it (pages still render, background work waits).
    return 200 if report.database.ok else 503


@login_required  # its natural clips could be recognised among a study's NAT stimuli
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
@login_required  # /health.json stays public for the container health checks
@require_safe
def health_page(request: HttpRequest) -> HttpResponse:
    report = _health()
    return render(request, "studyapp/health.html", {"health": report}, status=_http_status(report))


@never_cache
@require_safe
def health_json(request: HttpRequest) -> JsonResponse:
    """ok or not for anyone (load balancers, compose); the checks' details for researchers.

    The details name the broker's address and the workers' host names, which are
    nobody else's business.
    """
    report = _health()
    answer = report.as_dict() if request.user.is_authenticated else {"status": report.status}
    return JsonResponse(answer, status=_http_status(report))


def media_file(request: HttpRequest, path: str) -> HttpResponseBase:
    """A file under MEDIA_ROOT, seekable through range requests, to whoever may see it.

    Stimuli are for anyone with their random token (participants); the gallery is a
    researcher's (its natural clips could be recognised among a study's NAT stimuli);
    an analysis report holds a researcher's ratings and is for its owner alone.
    Anything else under MEDIA_ROOT is not served.
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
    return serve_with_ranges(request, path, settings.MEDIA_ROOT, reveal_mtime=folder != "stimuli")


def static_file(request: HttpRequest, path: str) -> HttpResponseBase:
    """A collected static file, for when no proxy or runserver serves them."""
    return serve_with_ranges(request, path, settings.STATIC_ROOT)


class RatingsUploadForm(forms.Form):
    ratings = forms.FileField(help_text="A ratings table as CSV (see docs/ratings-schema.md).")
    reference = forms.CharField(required=False, initial="NAT", max_length=100,
                                help_text="System that significance stars compare against (empty: none).")

    def clean_ratings(self):
        upload = self.cleaned_data["ratings"]
        if upload.size > settings.MAX_RATINGS_UPLOAD_BYTES:
            raise forms.ValidationError(
                f"the file is {upload.size / 1e6:.1f} MB; the limit is {settings.MAX_RATINGS_UPLOAD_BYTES / 1e6:.0f} MB")
        return upload


@login_required
def analysis_upload(request: HttpRequest) -> HttpResponse:
    """Researchers: upload a ratings table, get the papers' tables and figures."""
    form = RatingsUploadForm(request.POST or None, request.FILES or None)
    status = 200
    if request.method == "POST":
        if form.is_valid():
            try:
                digest = create_report(settings.MEDIA_ROOT, form.cleaned_data["ratings"].read(),
                                       form.cleaned_data["reference"].strip() or None, request.user.pk)
                return redirect("analysis-report", digest=digest)
            except AnalysisInputError as exc:
                form.add_error("ratings", str(exc))
        status = 400
    return render(request, "studyapp/analysis_upload.html", {"form": form}, status=status)


@login_required
@require_safe
def analysis_report(request: HttpRequest, digest: str) -> HttpResponse:
    try:
        page = report_page(settings.MEDIA_ROOT, digest, request.user.pk)
    except FileNotFoundError:
        raise Http404("no such report") from None
    return render(request, "studyapp/analysis_report.html", {"page": page})
