"""The participant's path through a study, declared once: ``PATH``, its steps in order.

    entry link -> (device check) -> consent -> (screening questions) -> instructions
      -> practice clips -> the study's pages -> (closing questions) -> completion

The pages are those of the study's design (``Study.design``): one clip each (single),
every system's clip of one control on sliders (side-by-side), or two clips to choose
between (pairwise); a step with a ``design`` belongs to that design's path only. A
participant who fails too many instructed checks leaves the path with a polite ending.

Each ``Step`` says when the participant is on it (``pending``: the first pending
step is theirs, so a reload or a return on another day shows the page they left), what
its page shows (a template and its context) and what its form does (``submit``, which
redirects to the one page URL; the last step has no form). ``stage()`` reads the table,
``participant_views`` renders and guards the steps through it, and ``urls`` gives each
form its URL, /p/KEY/<step name>/. A new page type (a questionnaire, a multi-clip page)
is one entry here and one template.

Nothing on these pages names a system: clips are served by random tokens and the rating
form names its assignment by another.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from urllib.parse import urlencode, urlparse

from django.http import Http404, HttpRequest, HttpResponse
from django.shortcuts import redirect, render
from django.utils import timezone

from studyapp.designs.instructed_checks import instruction
from studyapp.designs.page_steps import client_times, page_context, rate_pairwise, rate_side_by_side
from studyapp.designs.ratings import RatingRejected, record_rating
from studyapp.models import Assignment, Participant, Question, Stimulus, Study
from studyapp.participants.assignment import is_idle, renew_reservations
from studyapp.participants.questionnaires import field_name, questions, read_answers, screened_out

PROLIFIC_COMPLETION_URL = "https://app.prolific.com/submissions/complete"
MTURK_SUBMIT_HOSTS = {"www.mturk.com", "workersandbox.mturk.com"}

PageContext = Callable[[Study, Participant], dict]
Submit = Callable[[HttpRequest, Study, Participant], HttpResponse]


@dataclass(frozen=True)
class Step:
    """One page of the path; its form posts to /p/KEY/<name>/ (URL name ``participant-<name>``)."""

    name: str
    template: str  # under studyapp/templates/studyapp/participant/
    pending: Callable[[Participant], bool]  # not passed yet
    design: str | None = None  # on the path of studies of this design only (None: of every design)
    page: PageContext = lambda study, participant: {}
    submit: Submit | None = None
    # Its form is still passed to ``submit`` once the participant has gone past the step,
    # so that submit can say why it refuses (a rating sent again after the last clip).
    takes_late_posts: bool = False


def message(request: HttpRequest, title: str, text: str, status: int = 200, back: str = "") -> HttpResponse:
    """A page with a title and one notice, and no form; ``back``, a link to the page to go on from."""
    return render(request, "studyapp/participant/message.html", {"title": title, "text": text, "back": back},
                  status=status)


def _next_page(study: Study) -> HttpResponse:
    return redirect("participant-page", key=study.key)


def _passing(moment: str) -> Submit:
    """A submit that records when the participant passed the step (``moment`` is its timestamp field)."""
    def submit(request: HttpRequest, study: Study, participant: Participant) -> HttpResponse:
        setattr(participant, moment, timezone.now())
        participant.save(update_fields=[moment])
        return _next_page(study)
    return submit


def _consent(request: HttpRequest, study: Study, participant: Participant) -> HttpResponse:
    """Agree (or not) to take part; a study without screening questions passes that step too."""
    if request.POST.get("agree") != "yes":
        return message(request, "Thank you", "You chose not to take part. Please return the study on your platform.")
    participant.consented_at = timezone.now()
    if not study.questions.filter(part=Question.Part.BEFORE).exists():
        participant.screened_at = participant.consented_at
    participant.save(update_fields=["consented_at", "screened_at"])
    return _next_page(study)


def _device_page(study: Study, participant: Participant) -> dict:
    """A clip the participant will see anyway (their first), played before they consent."""
    first = participant.training[0] if participant.training else participant.assignments.values_list(
        "stimulus_id", flat=True).order_by("position").first()
    stimulus = Stimulus.objects.filter(pk=first).first()
    if stimulus is None:
        raise Http404("no clip for the device check")
    return {"video_url": stimulus.video_url, "min_width": study.min_screen_width,
            "min_height": study.min_screen_height}


def _device_check(request: HttpRequest, study: Study, participant: Participant) -> HttpResponse:
    """The browser played the clip; its screen is as large as the study asks."""
    try:
        width, height = int(request.POST.get("width", "")), int(request.POST.get("height", ""))
    except ValueError:
        raise RatingRejected("the device check needs the screen's width and height in whole pixels") from None
    if width < study.min_screen_width or height < study.min_screen_height:
        raise RatingRejected(f"this study needs a screen at least {study.min_screen_width} × "
                             f"{study.min_screen_height} pixels, and this one is {width} × {height}: please open "
                             f"the link on a larger screen (or turn your device)", status=409)
    return _passing("device_checked_at")(request, study, participant)


def questions_page(part: str) -> PageContext:
    def page(study: Study, participant: Participant) -> dict:
        asked = questions(study, part)
        return {"questions": [(question, field_name(question)) for question in asked],
                "action": "participant-screening" if part == Question.Part.BEFORE else "participant-survey",
                "heading": "A few questions first" if part == Question.Part.BEFORE else "A few questions to finish"}
    return page


def _screening(request: HttpRequest, study: Study, participant: Participant) -> HttpResponse:
    """Answers before the ratings: an answer a screening question does not accept ends the
    study there, and the participant's clips go back to the others."""
    asked = questions(study, Question.Part.BEFORE)
    answers = read_answers(asked, request.POST)
    now = timezone.now()
    participant.answers = {**participant.answers, **answers}
    participant.screened_at = now
    fields = ["answers", "screened_at"]
    if screened_out(asked, answers):
        participant.screened_out_at = now
        fields.append("screened_out_at")
        participant.assignments.filter(rating__isnull=True).delete()  # reservations, not data
    participant.save(update_fields=fields)
    return _next_page(study)


def _survey(request: HttpRequest, study: Study, participant: Participant) -> HttpResponse:
    """Answers after the ratings."""
    participant.answers = {**participant.answers, **read_answers(questions(study, Question.Part.AFTER), request.POST)}
    participant.surveyed_at = timezone.now()
    participant.save(update_fields=["answers", "surveyed_at"])
    return _next_page(study)


def _screened_out_page(study: Study, participant: Participant) -> dict:
    """The end for a participant a screening answer turned away: the study's screen-out
    code where it has one (Prolific pays it at its fixed screen-out rate), else a request
    to return the study."""
    ending = "Thank you for your answers. This study is looking for participants with other answers, so it ends here for you."
    if not study.screen_out_code:
        return {"heading": "Thank you", "text": f"{ending} Please return it on your platform (do not submit it), so "
                                                "that your place goes to someone else."}
    return {"heading": "Thank you", "text": f"{ending} The code below tells {study.get_platform_display()} that you "
                                            "were screened out, so that you are paid for your time.",
            **_leaving_with(study, participant, study.screen_out_code)}


def clip_page(study: Study, stimulus: Stimulus, action: str, form: dict, heading: str, done: int,
              total: int, upcoming: Stimulus | None, instruction: str = "") -> dict:
    """A clip and its rating form; ``upcoming``, the next clip, which the browser fetches meanwhile."""
    return {
        "video_url": stimulus.video_url, "seconds": stimulus.duration_s or 0.0, "action": action, "form": form,
        "heading": heading, "next_video_url": upcoming.video_url if upcoming else "",
        "scale": list(study.scale), "keys": len(study.scale) <= 10, "done": done, "total": total,
        "percent": round(100 * done / total) if total else 100, "instruction": instruction,
        # Practice of the multi-clip designs is to watch the range of motion, not to answer.
        "watch_only": action == "participant-practice" and study.design != Study.Design.SINGLE,
    }


def _practice_page(study: Study, participant: Participant) -> dict:
    index = participant.training_done
    ids = participant.training[index:index + 2]
    stimuli = Stimulus.objects.in_bulk(ids)  # this clip and the next practice clip, in one query
    if ids[0] not in stimuli:
        raise Http404("practice clip gone")
    return clip_page(study, stimuli[ids[0]], "participant-practice", {"index": index},
                      f"Practice clip {index + 1} of {len(participant.training)} (not recorded)",
                      index, len(participant.training), stimuli.get(ids[1]) if len(ids) > 1 else None)


def _practice(request: HttpRequest, study: Study, participant: Participant) -> HttpResponse:
    """Move past a practice clip; its answer is not recorded."""
    if request.POST.get("index") == str(participant.training_done):  # a resubmitted form moves nothing
        Participant.objects.filter(pk=participant.pk, training_done=participant.training_done).update(
            training_done=participant.training_done + 1)
    return _next_page(study)


def _rating_page(study: Study, participant: Participant) -> dict:
    # Every clip of the participant in one query: the first unrated one is on screen, the
    # next is fetched while it plays, and all of them make the progress.
    clips = list(participant.assignments.order_by("position").values(
        "pk", "token", "shown_at", "expected", "rating", "stimulus__token", "stimulus__duration_s"))
    unrated = [clip for clip in clips if clip["rating"] is None]
    clip, upcoming = unrated[0], unrated[1:2]
    if clip["shown_at"] is None:  # the first clip, or one after a return: recording a rating marks the next
        Assignment.objects.filter(pk=clip["pk"]).update(shown_at=timezone.now())
    total, done = len(clips), len(clips) - len(unrated)
    return clip_page(study, _stimulus(clip), "participant-rate", {"assignment": clip["token"]},
                     f"Clip {done + 1} of {total}", done, total, _stimulus(upcoming[0]) if upcoming else None,
                     instruction(study, [clip["expected"]]))


def _stimulus(clip: dict) -> Stimulus:
    """The stimulus of a clip read with its assignment, as far as its page needs it (address and length)."""
    return Stimulus(token=clip["stimulus__token"], duration_s=clip["stimulus__duration_s"])


def _rate(request: HttpRequest, study: Study, participant: Participant) -> HttpResponse:
    """Store the rating of the clip on screen."""
    token = request.POST.get("assignment", "")
    if is_idle(participant, timezone.now()):  # away so long that the clip may have gone to another
        was_reserved = participant.assignments.filter(token=token, rating__isnull=True).exists()
        participant = renew_reservations(participant)
        if was_reserved and not participant.assignments.filter(token=token).exists():
            raise RatingRejected("that clip was given to another participant while this page was idle; "
                                 "please reload the page to go on with the next one", status=409)
    text = request.POST.get("value", "")
    try:
        value = int(text)
    except ValueError:
        raise RatingRejected(f"the rating must be a whole number from {study.scale_min} to {study.scale_max}, "
                             f"not {text[:20]!r}") from None
    record_rating(participant, token, value, client_times(request))  # after the last clip, it says why not
    return _next_page(study)


def mturk_submit_url(platform_data: dict) -> str | None:
    """MTurk's external-submit URL from the link's turkSubmitTo, if that is MTurk's own site."""
    submit_to = platform_data.get("turkSubmitTo", "")
    parsed = urlparse(submit_to)
    if parsed.scheme == "https" and parsed.hostname in MTURK_SUBMIT_HOSTS:
        return f"{submit_to.rstrip('/')}/mturk/externalSubmit"
    return None


def completion_page(study: Study, participant: Participant) -> dict:
    """Where a finished participant goes and what code they are given."""
    return _leaving_with(study, participant, study.completion_code, study.redirect_url)


def _leaving_with(study: Study, participant: Participant, code: str, target: str = "") -> dict:
    """The page context that hands the participant ``code`` and sends them back to their
    platform: ``target``, else Prolific's completion URL with the code, or MTurk's submit form."""
    mturk_submit = None
    if study.platform == Study.Platform.PROLIFIC and code and not target:
        target = f"{PROLIFIC_COMPLETION_URL}?{urlencode({'cc': code})}"
    if study.platform == Study.Platform.MTURK and (url := mturk_submit_url(participant.platform_data)):
        mturk_submit = {"url": url, "assignment_id": participant.platform_data.get("assignmentId", "")}
    return {"code": code, "redirect_url": target, "mturk_submit": mturk_submit}


def _stopped_page(study: Study, participant: Participant) -> dict:
    """The polite end of a session stopped by failed instructed checks: the study's code
    for those it stopped where it has one, else a request to return the study."""
    ending = ("Thank you for your time. Some answers did not follow the instructions shown on the page, so this "
              "session has ended here.")
    if not study.stopped_code:
        return {"heading": "Thank you", "text": f"{ending} Please return the study on your platform."}
    return {"heading": "Thank you", "text": f"{ending} Please hand in the code below on "
                                            f"{study.get_platform_display()}.",
            **_leaving_with(study, participant, study.stopped_code)}


PATH: tuple[Step, ...] = (
    Step("screened-out", "done.html", pending=lambda p: p.screened_out_at is not None, page=_screened_out_page),
    Step("device", "device.html", pending=lambda p: p.study.device_check and p.device_checked_at is None,
         page=_device_page, submit=_device_check),
    Step("consent", "consent.html", pending=lambda p: p.consented_at is None, submit=_consent),
    Step("screening", "questions.html", pending=lambda p: p.screened_at is None,
         page=questions_page(Question.Part.BEFORE), submit=_screening),
    Step("instructions", "instructions.html", pending=lambda p: p.instructed_at is None,
         submit=_passing("instructed_at")),
    Step("practice", "clip.html", pending=lambda p: p.training_done < len(p.training), page=_practice_page,
         submit=_practice),
    Step("rate", "clip.html", pending=lambda p: p.finished_at is None, page=_rating_page, submit=_rate,
         takes_late_posts=True, design=Study.Design.SINGLE),
    Step("rate-page", "side_by_side.html", pending=lambda p: p.finished_at is None, page=page_context,
         submit=rate_side_by_side, takes_late_posts=True, design=Study.Design.SIDE_BY_SIDE),
    Step("compare", "pairwise.html", pending=lambda p: p.finished_at is None, page=page_context,
         submit=rate_pairwise, takes_late_posts=True, design=Study.Design.PAIRWISE),
    Step("stopped", "done.html", pending=lambda p: p.stopped_at is not None, page=_stopped_page),
    # Asked only once the ratings are done, so the query costs the rating pages nothing.
    Step("survey", "questions.html",
         pending=lambda p: p.surveyed_at is None and p.study.questions.filter(part=Question.Part.AFTER).exists(),
         page=questions_page(Question.Part.AFTER), submit=_survey),
    Step("done", "done.html", pending=lambda p: True, page=completion_page),
)


def _on_path(step: Step, participant: Participant) -> bool:
    return step.design is None or step.design == participant.study.design


def current_step(participant: Participant) -> Step:
    """The step the participant is on: the first one of their study's design not passed."""
    return next(step for step in PATH if _on_path(step, participant) and step.pending(participant))


def stage(participant: Participant) -> str:
    """The name of the step the participant is on."""
    return current_step(participant).name


def may_post(step: Step, participant: Participant) -> bool:
    """Whether ``step``'s form may be sent now: the participant is on it (or past it, where it takes late posts)."""
    if not _on_path(step, participant):
        return False
    current = PATH.index(current_step(participant))
    here = PATH.index(step)
    return current == here or (step.takes_late_posts and current > here)


__all__ = ["PATH", "Step", "clip_page", "completion_page", "current_step", "may_post", "message", "mturk_submit_url",
           "questions_page", "stage"]
