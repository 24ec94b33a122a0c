"""The researcher's pages: studies, their systems, controls, stimuli and the running study.

Every page needs a login, and a researcher reaches only their own studies: another
researcher's study answers 404, as if it did not exist. Forms post back to their page;
what a form means is done by the service modules (``stimuli.systems``, ``stimuli.controls``,
``stimuli.clips``, ``monitor``, ``export``), which the management commands share.
"""

from __future__ import annotations

from functools import partial

from django.conf import settings
from django.contrib import messages
from django.contrib.auth.decorators import login_required
from django.db.models import Count, Q
from django.http import FileResponse, Http404, HttpRequest, HttpResponse, JsonResponse
from django.shortcuts import get_object_or_404, redirect, render
from django.urls import reverse
from django.views.decorators.cache import never_cache
from django.utils import timezone
from django.views.decorators.http import require_http_methods, require_POST, require_safe

from generation import registry
from studyapp.designs.registry import design_of
from studyapp.designs.rules import StudyRules
from studyapp.models import ControlSignal, Question, Stimulus, Study, System
from studyapp.participants.views import PLATFORM_PARAMETERS
from studyapp.plan.fixed import StudyFixed, started
from studyapp.plan.lock import preregistration
from studyapp.plan.words import in_words
from studyapp.researchers.setup import question_order
from studyapp.researchers.results.adherence import adherence_tables
from studyapp.researchers.crowd.completion_time import completion_minutes
from studyapp.researchers.setup.duplication import duplicate_study
from studyapp.researchers.setup.editing import EditRefused, edit_system, rename_control
from studyapp.researchers.results.export import ratings_csv, rules_json
from studyapp.researchers.setup.forms import (CheckpointSystemForm, ControlEditForm, ControlFileForm, GenerateForm, HeldOutControlsForm,
                            LabelControlsForm, NaturalSystemForm, PresetControlsForm, QuestionForm, QuestionRemovalForm, StudyForm,
                            SubmittedMotionSystemForm, SystemEditForm, VideoSystemForm)
from studyapp.researchers.results.monitor import study_monitor
from studyapp.researchers.results.monitor_figures import live_figures
from studyapp.researchers.crowd.participant_list import participant_rows, participants_csv, question_names
from studyapp.researchers.setup.preview import preview_pages, render_preview
from studyapp.researchers.setup.readiness import open_problems, open_warnings
from studyapp.researchers.setup.removal import SystemsFixed, removal_summary, remove, remove_study, require_not_started
from studyapp.researchers.results.reports import AnalysisInputError, create_study_report, html_table
from studyapp.server.celery import app as celery_app
from studyapp.server.health import collect_health
from studyapp.stimuli.clips import progress
from studyapp.stimuli.control_export import bundle_zip
from studyapp.stimuli.controls import (ControlError, add_control_file, add_held_out_controls, add_label_controls,
                               add_preset_controls, control_kind, shorter_than_asked_warnings, study_labels)
from studyapp.stimuli.dispatch import BrokerUnavailable, generate_stimuli, retry_stimulus
from studyapp.stimuli.lost_tasks import worker_seen_lately
from studyapp.stimuli.mismatched import study_pairings
from studyapp.stimuli.motion_export import exported_stimuli, motion_zip
from studyapp.stimuli.submissions import Reading, add_submitted_upload
from studyapp.stimuli.systems import UploadRefused, add_checkpoint_system, add_natural_system, add_video_system
from studyapp.stimuli.video_export import finished_clips, stimuli_zip

# Prolific fills these placeholders in a study URL; MTurk appends its own ids.
PROLIFIC_PLACEHOLDERS = "PROLIFIC_PID={{%PROLIFIC_PID%}}&STUDY_ID={{%STUDY_ID%}}&SESSION_ID={{%SESSION_ID%}}"


def _study(request: HttpRequest, pk: int) -> Study:
    return get_object_or_404(Study, pk=pk, owner=request.user)


def _download(body: bytes | str, content_type: str, filename: str) -> HttpResponse:
    """``body`` as a file the browser saves as ``filename``."""
    response = HttpResponse(body, content_type=content_type)
    response["Content-Disposition"] = f'attachment; filename="{filename}"'
    return response


@login_required
@require_safe
def study_list(request: HttpRequest) -> HttpResponse:
    rated_clip = Q(stimuli__status=Stimulus.Status.DONE) & ~Q(stimuli__system__role=System.Role.BAD)
    studies = Study.objects.filter(owner=request.user).annotate(
        started=Count("participants", distinct=True),
        finished=Count("participants", filter=Q(participants__finished_at__isnull=False), distinct=True),
        rated_clips=Count("stimuli", filter=rated_clip, distinct=True),
        ratings=Count("participants__assignments__rating", distinct=True,
                      filter=~Q(participants__assignments__stimulus__system__role=System.Role.BAD)),
    )
    for study in studies:
        needed = study.rated_clips * study.ratings_per_stimulus
        study.needed = needed
        study.percent = min(100, round(100 * study.ratings / needed)) if needed else 0
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
        return {"title": str(error).splitlines()[0].rstrip(":"), "problems": problems}
    return {"title": "Not done", "problems": [str(error)]}


def _submitted(system: System) -> str:
    return f"Registered {system.name} with motion for {len(system.metadata['controls'])} control(s)."


@login_required
def study_systems(request: HttpRequest, pk: int) -> HttpResponse:
    study = _study(request, pk)
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


@login_required
def study_controls(request: HttpRequest, pk: int) -> HttpResponse:
    study = _study(request, pk)
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
@login_required
@require_safe
def study_controls_download(request: HttpRequest, pk: int) -> HttpResponse:
    """The controls as a zip (``control_export``); ``?natural=1`` adds the held-out controls' natural clips."""
    study = _study(request, pk)
    try:
        data = bundle_zip(study, natural=request.GET.get("natural") == "1")
    except (ControlError, ValueError, FileNotFoundError) as error:
        messages.error(request, f"No download: {error}")
        return redirect("study-controls", pk=study.pk)
    return _download(data, "application/zip", f"controls-study-{study.pk}.zip")


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
        except StudyFixed as error:
            form.add_error("seed", str(error))
            status = 409
        else:
            messages.success(request, f"{result.total} stimuli ({result.created} new); {result.queued} sent to the workers.")
            return redirect("study-stimuli", pk=study.pk)
    elif request.method == "POST":
        status = 400  # the form, with what is wrong with it
    state = progress(study)
    # Queued clips with nobody to make them: say so rather than let the bar sit still. A
    # worker busy rendering may miss the ping, so a row a worker took (or one queued too
    # recently for any to take) within the heartbeat's time says more than the ping.
    waiting = state["counts"]["queued"] + state["counts"]["running"]
    health = (collect_health(celery_app, settings.HEALTH_TIMEOUT_S)
              if waiting and not worker_seen_lately() else None)
    context = {"study": study, "form": form,
               "stimuli": study.stimuli.select_related("system", "control", "shown_control"),
               "pairings": study_pairings(study) if design_of(study).mismatched_clips else None,
               "progress": state, "no_worker": health is not None and not health.workers, "health": health}
    return render(request, "studyapp/researcher/stimuli.html", context, status=status)


def _item(study: Study, kind: str, item: int) -> System | ControlSignal:
    """The study's system or control ``item`` (``kind`` "systems" or "controls"), or 404."""
    model = {"systems": System, "controls": ControlSignal}.get(kind)
    if model is None:
        raise Http404(f"nothing called {kind} in a study")
    return get_object_or_404(model, pk=item, study=study)


def _save_edit(target: System | ControlSignal, data: dict) -> str:
    """Apply an edit form's data (``editing``); the message saying what happened."""
    if isinstance(target, ControlSignal):
        rename_control(target, data["name"])
        return f"Saved {target.name}."
    deleted = edit_system(target, data["name"], data.get("temperature"))
    resample = f" Its {deleted} clip(s) were deleted: generate the stimuli to sample them at temperature " \
               f"{target.temperature:g}." if deleted else ""
    return f"Saved {target.name}.{resample}"


@login_required
def study_item_edit(request: HttpRequest, pk: int, kind: str, item: int) -> HttpResponse:
    """Edit a system's name and temperature or a control's name, until the first participant starts (409 after)."""
    study = _study(request, pk)
    target = _item(study, kind, item)
    if isinstance(target, System):
        form = SystemEditForm(request.POST or None, sampled=bool(target.checkpoint),
                              initial={"name": target.name, "temperature": target.temperature})
    else:
        form = ControlEditForm(request.POST or None, initial={"name": target.name})
    status = 200
    if request.method == "POST":
        try:
            require_not_started(study)  # before the form: once anyone has started, any input gets 409
            if form.is_valid():
                messages.success(request, _save_edit(target, form.cleaned_data))
                return redirect(f"study-{kind}", pk=study.pk)
            status = 400
        except EditRefused as error:
            form.add_error(error.field, str(error))
            status = 400
        except SystemsFixed:
            status = 409
    context = {"study": study, "form": form, "target": target, "kind": kind, "locked": started(study)}
    return render(request, "studyapp/researcher/edit_item.html", context, status=status)


def _confirm_removal(request: HttpRequest, study: Study, target: System | ControlSignal | Study,
                     back: str, refusal: str = "") -> HttpResponse:
    """The page that says what a removal deletes (and what it keeps) and asks to confirm it."""
    *deletes, kept = removal_summary(target)
    context = {"study": study, "target": target, "deletes": deletes, "kept": kept, "back": back, "refusal": refusal,
               "whole_study": isinstance(target, Study)}
    return render(request, "studyapp/researcher/confirm_removal.html", context)


@login_required
@require_http_methods(["GET", "HEAD", "POST"])
def study_remove(request: HttpRequest, pk: int, kind: str, item: int) -> HttpResponse:
    """Remove a system or a control, with its clips, until the first participant starts:
    asked for (GET) with what it deletes, done when confirmed (POST)."""
    study = _study(request, pk)
    target = _item(study, kind, item)
    if request.method != "POST":
        fixed = "participants have started this study: its systems and controls are fixed" \
            if started(study) else ""
        return _confirm_removal(request, study, target, reverse(f"study-{kind}", args=[study.pk]), fixed)
    try:
        clips = remove(target)
        messages.success(request, f"Removed {target.name} and its {clips} clip(s).")
    except SystemsFixed as refusal:
        messages.error(request, f"{target.name} stays: {refusal}.")
    return redirect(f"study-{kind}", pk=study.pk)


@login_required
@require_http_methods(["GET", "HEAD", "POST"])
def study_delete(request: HttpRequest, pk: int) -> HttpResponse:
    """Delete a whole study with everything in it: asked for (GET) with what it deletes, done when confirmed (POST)."""
    study = _study(request, pk)
    if request.method != "POST":
        return _confirm_removal(request, study, study, reverse("study-monitor", args=[study.pk]))
    title = study.title
    clips = remove_study(study)
    messages.success(request, f"Deleted “{title}” and its {clips} clip(s).")
    return redirect("study-list")


@login_required
@require_POST
def study_duplicate(request: HttpRequest, pk: int) -> HttpResponse:
    """A closed copy of the study, its clips linked rather than rendered again; its settings page next."""
    study = _study(request, pk)
    try:
        copy = duplicate_study(study)
    except FileNotFoundError as error:
        messages.error(request, f"Not duplicated: {error}.")
        return redirect("study-monitor", pk=study.pk)
    messages.success(request, f"Duplicated as “{copy.title}”, closed, with {copy.stimuli.count()} finished clip(s) "
                              "and no participants: change what differs, then open it.")
    return redirect("study-edit", pk=copy.pk)


@never_cache
@login_required
@require_safe
def study_stimuli_download(request: HttpRequest, pk: int) -> HttpResponse:
    """Every finished clip as an MP4, in one zip with an index (``video_export``)."""
    study = _study(request, pk)
    if not finished_clips(study):
        messages.error(request, "No clips to download yet: generate the stimuli first.")
        return redirect("study-stimuli", pk=study.pk)
    try:
        archive = stimuli_zip(study)
    except FileNotFoundError as error:
        messages.error(request, f"No download: {error}.")
        return redirect("study-stimuli", pk=study.pk)
    return FileResponse(archive, as_attachment=True, filename=f"stimuli-study-{study.pk}.zip",
                        content_type="application/zip")


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
@login_required
@require_safe
def study_preview(request: HttpRequest, pk: int, index: int = 0) -> HttpResponse:
    """Page ``index`` of the participant's path as a participant sees it; nothing is recorded."""
    study = _study(request, pk)
    pages = preview_pages(study)
    if not pages:
        messages.error(request, "The preview needs a finished clip: generate the stimuli first.")
        return redirect("study-stimuli", pk=study.pk)
    # An update, not a save: participants' pages keep the study cached while ``updated`` stands.
    Study.objects.filter(pk=study.pk).update(previewed_at=timezone.now())
    if index >= len(pages):
        return redirect("study-preview-page", pk=study.pk, index=0)
    page = pages[index]
    following = reverse("study-preview-page", args=[study.pk, index + 1]) if index + 1 < len(pages) else ""
    preview = {"index": index + 1, "count": len(pages), "name": page.name, "next": following,
               "back": reverse("study-monitor", args=[study.pk])}
    return render_preview(request, study, page, preview)


@never_cache
@login_required
@require_safe
def study_participants(request: HttpRequest, pk: int) -> HttpResponse:
    """Who took part, how far they got and what the study's rules suggest doing with their submission."""
    study = _study(request, pk)
    names = question_names(study)
    rows = [(row, [row.answers.get(name, "") for name in names]) for row in participant_rows(study)]
    context = {"study": study, "rows": rows, "questions": names, "completion": completion_minutes(study)}
    return render(request, "studyapp/researcher/participants.html", context)


@login_required
def study_questions(request: HttpRequest, pk: int) -> HttpResponse:
    """Questions before the ratings (screening) and after them; fixed once anyone has started."""
    study = _study(request, pk)
    locked = started(study)
    form = QuestionForm(instance=Question(study=study))
    status = 200
    if request.method == "POST":
        if locked:
            messages.error(request, "Participants have started: the questions are fixed.")
            return redirect("study-questions", pk=study.pk)
        if request.POST.get("action") == "remove":
            removal = QuestionRemovalForm(request.POST, study=study)
            if removal.is_valid():
                question = removal.cleaned_data["question"]
                question.delete()
                messages.success(request, f"Removed “{question.text}”.")
                return redirect("study-questions", pk=study.pk)
            messages.error(request, "Nothing removed: " + " ".join(removal.errors["question"]))
        else:
            form = QuestionForm(request.POST, instance=Question(study=study))
            if form.is_valid():
                form.instance.order = question_order.last_place(form.instance)
                messages.success(request, f"Added “{form.save().text}”.")
                return redirect("study-questions", pk=study.pk)
        status = 400
    # In the order participants meet them: the questions before the ratings first.
    questions = study.questions.order_by("-part", "order", "created", "pk")
    context = {"study": study, "form": form, "locked": locked, "questions": questions}
    return render(request, "studyapp/researcher/questions.html", context, status=status)


@login_required
def study_question_edit(request: HttpRequest, pk: int, question: int) -> HttpResponse:
    """Change a question (its text, choices, part, ...) until anyone has started."""
    study = _study(request, pk)
    target = get_object_or_404(Question, pk=question, study=study)
    locked = started(study)
    part = target.part
    form = QuestionForm(request.POST or None, instance=target)
    status = 200
    if request.method == "POST":
        if locked:
            messages.error(request, "Participants have started: the questions are fixed.")
            return redirect("study-questions", pk=study.pk)
        if form.is_valid():
            if form.instance.part != part:  # it joins the other part at its end
                form.instance.order = question_order.last_place(form.instance)
            messages.success(request, f"Saved “{form.save().text}”.")
            return redirect("study-questions", pk=study.pk)
        status = 400
    return render(request, "studyapp/researcher/question_edit.html",
                  {"study": study, "form": form, "question": target, "locked": locked}, status=status)


@login_required
@require_POST
def study_question_move(request: HttpRequest, pk: int, question: int) -> HttpResponse:
    """Move a question one place up or down (``direction`` "up" or "down") within its part."""
    study = _study(request, pk)
    target = get_object_or_404(Question, pk=question, study=study)
    step = {"up": -1, "down": 1}.get(request.POST.get("direction", ""))
    if step is None:
        return HttpResponse("direction must be up or down", status=400, content_type="text/plain")
    if started(study):
        messages.error(request, "Participants have started: the questions are fixed.")
    elif not question_order.move(target, step):
        messages.error(request, f"“{target.text}” is {'first' if step < 0 else 'last'} of its part already.")
    return redirect("study-questions", pk=study.pk)


@never_cache
@login_required
@require_safe
def study_participants_csv(request: HttpRequest, pk: int) -> HttpResponse:
    study = _study(request, pk)
    return _download(participants_csv(study), "text/csv", f"participants-study-{study.pk}.csv")


@login_required
@require_POST
def study_open(request: HttpRequest, pk: int) -> HttpResponse:
    """Open the study to participants, or close it (``open`` = "1" or "0"); a study with
    warnings opens only when they were seen (``despite_warnings`` = "1")."""
    study = _study(request, pk)
    want_open = request.POST.get("open") == "1"
    if want_open and (problems := open_problems(study)):
        messages.error(request, "The study cannot open: " + "; ".join(problems) + ".")
    elif want_open and (warnings := open_warnings(study)) and request.POST.get("despite_warnings") != "1":
        messages.error(request, "Not opened: " + "; ".join(warnings) + ". To open it all the same, tick "
                                "“Open it despite the warning” beside the button.")
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
    return _download(ratings_csv(study, for_spreadsheets=True), "text/csv", f"ratings-study-{study.pk}.csv")


@never_cache
@login_required
@require_safe
def study_rules(request: HttpRequest, pk: int) -> HttpResponse:
    """The exclusion rules of the ratings table, for ``python -m analysis report --rules``."""
    study = _study(request, pk)
    return _download(rules_json(study), "application/json", f"rules-study-{study.pk}.json")


@never_cache
@login_required
@require_safe
def study_motion_download(request: HttpRequest, pk: int) -> HttpResponse:
    """Every system's motion of the finished clips as a zip, for the objective metrics (``motion_export``)."""
    study = _study(request, pk)
    if not exported_stimuli(study):
        messages.error(request, "No motion to download yet: generate the stimuli first.")
        return redirect("study-monitor", pk=study.pk)
    try:
        data = motion_zip(study)
    except ValueError as error:
        messages.error(request, f"No download: {error}")
        return redirect("study-monitor", pk=study.pk)
    return _download(data, "application/zip", f"motion-study-{study.pk}.zip")


@never_cache
@login_required
@require_safe
def study_adherence(request: HttpRequest, pk: int) -> HttpResponse:
    """How closely the study's motion follows its controls, and (appropriateness) its correlation with the scores."""
    study = _study(request, pk)
    try:
        tables, notes = adherence_tables(study)
    except ValueError as error:
        messages.error(request, f"No control adherence: {error}")
        return redirect("study-monitor", pk=study.pk)
    return render(request, "studyapp/researcher/adherence.html",
                  {"study": study, "tables": [(title, html_table(table)) for title, table in tables], "notes": notes})


@never_cache
@login_required
@require_safe
def study_plan(request: HttpRequest, pk: int) -> HttpResponse:
    """The plan locked when the study first opened, in words, and every deviation from it since."""
    study = _study(request, pk)
    return render(request, "studyapp/researcher/plan.html", {"study": study, "plan": in_words(preregistration(study))})


@login_required
@require_POST
def study_report(request: HttpRequest, pk: int) -> HttpResponse:
    """The analysis report of the ratings so far (the analysis pages' report)."""
    study = _study(request, pk)
    try:
        digest = create_study_report(study, request.user.pk)
    except AnalysisInputError as error:
        messages.error(request, f"No report yet: {error}")
        return redirect("study-monitor", pk=study.pk)
    return redirect("analysis-report", digest=digest)
