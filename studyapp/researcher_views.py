"""The researcher's pages: studies, their systems, controls, stimuli and the running study.

Every page needs a login, and a researcher reaches only their own studies: another
researcher's study answers 404, as if it did not exist. Forms post back to their page;
what a form means is done by the service modules (``systems``, ``controls``,
``stimuli``, ``monitor``), which the management commands share.
"""

from __future__ import annotations

from django.conf import settings
from django.contrib import messages
from django.contrib.auth.decorators import login_required
from django.http import HttpRequest, HttpResponse, JsonResponse
from django.shortcuts import get_object_or_404, redirect, render
from django.urls import reverse
from django.views.decorators.cache import never_cache
from django.views.decorators.http import require_POST, require_safe

from studyapp.controls import ControlError, add_control_file, add_held_out_controls, add_preset_controls
from studyapp.forms import (CheckpointSystemForm, ControlFileForm, GenerateForm, HeldOutControlsForm,
                            NaturalSystemForm, PresetControlsForm, StudyForm, VideoSystemForm)
from studyapp.models import NATURAL_NAME, Stimulus, Study, System
from studyapp.monitor import ratings_csv, study_monitor
from studyapp.participant_views import PLATFORM_PARAMETERS
from studyapp.reports import AnalysisInputError, create_report
from studyapp.stimuli import BrokerUnavailable, generate_stimuli, progress, retry_stimulus
from studyapp.systems import UploadRefused, add_checkpoint_system, add_natural_system, add_video_system

# Prolific fills these placeholders in a study URL; MTurk appends its own ids.
PROLIFIC_PLACEHOLDERS = "PROLIFIC_PID={{%PROLIFIC_PID%}}&STUDY_ID={{%STUDY_ID%}}&SESSION_ID={{%SESSION_ID%}}"


def _study(request: HttpRequest, pk: int) -> Study:
    return get_object_or_404(Study, pk=pk, owner=request.user)


@login_required
@require_safe
def study_list(request: HttpRequest) -> HttpResponse:
    studies = Study.objects.filter(owner=request.user)
    return render(request, "studyapp/researcher/study_list.html", {"studies": studies})


@login_required
def study_edit(request: HttpRequest, pk: int | None = None) -> HttpResponse:
    """Create a study (no ``pk``) or edit one."""
    study = _study(request, pk) if pk is not None else Study(owner=request.user)
    form = StudyForm(request.POST or None, instance=study)
    if request.method == "POST":
        if form.is_valid():
            study = form.save()
            messages.success(request, f"Saved {study.title}.")
            return redirect("study-systems", pk=study.pk)
        return render(request, "studyapp/researcher/study_form.html", {"form": form, "study": study}, status=400)
    return render(request, "studyapp/researcher/study_form.html", {"form": form, "study": study})


def _bound(form_class, request: HttpRequest, action: str):
    """The form bound to this POST if it is the one submitted, else an empty one."""
    if request.method == "POST" and request.POST.get("action") == action:
        return form_class(request.POST, request.FILES)
    return form_class()


def _run(form, request: HttpRequest, action, errors: tuple[type[Exception], ...]) -> bool:
    """Validate a submitted form and run its action; a refused action becomes a form error."""
    if not form.is_bound or not form.is_valid():
        return False
    try:
        message = action(form.cleaned_data)
    except errors as error:
        form.add_error(None, str(error))
        return False
    messages.success(request, message)
    return True


@login_required
def study_systems(request: HttpRequest, pk: int) -> HttpResponse:
    study = _study(request, pk)
    forms = {
        "checkpoint": _bound(CheckpointSystemForm, request, "checkpoint"),
        "natural": _bound(NaturalSystemForm, request, "natural"),
        "videos": _bound(VideoSystemForm, request, "videos"),
    }
    actions = {
        "checkpoint": lambda data: "Registered {}.".format(add_checkpoint_system(
            study, data["name"], data["checkpoint"], data["role"], data["temperature"]).name),
        "natural": lambda data: f"Registered {add_natural_system(study, data['name']).name}.",
        "videos": lambda data: "Registered {} with {} video(s).".format(
            add_video_system(study, data["name"], data["videos"]).name, len(data["videos"])),
    }
    if request.method == "POST":
        action = request.POST.get("action")
        if action in forms and _run(forms[action], request, actions[action], (UploadRefused,)):
            return redirect("study-systems", pk=study.pk)
    status = 400 if any(f.is_bound for f in forms.values()) else 200
    return render(request, "studyapp/researcher/systems.html",
                  {"study": study, "systems": study.systems.all(), "forms": forms}, status=status)


@login_required
def study_controls(request: HttpRequest, pk: int) -> HttpResponse:
    study = _study(request, pk)
    forms = {
        "held_out": _bound(HeldOutControlsForm, request, "held_out"),
        "presets": _bound(PresetControlsForm, request, "presets"),
        "file": _bound(ControlFileForm, request, "file"),
    }
    actions = {
        "held_out": lambda data: "{} held-out control(s).".format(
            len(add_held_out_controls(study, data["seconds"], data["count"]))),
        "presets": lambda data: f"{len(add_preset_controls(study, data['presets']))} synthetic control(s).",
        "file": lambda data: f"{len(add_control_file(study, data['description']))} control(s) from the file.",
    }
    if request.method == "POST":
        action = request.POST.get("action")
        if action in forms and _run(forms[action], request, actions[action], (ControlError,)):
            return redirect("study-controls", pk=study.pk)
    status = 400 if any(f.is_bound for f in forms.values()) else 200
    return render(request, "studyapp/researcher/controls.html",
                  {"study": study, "controls": study.controls.all(), "forms": forms}, status=status)


@login_required
def study_stimuli(request: HttpRequest, pk: int) -> HttpResponse:
    """Generate (idempotently) and watch the progress; failed clips with their reasons."""
    study = _study(request, pk)
    form = GenerateForm(request.POST or None)
    status = 200
    if request.method == "POST" and form.is_valid():
        try:
            result = generate_stimuli(study, form.cleaned_data["seed"])
        except BrokerUnavailable as error:
            messages.error(request, str(error))
            status = 503
        else:
            messages.success(request, f"{result.total} stimuli ({result.created} new); {result.queued} sent to the workers.")
            return redirect("study-stimuli", pk=study.pk)
    stimuli = study.stimuli.select_related("system", "control")
    return render(request, "studyapp/researcher/stimuli.html",
                  {"study": study, "form": form, "stimuli": stimuli, "progress": progress(study)}, status=status)


@never_cache
@login_required
@require_safe
def study_progress(request: HttpRequest, pk: int) -> JsonResponse:
    return JsonResponse(progress(_study(request, pk)))


@login_required
@require_POST
def stimulus_retry(request: HttpRequest, pk: int, stimulus_id: int) -> HttpResponse:
    study = _study(request, pk)
    stimulus = get_object_or_404(Stimulus, pk=stimulus_id, study=study, status=Stimulus.Status.FAILED)
    try:
        retry_stimulus(stimulus)
        messages.success(request, "Sent again.")
    except BrokerUnavailable as error:
        messages.error(request, str(error))
    return redirect("study-stimuli", pk=study.pk)


def entry_link(request: HttpRequest, study: Study) -> str:
    """The participants' entry link as the platform needs it."""
    base = request.build_absolute_uri(reverse("participant-enter", args=[study.key]))
    if study.platform == Study.Platform.PROLIFIC:
        return f"{base}?{PROLIFIC_PLACEHOLDERS}"
    if study.platform == Study.Platform.LINK:
        return f"{base}?{PLATFORM_PARAMETERS[Study.Platform.LINK][0]}=PARTICIPANT_ID"
    return base


@never_cache
@login_required
@require_safe
def study_monitor_page(request: HttpRequest, pk: int) -> HttpResponse:
    study = _study(request, pk)
    context = {
        "study": study, "monitor": study_monitor(study), "entry_link": entry_link(request, study),
        "parameters": PLATFORM_PARAMETERS[study.platform],
    }
    return render(request, "studyapp/researcher/monitor.html", context)


@login_required
@require_POST
def study_open(request: HttpRequest, pk: int) -> HttpResponse:
    """Open the study to participants, or close it (``open`` = "1" or "0")."""
    study = _study(request, pk)
    want_open = request.POST.get("open") == "1"
    if want_open and not study.stimuli.filter(status=Stimulus.Status.DONE).exists():
        messages.error(request, "Generate stimuli first: a study with no finished clip cannot open.")
    else:
        study.is_open = want_open
        study.save(update_fields=["is_open"])
        messages.success(request, "The study is open." if want_open else "The study is closed.")
    return redirect("study-monitor", pk=study.pk)


@never_cache
@login_required
@require_safe
def study_export(request: HttpRequest, pk: int) -> HttpResponse:
    """The ratings table as a CSV download."""
    study = _study(request, pk)
    response = HttpResponse(ratings_csv(study), content_type="text/csv")
    response["Content-Disposition"] = f'attachment; filename="ratings-study-{study.pk}.csv"'
    return response


@login_required
@require_POST
def study_report(request: HttpRequest, pk: int) -> HttpResponse:
    """The analysis report of the ratings so far (the analysis pages' report)."""
    study = _study(request, pk)
    try:
        has_natural = study.systems.filter(role=System.Role.NATURAL).exists()
        digest = create_report(settings.MEDIA_ROOT, ratings_csv(study), NATURAL_NAME if has_natural else None)
    except AnalysisInputError as error:
        messages.error(request, f"No report yet: {error}")
        return redirect("study-monitor", pk=study.pk)
    return redirect("analysis-report", digest=digest)
