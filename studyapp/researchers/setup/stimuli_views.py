"""The stimuli page: generating a study's clips, their progress, a failed clip sent
again, and every finished clip in one zip."""

from __future__ import annotations

from functools import partial

from django.conf import settings
from django.contrib import messages
from django.http import HttpRequest, HttpResponse, JsonResponse
from django.shortcuts import get_object_or_404, redirect, render
from django.views.decorators.cache import never_cache
from django.views.decorators.http import require_POST, require_safe

from studyapp.designs.registry import design_of
from studyapp.models import Stimulus, Study
from studyapp.preregistration.fixed import StudyFixed
from studyapp.researchers.access import researcher_study
from studyapp.researchers.downloads import zip_download
from studyapp.researchers.setup.forms import GenerateForm
from studyapp.server.celery import app as celery_app
from studyapp.server.health import collect_health
from studyapp.stimuli.clips import progress
from studyapp.stimuli.dispatch import BrokerUnavailable, generate_stimuli, retry_stimulus
from studyapp.stimuli.lost_tasks import worker_seen_lately
from studyapp.stimuli.mismatched import study_pairings
from studyapp.stimuli.video_export import finished_clips, stimuli_zip


@researcher_study
def study_stimuli(request: HttpRequest, study: Study) -> HttpResponse:
    """Generate (idempotently) and watch the progress; failed clips with their reasons."""
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


@never_cache
@researcher_study
@require_safe
def study_progress(request: HttpRequest, study: Study) -> JsonResponse:
    return JsonResponse(progress(study))


@researcher_study
@require_POST
def stimulus_retry(request: HttpRequest, study: Study, stimulus_id: int) -> HttpResponse:
    stimulus = get_object_or_404(Stimulus, pk=stimulus_id, study=study, status=Stimulus.Status.FAILED)
    try:
        retry_stimulus(stimulus)
        messages.success(request, "Sent again.")
    except BrokerUnavailable as error:
        messages.error(request, str(error))
    return redirect("study-stimuli", pk=study.pk)


@never_cache
@researcher_study
@require_safe
def study_stimuli_download(request: HttpRequest, study: Study) -> HttpResponse:
    """Every finished clip as an MP4, in one zip with an index (``video_export``)."""
    return zip_download(request, study, f"stimuli-study-{study.pk}.zip", partial(stimuli_zip, study),
                        "study-stimuli", (FileNotFoundError,),
                        not_yet="" if finished_clips(study) else "No clips to download yet: generate the stimuli first.")


__all__ = ["stimulus_retry", "study_progress", "study_stimuli", "study_stimuli_download"]
