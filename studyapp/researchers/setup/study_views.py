"""The pages of a study as a whole: the list of studies, its settings, its copy, its
removal and its items' edits and removals, the preview of the participant's path, and opening it.

Every page needs a login, and a researcher reaches only their own studies
(``access.researcher_study``: another researcher's study answers 404). What a form
means is done by the service modules of ``setup`` and ``stimuli``, which the management
commands share.
"""

from __future__ import annotations

from django.contrib import messages
from django.contrib.auth.decorators import login_required
from django.db.models import Count, Q
from django.http import Http404, HttpRequest, HttpResponse
from django.shortcuts import get_object_or_404, redirect, render
from django.urls import reverse
from django.utils import timezone
from django.views.decorators.cache import never_cache
from django.views.decorators.http import require_http_methods, require_POST, require_safe

from studyapp.models import ControlSignal, Stimulus, Study, System
from studyapp.preregistration.fixed import started
from studyapp.researchers.access import owned_study, researcher_study
from studyapp.researchers.setup.duplication import duplicate_study
from studyapp.researchers.setup.editing import EditRefused, edit_system, rename_control
from studyapp.researchers.setup.forms import ControlEditForm, StudyForm, SystemEditForm
from studyapp.researchers.setup.preview import preview_pages
from studyapp.researchers.setup.readiness import open_problems, open_warnings
from studyapp.researchers.setup.removal import SystemsFixed, removal_summary, remove, remove_study, require_not_started


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
    study = owned_study(request, pk) if pk is not None else Study(owner=request.user)
    form = StudyForm(request.POST or None, instance=study)
    if request.method == "POST":
        if form.is_valid():
            study = form.save()
            messages.success(request, f"Saved {study.title}.")
            return redirect("study-systems", pk=study.pk)
        return render(request, "studyapp/researcher/study_form.html", {"form": form, "study": study}, status=400)
    return render(request, "studyapp/researcher/study_form.html", {"form": form, "study": study})


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


@researcher_study
def study_item_edit(request: HttpRequest, study: Study, kind: str, item: int) -> HttpResponse:
    """Edit a system's name and temperature or a control's name, until the first participant starts (409 after)."""
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


@researcher_study
@require_http_methods(["GET", "HEAD", "POST"])
def study_remove(request: HttpRequest, study: Study, kind: str, item: int) -> HttpResponse:
    """Remove a system or a control, with its clips, until the first participant starts:
    asked for (GET) with what it deletes, done when confirmed (POST)."""
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


@researcher_study
@require_http_methods(["GET", "HEAD", "POST"])
def study_delete(request: HttpRequest, study: Study) -> HttpResponse:
    """Delete a whole study with everything in it: asked for (GET) with what it deletes, done when confirmed (POST)."""
    if request.method != "POST":
        return _confirm_removal(request, study, study, reverse("study-monitor", args=[study.pk]))
    title = study.title
    clips = remove_study(study)
    messages.success(request, f"Deleted “{title}” and its {clips} clip(s).")
    return redirect("study-list")


@researcher_study
@require_POST
def study_duplicate(request: HttpRequest, study: Study) -> HttpResponse:
    """A closed copy of the study, its clips linked rather than rendered again; its settings page next."""
    try:
        copy = duplicate_study(study)
    except FileNotFoundError as error:
        messages.error(request, f"Not duplicated: {error}.")
        return redirect("study-monitor", pk=study.pk)
    messages.success(request, f"Duplicated as “{copy.title}”, closed, with {copy.stimuli.count()} finished clip(s) "
                              "and no participants: change what differs, then open it.")
    return redirect("study-edit", pk=copy.pk)


@never_cache
@researcher_study
@require_safe
def study_preview(request: HttpRequest, study: Study, index: int = 0) -> HttpResponse:
    """Page ``index`` of the participant's path as a participant sees it; nothing is recorded."""
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
    return render(request, f"studyapp/participant/{page.template}", {"study": study, "preview": preview, **page.context})


@researcher_study
@require_POST
def study_open(request: HttpRequest, study: Study) -> HttpResponse:
    """Open the study to participants, or close it (``open`` = "1" or "0"); a study with
    warnings opens only when they were seen (``despite_warnings`` = "1")."""
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


__all__ = ["study_delete", "study_duplicate", "study_edit", "study_item_edit", "study_list", "study_open", "study_preview", "study_remove"]
