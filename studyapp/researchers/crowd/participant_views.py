"""The participant list: who took part, how far they got and what the study's rules
suggest doing with each submission, as a page and as a CSV."""

from __future__ import annotations

from django.http import HttpRequest, HttpResponse
from django.shortcuts import render
from django.views.decorators.cache import never_cache
from django.views.decorators.http import require_safe

from studyapp.models import Study
from studyapp.researchers.access import researcher_study
from studyapp.researchers.crowd.completion_time import completion_minutes
from studyapp.researchers.crowd.participant_list import participant_rows, participants_csv, question_names
from studyapp.researchers.downloads import download


@never_cache
@researcher_study
@require_safe
def study_participants(request: HttpRequest, study: Study) -> HttpResponse:
    """Who took part, how far they got and what the study's rules suggest doing with their submission."""
    names = question_names(study)
    rows = [(row, [row.answers.get(name, "") for name in names]) for row in participant_rows(study)]
    context = {"study": study, "rows": rows, "questions": names, "completion": completion_minutes(study)}
    return render(request, "studyapp/researcher/participants.html", context)


@never_cache
@researcher_study
@require_safe
def study_participants_csv(request: HttpRequest, study: Study) -> HttpResponse:
    return download(participants_csv(study), "text/csv", f"participants-study-{study.pk}.csv")


__all__ = ["study_participants", "study_participants_csv"]
