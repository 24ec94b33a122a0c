"""A study as a file on the researcher's pages: its definition to download, and a new
study made from an uploaded one (``studyapp.definitions``).

Both are behind login; the download answers only the study's owner (404 to anyone
else, as every researcher page). A refused definition lists its problems at the top of
the page, one a line with the line of the file it is on, and answers 400.
"""

from __future__ import annotations

from pathlib import Path

from django import forms
from django.contrib import messages
from django.contrib.auth.decorators import login_required
from django.http import HttpRequest, HttpResponse
from django.shortcuts import redirect, render
from django.views.decorators.cache import never_cache
from django.views.decorators.http import require_http_methods, require_safe

from studyapp.definitions import (
    DefinitionError,
    create_study_from_definition,
    definition_yaml,
)
from studyapp.definitions.reading import MAX_DEFINITION_BYTES
from studyapp.models import StoredDataError, Study
from studyapp.researchers.access import researcher_study
from studyapp.researchers.downloads import download


class DefinitionUploadForm(forms.Form):
    definition = forms.FileField(
        label="Study definition", widget=forms.ClearableFileInput(attrs={"accept": ".yaml,.yml,text/yaml"}),
        help_text=f"a YAML file as “Download definition” writes it, at most {MAX_DEFINITION_BYTES / 1e6:g} MB; its "
                  "checkpoints and submitted motion must be yours (uploaded on one of your studies) or shared on "
                  "this server")

    def clean_definition(self):
        upload = self.cleaned_data["definition"]
        if upload.size > MAX_DEFINITION_BYTES:
            raise forms.ValidationError(f"the file is {upload.size / 1e6:.1f} MB; the limit is "
                                        f"{MAX_DEFINITION_BYTES / 1e6:g} MB")
        return upload


@login_required
@require_http_methods(["GET", "HEAD", "POST"])
def study_from_definition(request: HttpRequest) -> HttpResponse:
    """Upload a definition (GET: the form); a new, closed study of it, then its settings page."""
    form = DefinitionUploadForm(request.POST or None, request.FILES or None)
    refused = None
    if request.method == "POST" and form.is_valid():
        upload = form.cleaned_data["definition"]
        name = Path(upload.name or "definition").name
        try:
            study = create_study_from_definition(b"".join(upload.chunks()), request.user, source=name)
        except DefinitionError as error:
            refused = {"title": f"{name} did not become a study; nothing was kept:", "problems": error.lines()}
        else:
            messages.success(request, f"Made “{study.title}” from {name}, closed: generate its stimuli, then open it.")
            return redirect("study-edit", pk=study.pk)
    return render(request, "studyapp/researcher/study_from_definition.html", {"form": form, "refused": refused},
                  status=400 if request.method == "POST" else 200)


@never_cache
@researcher_study
@require_safe
def study_definition(request: HttpRequest, study: Study) -> HttpResponse:
    """The study's definition as a YAML download."""
    try:
        text = definition_yaml(study)
    except StoredDataError as error:
        messages.error(request, f"No definition: {error} (fix it in the admin: {error.admin_url})")
        return redirect("study-monitor", pk=study.pk)
    return download(text, "application/yaml; charset=utf-8", f"study-{study.pk}.yaml")
