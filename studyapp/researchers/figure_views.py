"""A system's display-figure page: how its rig's joints map to the study's figure, and the
researcher's corrections of that mapping (``setup.editing.correct_figure_mapping``)."""

from __future__ import annotations

from django.contrib import messages
from django.http import HttpRequest, HttpResponse
from django.shortcuts import get_object_or_404, redirect, render
from django.views.decorators.http import require_http_methods

from generation.render.display_figure import PARENT
from studyapp.models import Study, System
from studyapp.researchers.access import researcher_study
from studyapp.researchers.setup.editing import EditRefused, correct_figure_mapping
from studyapp.researchers.setup.removal import SystemsFixed
from studyapp.stimuli.figure import figure_table

FIELD_PREFIX = "point_"


@researcher_study
@require_http_methods(["GET", "HEAD", "POST"])
def system_figure(request: HttpRequest, study: Study, system: int) -> HttpResponse:
    """The mapping of ``system``'s joints to the figure's points (GET); a corrected table
    kept (POST, one ``point_<name>`` field a point, blank: as found)."""
    target = get_object_or_404(System, pk=system, study=study)
    status, refusal = 200, ""
    if request.method == "POST":
        table = {name.removeprefix(FIELD_PREFIX): value.strip() for name, value in request.POST.items()
                 if name.startswith(FIELD_PREFIX) and name.removeprefix(FIELD_PREFIX) in PARENT}
        try:
            deleted = correct_figure_mapping(target, table)
        except EditRefused as error:
            status, refusal = 400, str(error)
        except SystemsFixed as error:
            status, refusal = 409, str(error)
        else:
            messages.success(request, f"The mapping of {target.name} is kept; {deleted} clip(s) deleted, to be drawn "
                                      "again when the stimuli are generated.")
            return redirect("study-system-figure", pk=study.pk, system=target.pk)
    context = {"study": study, "target": target, "table": figure_table(target), "refusal": refusal,
               "prefix": FIELD_PREFIX, "figure": study.display_figure.get("lengths", {}),
               "locked": study.participants.exists()}
    return render(request, "studyapp/researcher/system_figure.html", context, status=status)
