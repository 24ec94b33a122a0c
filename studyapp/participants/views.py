"""The participant's views: the entry link, the one page they are on, and each step's form.

The steps themselves (what each page shows, what its form does, in which order) are
declared in ``participants.path.PATH``; this module finds the participant of the browser's
cookie and guards each step with ``participant_access``. Each form posts to its step's
URL and redirects back to the one page URL (or, from the clip pages' script, answers
with the next page of clips itself: ``path.next_page``).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from functools import wraps

from django.conf import settings
from django.db import IntegrityError
from django.db.models import F
from django.http import Http404, HttpRequest, HttpResponse
from django.shortcuts import redirect
from django.urls import reverse
from django.utils.translation import gettext as _
from django.views.decorators.cache import never_cache
from django.views.decorators.http import require_POST, require_safe

from studyapp.models import Participant, StoredDataError, Study, json_object, new_token
from studyapp.participants.assignment import StudyFull, StudyNotReady, enrol
from studyapp.participants.language import in_study_language, participant_language, speak
from studyapp.participants.path import Step, current_page, may_post, message, stage
from studyapp.participants.refusal import AnswerRefused
from studyapp.participants.study_cache import current_study
from studyapp.platforms.links import PLATFORM_PARAMETERS, SESSION_PARAMETERS, mturk_submit_url
from studyapp.server.db.compiled_queries import CompiledQuery

# MTurk shows the study in an iframe of its own site; other platforms link to it, so
# their pages keep Django's X-Frame-Options: DENY.
MTURK_FRAME_ANCESTORS = "frame-ancestors https://*.mturk.com"
MAX_ID_LENGTH = 100

logger = logging.getLogger(__name__)

ParticipantView = Callable[[HttpRequest, Study, Participant], HttpResponse]


def _framed(study: Study, response: HttpResponse) -> HttpResponse:
    """Let MTurk frame the pages of MTurk studies (and no one else frame any study)."""
    if study.platform == Study.Platform.MTURK:
        response.xframe_options_exempt = True
        response["Content-Security-Policy"] = MTURK_FRAME_ANCESTORS
    return response


def _cookie(study_key: str) -> tuple[str, str]:
    """The name and the signing salt of the cookie naming this browser's participant of a study."""
    return f"participant-{study_key}", f"studyapp.participant:{study_key}"


def _participant_pk(request: HttpRequest, study_key: str) -> str | None:
    name, salt = _cookie(study_key)
    return request.get_signed_cookie(name, default=None, salt=salt, max_age=settings.SESSION_COOKIE_AGE)


def _remember(response: HttpResponse, participant: Participant) -> HttpResponse:
    """Name the participant in a signed cookie that only their study's pages receive. Not
    the session: reading it costs every page a query, and participants need nothing else
    from it."""
    name, salt = _cookie(participant.study.key)
    response.set_signed_cookie(name, str(participant.pk), salt=salt, max_age=settings.SESSION_COOKIE_AGE,
                               path=f"/p/{participant.study.key}/", secure=settings.SESSION_COOKIE_SECURE,
                               httponly=True, samesite=settings.SESSION_COOKIE_SAMESITE)
    return response


class StudyUnavailable(Exception):
    """No study at this address, or one closed to newcomers: a plain page says which."""

    def __init__(self, title: str, text: str, study: Study | None = None) -> None:
        super().__init__(text)
        self.title, self.text, self.study = title, text, study


def _study(key: str, must_be_open: bool = False) -> Study:
    """The study of an entry key. Only new participants need it open: closing a study
    lets those already taking part finish and get their completion code."""
    study = Study.objects.filter(key=key).first()
    if study is None:
        raise StudyUnavailable(_("No study here"), _("There is no study at this address. Please check the link your "
                                                    "platform gave you."))
    speak(study)
    if must_be_open and not study.is_open:
        raise StudyUnavailable(study.title, _("This study is closed and takes no new participants. Thank you for "
                                              "your interest; please return it on your platform."), study)
    return study


def plain_pages(view: Callable[..., HttpResponse]) -> Callable[..., HttpResponse]:
    """Whatever goes wrong, a participant gets a plain page of the study's own, never
    Django's error or debug pages: a missing study or page (404), a row of the study's
    that its code cannot read (503) or a server error (500, its traceback logged). Its pages
    are in the study's language from the moment the study is read (``language``), and so are the
    refusals made before the view runs (``in_study_language``)."""
    @in_study_language
    @wraps(view)
    def shielded(request: HttpRequest, *args, **kwargs) -> HttpResponse:
        with participant_language():
            return _shielded(view, request, *args, **kwargs)
    return shielded


def _shielded(view: Callable[..., HttpResponse], request: HttpRequest, *args, **kwargs) -> HttpResponse:
    try:
        return view(request, *args, **kwargs)
    except StudyUnavailable as unavailable:
        response = message(request, unavailable.title, unavailable.text, 404)
        return _framed(unavailable.study, response) if unavailable.study else response
    except Http404:
        return message(request, _("Page not found"), _("There is no such page in this study. Please go back to "
                                                       "the link your platform gave you."), 404)
    except StoredDataError:  # the researcher's row, not the participant's doing: they may come back later
        logger.exception("participant page %s met a broken row", request.path)
        return message(request, _("Not available just now"), _("This study cannot go on at the moment. Your "
                       "answers so far are saved: please try again later, or contact the researcher."), 503)
    except Exception:
        logger.exception("participant page %s failed", request.path)
        return message(request, _("Something went wrong"), _("The server could not show this page. Please try "
                       "again in a moment: your answers so far are saved."), 500)


_participant_in_study = CompiledQuery(
    lambda pk, key: Participant.objects.annotate(study_updated=F("study__updated")).filter(pk=pk, study__key=key),
    int, str)


def _participant(request: HttpRequest, key: str) -> tuple[Study, Participant | None]:
    """The study of an entry key (StudyUnavailable if none) and this browser's participant in it, if
    any: one query for both when there is one, as on every page of the path (the study
    itself from this process's memory while unchanged)."""
    pk = _participant_pk(request, key)
    rows = _participant_in_study(int(pk), key) if pk and pk.isdigit() else []
    if not rows:
        return _study(key), None
    found = rows[0]
    found.study = speak(current_study(found.study_id, found.study_updated))
    return found.study, found


def participant_access(step: Step | None = None) -> Callable[[ParticipantView], Callable[..., HttpResponse]]:
    """Decorate a view of this browser's participant (its cookie); it is called with
    (request, study, participant). Without a participant: 403. With ``step``: only while
    the participant may send that step's form (409 otherwise), and a step that refuses
    (AnswerRefused) answers with its 4xx and a message, having changed nothing."""
    def decorate(view: ParticipantView) -> Callable[..., HttpResponse]:
        @wraps(view)
        def guarded(request: HttpRequest, key: str) -> HttpResponse:
            study, participant = _participant(request, key)
            if participant is None:
                return _framed(study, message(request, study.title, _("Please open the study through the link "
                                                                      "your platform gave you."), 403))
            if step is None:
                return _framed(study, view(request, study, participant))
            try:
                if not may_post(step, participant):
                    raise AnswerRefused(_("this step is not the current one (expected %(step)s, at %(stage)s)")
                                        % {"step": step.name, "stage": stage(participant)}, status=409)
                response = view(request, study, participant)
            except AnswerRefused as rejection:
                response = message(request, _("That did not work"), str(rejection),
                                   rejection.status, back=reverse("participant-page", args=[key]))
            return _framed(study, response)
        return guarded
    return decorate


@never_cache
@plain_pages
@require_safe
def enter(request: HttpRequest, key: str) -> HttpResponse:
    """The entry link: find or create the participant of this platform id, then go to their page."""
    study = _study(key, must_be_open=True)
    return _framed(study, _enrolled(request, study))


def _enrolled(request: HttpRequest, study: Study) -> HttpResponse:
    key = study.key
    names = PLATFORM_PARAMETERS[study.platform]
    data = {name: request.GET[name] for name in names if request.GET.get(name)}
    # Refused rather than cut: two ids that differ only past the limit would become one participant.
    if too_long := [name for name, value in data.items() if len(value) > MAX_ID_LENGTH]:
        return message(request, _("Link not valid"), _(
            "The link's %(name)s is longer than %(limit)s characters, longer than any platform gives. Please open "
            "the study from the platform again.") % {"name": too_long[0], "limit": MAX_ID_LENGTH}, 400)
    if study.platform == Study.Platform.MTURK and data.get("assignmentId") == "ASSIGNMENT_ID_NOT_AVAILABLE":
        return message(request, study.title, _("This is a preview. Accept the task to take part."))
    if study.platform == Study.Platform.MTURK and mturk_submit_url(data) is None:
        return message(request, _("Link incomplete"), _("The link lacks MTurk's submit address (turkSubmitTo). "
                                                        "Please open the task from MTurk again."), 400)
    platform_id = data.get(names[0])
    pk = _participant_pk(request, key)
    existing = Participant.objects.filter(pk=pk, study=study).first() if pk else None
    if existing and (platform_id is None or existing.platform_id == platform_id):
        return redirect("participant-page", key=key)
    if platform_id is None:
        if study.platform != Study.Platform.LINK:
            return message(request, _("Link incomplete"), _(
                "The link lacks the %(name)s parameter that %(platform)s adds. Please open the study from the "
                "platform again.") % {"name": names[0], "platform": study.get_platform_display()}, 400)
        platform_id = f"anonymous-{new_token()}"
    participant = Participant.objects.filter(study=study, platform_id=platform_id).first()
    if participant is None:
        try:
            participant = enrol(study, platform_id, data, request.META.get("HTTP_USER_AGENT", ""))
        except StudyFull:
            return message(request, _("The study is full"), _("Thank you for your interest: every clip has "
                           "received the ratings it needs. Please return the study on your platform."), ending="full")
        except StudyNotReady:
            return message(request, _("Not ready yet"), _("This study has no clips yet. Please try again later."), 503)
        except IntegrityError:  # the same id arriving at once elsewhere enrolled it: its session decides, as below
            participant = Participant.objects.get(study=study, platform_id=platform_id)
        else:
            return _remember(redirect("participant-page", key=key), participant)
    if not _same_session(study, participant, data):
        return message(request, _("Already started elsewhere"), _("This id has already started the study in "
                       "another browser or platform session. Please go on where you started it."), 409)
    participant.study = study
    return _remember(redirect("participant-page", key=key), participant)


def _same_session(study: Study, participant: Participant, data: dict) -> bool:
    """Whether the link continues the platform session ``participant`` started in (the
    link this browser has no cookie for: without a session parameter, nothing continues)."""
    name = SESSION_PARAMETERS.get(study.platform)
    stored = json_object(participant, "platform_data")
    return bool(name and stored.get(name) and stored[name] == data.get(name))


def step_form(step: Step) -> Callable[..., HttpResponse]:
    """The view that takes ``step``'s form (POST only); its response may be a page (``path.next_page``)."""
    return never_cache(plain_pages(require_POST(participant_access(step)(step.submit))))


@never_cache
@plain_pages
@require_safe
@participant_access()
def page(request: HttpRequest, study: Study, participant: Participant) -> HttpResponse:
    """Whatever page the participant is on."""
    return current_page(request, study, participant)


@never_cache
@plain_pages
def unknown_page(request: HttpRequest, key: str, rest: str) -> HttpResponse:
    """Any other address under a study's pages (said in the study's language)."""
    _study(key)
    raise Http404(rest)


def csrf_failure(request: HttpRequest, reason: str = "") -> HttpResponse:
    """A form sent without its CSRF token (a page kept open past its cookie, cookies
    blocked): a plain page that leads back, never Django's explanation of CSRF; a
    participant's in their study's language."""
    key = request.resolver_match.kwargs.get("key") if request.resolver_match else None
    participant_page = bool(key and request.path.startswith("/p/"))
    back = reverse("participant-page", args=[key]) if participant_page else ""
    with participant_language():
        if participant_page and (study := Study.objects.filter(key=key).first()):
            speak(study)
        return message(request, _("Please try again"), _("This page had expired, so your answer was not sent. Go "
                       "back to the study and answer again (if this keeps happening, allow cookies for this site)."),
                       403, back=back)
