"""The participant's path through a study, in the order they meet it:

    entry link -> consent -> instructions -> practice clips -> one clip per page -> completion

``stage()`` says where a participant is, so a reload (or a return on another day) shows
the page they left. Each step's form posts to its own URL and redirects back to the one
page URL. Nothing on these pages names a system: clips are served by random tokens and
the rating form names its assignment by another.
"""

from __future__ import annotations

from functools import wraps
from urllib.parse import urlencode, urlparse

from django.db import IntegrityError
from django.http import Http404, HttpRequest, HttpResponse
from django.shortcuts import get_object_or_404, redirect, render
from django.utils import timezone
from django.views.decorators.cache import never_cache
from django.views.decorators.http import require_POST, require_safe

from studyapp.assignment import StudyFull, StudyNotReady, enrol, renew_reservations
from studyapp.models import Participant, Stimulus, Study, new_token
from studyapp.ratings import ClientTimes, RatingRejected, current_assignment, record_rating

# The query parameters each platform adds to the entry link; the first one is the id.
PLATFORM_PARAMETERS = {
    Study.Platform.PROLIFIC: ("PROLIFIC_PID", "STUDY_ID", "SESSION_ID"),
    Study.Platform.MTURK: ("workerId", "assignmentId", "hitId", "turkSubmitTo"),
    Study.Platform.LINK: ("pid",),
}
# MTurk shows the study in an iframe of its own site; other platforms link to it, so
# their pages keep Django's X-Frame-Options: DENY.
MTURK_FRAME_ANCESTORS = "frame-ancestors https://*.mturk.com"
PROLIFIC_COMPLETION_URL = "https://app.prolific.com/submissions/complete"
MTURK_SUBMIT_HOSTS = {"www.mturk.com", "workersandbox.mturk.com"}
MAX_ID_LENGTH = 100


def _message(request: HttpRequest, title: str, text: str, status: int = 200) -> HttpResponse:
    return render(request, "studyapp/participant/message.html", {"title": title, "text": text}, status=status)


def _framable_by_platform(view):
    """Let MTurk frame the pages of MTurk studies (and no one else frame any study)."""
    @wraps(view)
    def framed(request: HttpRequest, key: str) -> HttpResponse:
        response = view(request, key)
        if Study.objects.filter(key=key, platform=Study.Platform.MTURK).exists():
            response.xframe_options_exempt = True
            response["Content-Security-Policy"] = MTURK_FRAME_ANCESTORS
        return response
    return framed


def _session_key(study: Study) -> str:
    return f"participant:{study.key}"


def _study(key: str, must_be_open: bool = False) -> Study:
    """The study of an entry key. Only new participants need it open: closing a study
    lets those already taking part finish and get their completion code."""
    study = Study.objects.filter(key=key).first()
    if study is None or (must_be_open and not study.is_open):
        raise Http404("no open study here")
    return study


def _participant(request: HttpRequest, study: Study) -> Participant | None:
    pk = request.session.get(_session_key(study))
    return Participant.objects.filter(pk=pk, study=study).first() if pk else None


def stage(participant: Participant) -> str:
    """The page the participant is on."""
    if participant.consented_at is None:
        return "consent"
    if participant.instructed_at is None:
        return "instructions"
    if participant.training_done < len(participant.training):
        return "practice"
    if participant.finished_at is None:
        return "rate"
    return "done"


@never_cache
@_framable_by_platform
@require_safe
def enter(request: HttpRequest, key: str) -> HttpResponse:
    """The entry link: find or create the participant of this platform id, then go to their page."""
    study = _study(key, must_be_open=True)
    names = PLATFORM_PARAMETERS[study.platform]
    data = {name: request.GET[name][:MAX_ID_LENGTH] for name in names if request.GET.get(name)}
    if study.platform == Study.Platform.MTURK and data.get("assignmentId") == "ASSIGNMENT_ID_NOT_AVAILABLE":
        return _message(request, study.title, "This is a preview. Accept the task to take part.")
    platform_id = data.get(names[0])
    existing = _participant(request, study)
    if existing and (platform_id is None or existing.platform_id == platform_id):
        return redirect("participant-page", key=key)
    if platform_id is None:
        if study.platform != Study.Platform.LINK:
            return _message(request, "Link incomplete", f"The link lacks the {names[0]} parameter that "
                            f"{study.get_platform_display()} adds. Please open the study from the platform again.", 400)
        platform_id = f"anonymous-{new_token()}"
    participant = Participant.objects.filter(study=study, platform_id=platform_id).first()
    if participant is None:
        try:
            participant = enrol(study, platform_id, data, request.META.get("HTTP_USER_AGENT", ""))
        except StudyFull:
            return _message(request, "The study is full", "Thank you for your interest: every clip has "
                            "received the ratings it needs. Please return the study on your platform.")
        except StudyNotReady:
            return _message(request, "Not ready yet", "This study has no clips yet. Please try again later.", 503)
        except IntegrityError:  # the same id arriving twice at once: the other request enrolled it
            participant = Participant.objects.get(study=study, platform_id=platform_id)
    request.session[_session_key(study)] = participant.pk
    return redirect("participant-page", key=key)


def _clip_page(request: HttpRequest, study: Study, stimulus: Stimulus, action: str, form: dict,
               heading: str, done: int, total: int, status: int = 200) -> HttpResponse:
    context = {
        "study": study, "video_url": stimulus.video_url, "action": action, "form": form, "heading": heading,
        "scale": list(study.scale), "keys": len(study.scale) <= 10, "done": done, "total": total,
        "percent": round(100 * done / total) if total else 100,
    }
    return render(request, "studyapp/participant/clip.html", context, status=status)


def _completion(study: Study, participant: Participant) -> dict:
    """Where a finished participant goes and what code they are given."""
    code, target = study.completion_code, study.redirect_url
    mturk_submit = None
    if study.platform == Study.Platform.PROLIFIC and code and not target:
        target = f"{PROLIFIC_COMPLETION_URL}?{urlencode({'cc': code})}"
    if study.platform == Study.Platform.MTURK:
        submit_to = participant.platform_data.get("turkSubmitTo", "")
        parsed = urlparse(submit_to)
        if parsed.scheme == "https" and parsed.hostname in MTURK_SUBMIT_HOSTS:
            mturk_submit = {"url": f"{submit_to.rstrip('/')}/mturk/externalSubmit",
                            "assignment_id": participant.platform_data.get("assignmentId", "")}
    return {"code": code, "redirect_url": target, "mturk_submit": mturk_submit}


@never_cache
@_framable_by_platform
@require_safe
def page(request: HttpRequest, key: str) -> HttpResponse:
    """Whatever page the participant is on."""
    study = _study(key)
    participant = _participant(request, study)
    if participant is None:
        return _message(request, study.title, "Please open the study through the link your platform gave you.", 403)
    participant = renew_reservations(participant)
    current = stage(participant)
    if current == "consent":
        return render(request, "studyapp/participant/consent.html", {"study": study})
    if current == "instructions":
        return render(request, "studyapp/participant/instructions.html", {"study": study})
    if current == "practice":
        index = participant.training_done
        stimulus = get_object_or_404(Stimulus, pk=participant.training[index])
        return _clip_page(request, study, stimulus, "participant-practice", {"index": index},
                          f"Practice clip {index + 1} of {len(participant.training)} (not recorded)",
                          index, len(participant.training))
    if current == "rate":
        assignment = current_assignment(participant)
        if assignment.shown_at is None:
            assignment.shown_at = timezone.now()
            assignment.save(update_fields=["shown_at"])
        total = participant.assignments.count()
        done = participant.assignments.filter(rating__isnull=False).count()
        return _clip_page(request, study, assignment.stimulus, "participant-rate", {"assignment": assignment.token},
                          f"Clip {done + 1} of {total}", done, total)
    return render(request, "studyapp/participant/done.html", {"study": study, **_completion(study, participant)})


def _require_stage(request: HttpRequest, key: str, expected: str) -> tuple[Study, Participant]:
    study = _study(key)
    participant = _participant(request, study)
    if participant is None:
        raise RatingRejected("no participant session: open the study through its link", status=403)
    if stage(participant) != expected:
        raise RatingRejected(f"this step is not the current one (expected {expected}, at {stage(participant)})", status=409)
    return study, participant


def _step(handler):
    """Run a POST step; a rejected step answers with its 4xx and a message, changing nothing."""
    @_framable_by_platform
    @require_POST
    @wraps(handler)
    def view(request: HttpRequest, key: str) -> HttpResponse:
        try:
            return handler(request, key)
        except RatingRejected as rejection:
            return _message(request, "That did not work", str(rejection), rejection.status)
    return view


def _passed(participant: Participant, moment: str, key: str) -> HttpResponse:
    """Record when the participant passed a step (``moment`` is its timestamp field); show the next page."""
    setattr(participant, moment, timezone.now())
    participant.save(update_fields=[moment])
    return redirect("participant-page", key=key)


@_step
def consent(request: HttpRequest, key: str) -> HttpResponse:
    """Agree (or not) to take part."""
    _, participant = _require_stage(request, key, "consent")
    if request.POST.get("agree") != "yes":
        return _message(request, "Thank you", "You chose not to take part. Please return the study on your platform.")
    return _passed(participant, "consented_at", key)


@_step
def instructions(request: HttpRequest, key: str) -> HttpResponse:
    """Instructions read."""
    _, participant = _require_stage(request, key, "instructions")
    return _passed(participant, "instructed_at", key)


@_step
def practice(request: HttpRequest, key: str) -> HttpResponse:
    """Move past a practice clip; its answer is not recorded."""
    _, participant = _require_stage(request, key, "practice")
    if request.POST.get("index") == str(participant.training_done):  # a resubmitted form moves nothing
        Participant.objects.filter(pk=participant.pk, training_done=participant.training_done).update(
            training_done=participant.training_done + 1)
    return redirect("participant-page", key=key)


def _optional_float(request: HttpRequest, name: str) -> float | None:
    text = request.POST.get(name, "").strip()
    if not text:
        return None
    try:
        value = float(text)
    except ValueError:
        raise RatingRejected(f"{name} must be a number of seconds, not {text[:20]!r}") from None
    if not 0 <= value < 1e6:
        raise RatingRejected(f"{name} must lie between 0 and a million seconds, not {value}")
    return value


@_step
def rate(request: HttpRequest, key: str) -> HttpResponse:
    """Store the rating of the clip on screen."""
    study = _study(key)
    participant = _participant(request, study)
    if participant is None:
        raise RatingRejected("no participant session: open the study through its link", status=403)
    token = request.POST.get("assignment", "")
    was_reserved = participant.assignments.filter(token=token, rating__isnull=True).exists()
    participant = renew_reservations(participant, touch=False)  # record_rating saves last_seen
    if was_reserved and not participant.assignments.filter(token=token).exists():
        raise RatingRejected("that clip was given to another participant while this page was idle; "
                             "please reload the page to go on with the next one", status=409)
    if stage(participant) not in ("rate", "done"):  # after "done", record_rating says why not
        raise RatingRejected(f"ratings come after the {stage(participant)} step", status=409)
    text = request.POST.get("value", "")
    try:
        value = int(text)
    except ValueError:
        raise RatingRejected(f"the rating must be a whole number from {study.scale_min} to {study.scale_max}, "
                             f"not {text[:20]!r}") from None
    times = ClientTimes(*(_optional_float(request, name) for name in ("started_s", "ended_s", "answered_s", "played_until_s")))
    record_rating(participant, token, value, times)
    return redirect("participant-page", key=key)
