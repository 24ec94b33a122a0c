"""The study bundle on the researcher's pages: downloaded from a study's settings page,
imported through an upload page (``studyapp.bundles``; the same as ``export_study`` and
``import_study``). Both need a login; the download only of the owner's own study.

A bundle downloaded here hashes platform ids with a key drawn for this download and
written nowhere; a key of the researcher's own is for ``export_study --pseudonym-key-file``.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from django.contrib import messages
from django.contrib.auth.decorators import login_required
from django.http import FileResponse, HttpRequest, HttpResponse
from django.shortcuts import redirect, render
from django.views.decorators.cache import never_cache
from django.views.decorators.http import require_http_methods, require_safe

from studyapp.bundles.importing import import_study
from studyapp.bundles.manifest import BundleRefused
from studyapp.bundles.pseudonyms import export_key
from studyapp.bundles.writing import ExportError, write_study_bundle
from studyapp.models import StoredDataError, Study
from studyapp.researchers.access import researcher_study
from studyapp.researchers.setup.forms import BundleImportForm


@never_cache
@researcher_study
@require_safe
def study_bundle_download(request: HttpRequest, study: Study) -> HttpResponse:
    """The study as one bundle (``?videos=1``: with every finished clip's video)."""
    with tempfile.TemporaryDirectory(prefix="study-bundle-") as folder:
        path = Path(folder) / "study.zip"
        try:
            write_study_bundle(study, path, export_key(None), with_videos=request.GET.get("videos") == "1")
        except (ExportError, StoredDataError, ValueError) as error:
            messages.error(request, f"No bundle: {error}")
            return redirect("study-edit", pk=study.pk)
        archive = path.open("rb")  # the open file outlives its folder, until the response closes it
    return FileResponse(archive, as_attachment=True, filename=f"study-{study.pk}.zip", content_type="application/zip")


@login_required
@require_http_methods(["GET", "POST"])
def study_import(request: HttpRequest) -> HttpResponse:
    """Upload a bundle: a new study of the researcher's, or the refusal with 400."""
    form = BundleImportForm(request.POST or None, request.FILES or None)
    refused = None
    if request.method == "POST" and form.is_valid():
        try:
            study = import_study(form.cleaned_data["bundle"], request.user, rerun=form.cleaned_data["rerun"])
        except BundleRefused as error:
            refused = str(error)
        else:
            pending = study.stimuli.exclude(status="done").count()
            messages.success(request, f"Imported {study.title} (closed)."
                                      + (f" {pending} clip(s) to render on the stimuli page." if pending else ""))
            return redirect("study-edit", pk=study.pk)
    status = 400 if request.method == "POST" else 200
    return render(request, "studyapp/researcher/study_import.html", {"form": form, "refused": refused}, status=status)
