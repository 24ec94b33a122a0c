"""The participant's path through a study, declared once: ``PATH``, its steps in order.

    entry link -> (device check) -> consent -> (screening questions) -> instructions
      -> practice pages -> the study's pages -> (closing questions) -> completion

The practice and rating pages are the study's design's (``designs``): one clip each
(single), every system's clip of one control on sliders (side-by-side), or two clips to
choose between (pairwise). A participant who fails too many instructed checks leaves the
path with a polite ending.

Each ``Step`` says when the participant is on it (``pending``: the first pending
step is theirs, so a reload or a return on another day shows the page they left), what
its page shows (a template and its context), what its form does (``submit``, which
redirects to the one page URL, or answers with the next page itself, see ``next_page``;
the last step has no form) and what the researcher's
preview shows of it (``preview``; by default its page, where a new participant meets
it). ``stage()`` reads the table, ``participants.views`` renders and guards the steps
through it, ``urls`` gives each form its URL, /p/KEY/<step name>/, and
``researchers.setup.preview`` walks it. A new page type (a questionnaire) is one entry here
and one template.

The design's pages of clips (practice and rating) are answered with one request: their
script sends the form with ``NEXT_PAGE_HEADER``, and where the next page is another page
of clips the answer's response is that page, rendered as the one page URL renders it
(``current_page``), which the script swaps in; any other next page (the questions, the
end, a session stopped by failed checks) is the redirect, which the script follows. The
form without the script posts and is redirected as any other.

Nothing on these pages names a system: clips are served by random tokens and the rating
form names its page by another.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from urllib.parse import urlencode

from django.http import HttpRequest, HttpResponse
from django.shortcuts import redirect, render
from django.utils import timezone

from studyapp.designs.answers import record_answer
from studyapp.designs.pages import (practice_page, preview_practice_pages, preview_rating_pages,
                                    rating_page, remaining_practice)
from studyapp.designs.registry import design_of
from studyapp.models import Participant, Question, Study, json_object
from studyapp.participants.assignment import is_idle, renew_reservations
from studyapp.participants.device_clip import device_clip_url
from studyapp.participants.questionnaires import field_name, questions, read_answers, screened_out
from studyapp.participants.refusal import AnswerRefused
from studyapp.platforms.links import PROLIFIC_COMPLETION_URL, mturk_submit_url

# Sent by the clip pages' script (static/studyapp/next-page.js) with an answer: "in-place"
# asks for the next page in the response where it is another page of clips.
NEXT_PAGE_HEADER = "Studyapp-Next-Page"

PageContext = Callable[[Study, Participant], dict]
Submit = Callable[[HttpRequest, Study, Participant], HttpResponse]


@dataclass(frozen=True)
class Step:
    """One page of the path; its form posts to /p/KEY/<name>/ (URL name ``participant-<name>``)."""

    name: str
    # Under studyapp/templates/studyapp/participant/; or the study's design's, for its pages.
    template: str | Callable[[Study], str]
    pending: Callable[[Participant], bool]  # not passed yet
    page: PageContext = lambda study, participant: {}
    submit: Submit | None = None
    # Its form is still passed to ``submit`` once the participant has gone past the step,
    # so that submit can say why it refuses (a rating sent again after the last clip).
    takes_late_posts: bool = False
    # Its page is the design's page of clips, which may come in place of the page before
    # it without a reload (``next_page``).
    in_place: bool = False
    title: str = ""  # what the preview calls it (default: its name)
    # The pages the researcher's preview shows of it (contexts, none where a new
    # participant would not meet it); None: its page, where a new participant is on it.
    preview: Callable[[Study], list[dict]] | None = None

    def template_for(self, study: Study) -> str:
        return self.template(study) if callable(self.template) else self.template

    def preview_pages(self, study: Study) -> list[dict]:
        if self.preview is not None:
            return self.preview(study)
        nobody = Participant(study=study)  # unsaved: no one is enrolled, nothing is reserved
        return [self.page(study, nobody)] if self.pending(nobody) else []


def message(request: HttpRequest, title: str, text: str, status: int = 200, back: str = "") -> HttpResponse:
    """A page with a title and one notice, and no form; ``back``, a link to the page to go on from."""
    return render(request, "studyapp/participant/message.html", {"title": title, "text": text, "back": back},
                  status=status)


def current_page(request: HttpRequest, study: Study, participant: Participant, in_place: bool = False) -> HttpResponse:
    """The page the participant is on: its step's template and context (a rating page is
    marked shown as it is rendered, ``designs.pages``); ``in_place``, only what the clip
    pages' script swaps in (a page of clips: ``in_place.html`` instead of ``base.html``)."""
    participant = renew_reservations(participant)
    step = current_step(participant)
    context = {"study": study, **step.page(study, participant)}
    if in_place:
        context["frame"] = "studyapp/participant/in_place.html"
    # Names this page among the participant's, so that another tab still on an earlier one moves on.
    context["page_id"] = "-".join([step.name, *map(str, context.get("form", {}).values())])
    return render(request, f"studyapp/participant/{step.template_for(study)}", context)


def next_page(request: HttpRequest, study: Study, participant: Participant) -> HttpResponse:
    """Where a form leads once it is taken: the redirect to the one page URL; or, asked by
    the clip pages' script, the participant's next page itself where it is a page of clips
    (``participant``: as the form left it, in memory)."""
    if request.headers.get(NEXT_PAGE_HEADER) == "in-place" and current_step(participant).in_place:
        return current_page(request, study, participant, in_place=True)
    return redirect("participant-page", key=study.key)


def _passing(moment: str) -> Submit:
    """A submit that records when the participant passed the step (``moment`` is its timestamp field)."""
    def submit(request: HttpRequest, study: Study, participant: Participant) -> HttpResponse:
        setattr(participant, moment, timezone.now())
        participant.save(update_fields=[moment])
        return next_page(request, study, participant)
    return submit


def _consent(request: HttpRequest, study: Study, participant: Participant) -> HttpResponse:
    """Agree (or not) to take part; a study without screening questions passes that step too."""
    if request.POST.get("agree") != "yes":
        return message(request, "Thank you", "You chose not to take part. Please return the study on your platform.")
    participant.consented_at = timezone.now()
    if not study.questions.filter(part=Question.Part.BEFORE).exists():
        participant.screened_at = participant.consented_at
    participant.save(update_fields=["consented_at", "screened_at"])
    return next_page(request, study, participant)


def screen_need(study: Study) -> str:
    """The screen size the study's device check asks for, naming only the sides it sets."""
    width, height = study.min_screen_width, study.min_screen_height
    if width and height:
        return f"at least {width} × {height} pixels"
    return f"at least {width} pixels wide" if width else f"at least {height} pixels high"


def _device_context(study: Study) -> dict:
    """The device check plays a neutral clip (``device_clip``), no study's stimulus: it comes before consent."""
    return {"video_url": device_clip_url(), "min_width": study.min_screen_width, "min_height": study.min_screen_height,
            "screen_need": screen_need(study)}


def _device_page(study: Study, participant: Participant) -> dict:
    return _device_context(study)


def _device_preview(study: Study) -> list[dict]:
    return [_device_context(study)] if study.device_check else []


def _device_check(request: HttpRequest, study: Study, participant: Participant) -> HttpResponse:
    """The browser played the clip; its screen is as large as the study asks."""
    try:
        width, height = int(request.POST.get("width", "")), int(request.POST.get("height", ""))
    except ValueError:
        raise AnswerRefused("the device check needs the screen's width and height in whole pixels") from None
    if width < study.min_screen_width or height < study.min_screen_height:
        raise AnswerRefused(f"this study needs a screen {screen_need(study)}, and this one is {width} × {height}: "
                             f"please open the link on a larger screen (or turn your device)", status=409)
    return _passing("device_checked_at")(request, study, participant)


def _instructions_page(study: Study, participant: Participant) -> dict:
    """What each page of the study's design will ask, and whether practice comes first:
    the participant's own practice clips, which a study asking for practice may not have
    (no finished clip to practise on when they enrolled)."""
    return {"task": design_of(study).task(study), "practice": participant.training_done < len(participant.training)}


def _instructions_preview(study: Study) -> list[dict]:
    """The instructions as a participant enrolled now reads them (practice where the study's plan has it)."""
    return [{"task": design_of(study).task(study), "practice": bool(preview_practice_pages(study))}]


def _questions_preview(part: str) -> Callable[[Study], list[dict]]:
    """The questions' page in the preview, where the study asks any."""
    def preview(study: Study) -> list[dict]:
        return [questions_page(part)(study, Participant(study=study))] if questions(study, part) else []
    return preview


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
    participant.answers = {**json_object(participant, "answers"), **answers}
    participant.screened_at = now
    fields = ["answers", "screened_at"]
    if screened_out(asked, answers):
        participant.screened_out_at = now
        fields.append("screened_out_at")
        participant.assignments.filter(rating__isnull=True).delete()  # reservations, not data
    participant.save(update_fields=fields)
    return next_page(request, study, participant)


def _survey(request: HttpRequest, study: Study, participant: Participant) -> HttpResponse:
    """Answers after the ratings."""
    participant.answers = {**json_object(participant, "answers"),
                           **read_answers(questions(study, Question.Part.AFTER), request.POST)}
    participant.surveyed_at = timezone.now()
    participant.save(update_fields=["answers", "surveyed_at"])
    return next_page(request, study, participant)


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


def _practice(request: HttpRequest, study: Study, participant: Participant) -> HttpResponse:
    """Move past a practice page; its answer is not recorded."""
    if request.POST.get("index") == str(participant.training_done):  # a resubmitted form moves nothing
        passed = participant.training_done + len(remaining_practice(study, participant)[0])
        if Participant.objects.filter(pk=participant.pk, training_done=participant.training_done).update(
                training_done=passed):
            participant.training_done = passed
        else:  # moved on by a request racing this one
            participant.refresh_from_db(fields=["training_done"])
    return next_page(request, study, participant)


def _rate(request: HttpRequest, study: Study, participant: Participant) -> HttpResponse:
    """Store the answer to the page on screen, as the study's design reads it."""
    answer = design_of(study).read_answer(study, request.POST)
    if is_idle(participant, timezone.now()):  # away so long that the page may have gone to another
        was_reserved = participant.assignments.filter(token=answer.page, rating__isnull=True).exists()
        participant = renew_reservations(participant)
        if was_reserved and not participant.assignments.filter(token=answer.page).exists():
            raise AnswerRefused("that page was given to another participant while it was idle; "
                                "please reload the page to go on with the next one", status=409)
    record_answer(participant, answer)  # after the last page, it says why not; updates ``participant``
    return next_page(request, study, participant)


def completion_page(study: Study, participant: Participant) -> dict:
    """Where a finished participant goes and what code they are given."""
    return _leaving_with(study, participant, study.completion_code, study.redirect_url)


def _leaving_with(study: Study, participant: Participant, code: str, target: str = "") -> dict:
    """The page context that hands the participant ``code`` and sends them back to their
    platform: ``target``, else Prolific's completion URL with the code, or MTurk's submit form."""
    mturk_submit = None
    if study.platform == Study.Platform.PROLIFIC and code and not target:
        target = f"{PROLIFIC_COMPLETION_URL}?{urlencode({'cc': code})}"
    platform_data = json_object(participant, "platform_data") if study.platform == Study.Platform.MTURK else {}
    if url := mturk_submit_url(platform_data):
        mturk_submit = {"url": url, "assignment_id": platform_data.get("assignmentId", "")}
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


def _design_template(study: Study) -> str:
    return design_of(study).template


PATH: tuple[Step, ...] = (
    Step("screened-out", "done.html", pending=lambda p: p.screened_out_at is not None, page=_screened_out_page),
    Step("device", "device.html", pending=lambda p: p.study.device_check and p.device_checked_at is None,
         page=_device_page, submit=_device_check, title="device check", preview=_device_preview),
    Step("consent", "consent.html", pending=lambda p: p.consented_at is None, submit=_consent),
    Step("screening", "questions.html", pending=lambda p: p.screened_at is None,
         page=questions_page(Question.Part.BEFORE), submit=_screening, preview=_questions_preview(Question.Part.BEFORE)),
    Step("instructions", "instructions.html", pending=lambda p: p.instructed_at is None,
         page=_instructions_page, submit=_passing("instructed_at"), preview=_instructions_preview),
    Step("practice", _design_template, pending=lambda p: p.training_done < len(p.training), page=practice_page,
         submit=_practice, in_place=True, preview=preview_practice_pages),
    Step("rate", _design_template, pending=lambda p: p.finished_at is None, page=rating_page, submit=_rate,
         takes_late_posts=True, in_place=True, title="a page to rate", preview=preview_rating_pages),
    Step("stopped", "done.html", pending=lambda p: p.stopped_at is not None, page=_stopped_page),
    # Asked only once the ratings are done, so the query costs the rating pages nothing.
    Step("survey", "questions.html",
         pending=lambda p: p.surveyed_at is None and p.study.questions.filter(part=Question.Part.AFTER).exists(),
         page=questions_page(Question.Part.AFTER), submit=_survey, title="closing questions"),
    Step("done", "done.html", pending=lambda p: True, page=completion_page, title="completion"),
)


def current_step(participant: Participant) -> Step:
    """The step the participant is on: the first one not passed."""
    return next(step for step in PATH if step.pending(participant))


def stage(participant: Participant) -> str:
    """The name of the step the participant is on."""
    return current_step(participant).name


def may_post(step: Step, participant: Participant) -> bool:
    """Whether ``step``'s form may be sent now: the participant is on it (or past it, where it takes late posts)."""
    current = PATH.index(current_step(participant))
    here = PATH.index(step)
    return current == here or (step.takes_late_posts and current > here)


__all__ = ["NEXT_PAGE_HEADER", "PATH", "Step", "completion_page", "current_page", "current_step", "may_post",
           "message", "next_page", "questions_page", "stage"]
