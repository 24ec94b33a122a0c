"""What a study's ratings say, as pages and files: the monitor, the ratings table and
its rules, every system's motion, the control adherence, the locked plan and the report."""

from __future__ import annotations

from functools import partial

from django.contrib import messages
from django.http import HttpRequest, HttpResponse
from django.shortcuts import redirect, render
from django.urls import reverse
from django.views.decorators.cache import never_cache
from django.views.decorators.http import require_http_methods, require_safe

from studyapp.designs.rules import StudyRules
from studyapp.models import Study
from studyapp.preregistration.lock import preregistration
from studyapp.preregistration.words import in_words
from studyapp.platforms.links import PLATFORM_PARAMETERS, entry_link
from studyapp.researchers.access import researcher_study
from studyapp.researchers.downloads import download, zip_download
from studyapp.researchers.results.adherence import adherence_tables
from studyapp.researchers.results.export import ratings_csv, rules_json
from studyapp.researchers.results.monitor import study_monitor
from studyapp.researchers.results.monitor_figures import live_figures
from studyapp.researchers.results.reports import AnalysisInputError, create_study_report, html_table
from studyapp.researchers.setup.readiness import open_problems, open_warnings
from studyapp.stimuli.motion_export import exported_stimuli, motion_zip


@never_cache
@researcher_study
@require_safe
def study_monitor_page(request: HttpRequest, study: Study) -> HttpResponse:
    context = {"study": study, "entry_link": entry_link(request, study),
               "parameters": PLATFORM_PARAMETERS[study.platform], "open_problems": open_problems(study),
               "open_warnings": open_warnings(study), "figures": live_figures(study),
               "rules": StudyRules.of(study).described()}
    plan = preregistration(study)
    context.update(plan_locked=plan["locked"], deviation_count=len(plan["deviations"]))
    try:
        context["monitor"] = study_monitor(study)
    except AnalysisInputError as error:  # rows changed outside the study pages (a rating without its value)
        context["unreadable"] = str(error)
    return render(request, "studyapp/researcher/monitor.html", context)


@never_cache
@researcher_study
@require_safe
def study_export(request: HttpRequest, study: Study) -> HttpResponse:
    """The ratings table as a CSV download."""
    return download(ratings_csv(study, for_spreadsheets=True), "text/csv", f"ratings-study-{study.pk}.csv")


@never_cache
@researcher_study
@require_safe
def study_rules(request: HttpRequest, study: Study) -> HttpResponse:
    """The exclusion rules of the ratings table, for ``python -m analysis report --rules``."""
    return download(rules_json(study), "application/json", f"rules-study-{study.pk}.json")


@never_cache
@researcher_study
@require_safe
def study_motion_download(request: HttpRequest, study: Study) -> HttpResponse:
    """Every system's motion of the finished clips as a zip, for the objective metrics (``motion_export``)."""
    return zip_download(request, study, f"motion-study-{study.pk}.zip", partial(motion_zip, study),
                        "study-monitor", (ValueError,),
                        not_yet="" if exported_stimuli(study) else "No motion to download yet: generate the stimuli first.")


@never_cache
@researcher_study
@require_safe
def study_adherence(request: HttpRequest, study: Study) -> HttpResponse:
    """How closely the study's motion follows its controls, and (appropriateness) its correlation with the scores."""
    try:
        tables, notes = adherence_tables(study)
    except ValueError as error:
        messages.error(request, f"No control adherence: {error}")
        return redirect("study-monitor", pk=study.pk)
    return render(request, "studyapp/researcher/adherence.html",
                  {"study": study, "tables": [(title, html_table(table)) for title, table in tables], "notes": notes})


@never_cache
@researcher_study
@require_safe
def study_plan(request: HttpRequest, study: Study) -> HttpResponse:
    """The plan locked when the study first opened, in words, and every deviation from it since."""
    return render(request, "studyapp/researcher/plan.html", {"study": study, "plan": in_words(preregistration(study))})


@researcher_study
@require_http_methods(["GET", "HEAD", "POST"])
def study_report(request: HttpRequest, study: Study) -> HttpResponse:
    """The analysis report of the ratings so far (the analysis pages' report), made by a POST;
    a GET (a bookmark, a link) leads to the monitor's button that makes it."""
    if request.method != "POST":
        messages.info(request, "The analysis report is made from the ratings so far: press “Analysis report”.")
        return redirect(reverse("study-monitor", args=[study.pk]) + "#data")
    try:
        digest = create_study_report(study, request.user.pk)
    except AnalysisInputError as error:
        messages.error(request, f"No report yet: {error}")
        return redirect("study-monitor", pk=study.pk)
    return redirect("analysis-report", digest=digest)


__all__ = ["study_adherence", "study_export", "study_monitor_page", "study_motion_download", "study_plan", "study_report", "study_rules"]
