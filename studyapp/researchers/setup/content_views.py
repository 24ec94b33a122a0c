"""The study's systems and controls pages (several forms a page, each posting its
``action``) and the controls' download."""

from __future__ import annotations

from functools import partial

from django.contrib import messages
from django.http import HttpRequest, HttpResponse
from django.shortcuts import redirect, render
from django.views.decorators.cache import never_cache
from django.views.decorators.http import require_safe

from generation import registry
from studyapp.models import Study, System
from studyapp.researchers.access import researcher_study
from studyapp.researchers.downloads import zip_download
from studyapp.researchers.setup.forms import (
    CheckpointSystemForm,
    ControlFileForm,
    HeldOutControlsForm,
    LabelControlsForm,
    NaturalSystemForm,
    PresetControlsForm,
    SubmittedMotionSystemForm,
    VideoSystemForm,
)
from studyapp.stimuli.control_export import bundle_zip
from studyapp.stimuli.controls import (
    ControlError,
    add_control_file,
    add_held_out_controls,
    add_label_controls,
    add_preset_controls,
    control_kind,
    shorter_than_asked_warnings,
    study_labels,
)
from studyapp.stimuli.submissions import Reading, add_submitted_upload
from studyapp.stimuli.systems import UploadRefused, add_checkpoint_system, add_natural_system, add_video_system


def _forms_page(request: HttpRequest, study: Study, page: str, forms: dict, actions: dict,
                refusal: type[Exception], context: dict) -> HttpResponse:
    """A page of several forms, each posting ``action=<its key>``.

    The submitted form is validated and its action run; the action's message is shown
    after a redirect. A refusal (``refusal``) is listed at the top of the page, one
    problem a line (a submission's every problem), and the form points there, with 400.
    """
    action = request.POST.get("action") if request.method == "POST" else None
    # Each form's own element ids, so that every label names its own input.
    bound = {key: form_class(request.POST, request.FILES, auto_id=f"id_{key}_%s") if key == action
             else form_class(auto_id=f"id_{key}_%s") for key, form_class in forms.items()}
    form = bound.get(action)
    refused = None
    if form is not None and form.is_valid():
        try:
            messages.success(request, actions[action](form.cleaned_data))
            return redirect(f"study-{page}", pk=study.pk)
        except refusal as error:
            refused = _refusal(error)
            form.add_error(None, "Refused: the problems are listed at the top of the page.")
    status = 400 if request.method == "POST" else 200
    return render(request, f"studyapp/researcher/{page}.html",
                  {"study": study, "forms": bound, "refused": refused, **context}, status=status)


def _refusal(error: Exception) -> dict:
    """A refusal as the top of a page lists it: a title, then one problem a line."""
    problems = getattr(error, "lines", None)  # a submission's report, one control a line
    if problems:
        refused = set(getattr(error, "refused", problems))  # the others say what was read or ready
        return {"title": str(error).splitlines()[0].rstrip(":"), "problems": problems,
                "accepted": [line for line in problems if line not in refused]}
    return {"title": "Not done", "problems": [str(error)]}


def _submitted(system: System) -> str:
    return f"Registered {system.name} with motion for {len(system.metadata['controls'])} control(s)."


@researcher_study
def study_systems(request: HttpRequest, study: Study) -> HttpResponse:
    forms = {"checkpoint": CheckpointSystemForm, "natural": NaturalSystemForm, "motion": SubmittedMotionSystemForm,
             "videos": VideoSystemForm}
    actions = {
        "checkpoint": lambda data: "Registered {}.".format(add_checkpoint_system(
            study, data["name"], data["checkpoint"], data["role"], data["temperature"]).name),
        "natural": lambda data: f"Registered {add_natural_system(study, data['name']).name}.",
        "motion": lambda data: _submitted(add_submitted_upload(study, data["name"], data["motion"], data["role"], Reading(
            data["unit"], data["up"], data["keep_root"]))),
        "videos": lambda data: "Registered {} with {} video(s).".format(
            add_video_system(study, data["name"], data["videos"], data["role"]).name, len(data["videos"])),
    }
    return _forms_page(request, study, "systems", forms, actions, UploadRefused, {"systems": study.systems.all()})


@researcher_study
def study_controls(request: HttpRequest, study: Study) -> HttpResponse:
    try:
        kind = control_kind(study)
    except ControlError as error:
        messages.error(request, str(error))
        kind = registry.PATH
    trained = study.systems.exclude(checkpoint="").exists()
    forms: dict = {"held_out": partial(HeldOutControlsForm, paths=kind == registry.PATH, trained=trained)}
    if kind == registry.PATH:
        forms.update(presets=PresetControlsForm, file=ControlFileForm)
    else:
        forms["labels"] = partial(LabelControlsForm, labels=study_labels(study))
    actions = {
        "held_out": lambda data: _add_held_out_controls(request, study, data),
        "presets": lambda data: f"{len(add_preset_controls(study, data['presets']))} synthetic control(s).",
        "file": lambda data: f"{len(add_control_file(study, data['description']))} control(s) from the file.",
        "labels": lambda data: "{} label control(s).".format(
            len(add_label_controls(study, data["actions"], data["styles"], data["seconds"]))),
    }
    return _forms_page(request, study, "controls", forms, actions, ControlError,
                       {"controls": study.controls.all(), "kind": kind, "trained": trained})


def _add_held_out_controls(request: HttpRequest, study: Study, data: dict) -> str:
    """Add the form's held-out controls; warn of each that lasts less than asked."""
    added = add_held_out_controls(study, data["seconds"], data["count"], data.get("lead_in") or 0.0,
                                  takes=data["takes"], scale=data.get("unit"), up=data.get("up"))
    for warning in shorter_than_asked_warnings(added, data["seconds"]):
        messages.warning(request, warning)
    return f"{len(added)} held-out control(s)."


@never_cache
@researcher_study
@require_safe
def study_controls_download(request: HttpRequest, study: Study) -> HttpResponse:
    """The controls as a zip (``control_export``); ``?natural=1`` adds the held-out controls' natural clips."""
    return zip_download(request, study, f"controls-study-{study.pk}.zip",
                        partial(bundle_zip, study, natural=request.GET.get("natural") == "1"),
                        "study-controls", (ControlError, ValueError, FileNotFoundError))


__all__ = ["study_controls", "study_controls_download", "study_systems"]
