"""The researcher's pages outside any one study: the gallery of natural clips and the
analysis of an uploaded ratings table."""

from django import forms
from django.conf import settings
from django.contrib.auth.decorators import login_required
from django.http import Http404, HttpRequest, HttpResponse
from django.shortcuts import redirect, render
from django.views.decorators.http import require_safe

from studyapp.models import Study
from studyapp.researchers.results.report_files import report_zip
from studyapp.researchers.results.reports import AnalysisInputError, create_report, report_page
from studyapp.server.views import current_health
from studyapp.stimuli.gallery import GalleryIndexError, index_path, load_gallery


@login_required  # its natural clips could be recognised among a study's NAT stimuli
@require_safe
def gallery(request: HttpRequest) -> HttpResponse:
    """The rendered natural clips, or how to build them, under the health summary."""
    report = current_health()
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
    # Each file by its place in the report (tables/..., figures/...); the tables' CSVs are the short list.
    files = [(path, path.split("/", 2)[2]) for path in page.files]
    csv_files = [(path, name) for path, name in files if name.endswith(".csv")]
    # A study's report leads back to the study (while it is there and the researcher's).
    study = Study.objects.filter(pk=page.study_id, owner=request.user).first() if page.study_id else None
    return render(request, "studyapp/analysis_report.html",
                  {"page": page, "files": files, "csv_files": csv_files, "study": study})


@login_required
@require_safe
def analysis_report_zip(request: HttpRequest, digest: str) -> HttpResponse:
    """Every file of a report in one zip."""
    try:
        data = report_zip(settings.MEDIA_ROOT, digest, request.user.pk)
    except FileNotFoundError:
        raise Http404("no such report") from None
    response = HttpResponse(data, content_type="application/zip")
    response["Content-Disposition"] = f'attachment; filename="report-{digest[:12]}.zip"'
    return response
