"""The platforms' link vocabulary: the query parameters each platform adds to a study's
entry link (the first one the participant's id, one the platform's session), and where
a finished participant is sent back to (Prolific's completion URL, MTurk's submit form)."""

from __future__ import annotations

from urllib.parse import urlparse

from django.http import HttpRequest
from django.urls import reverse

from studyapp.models import Study

# The query parameters each platform adds to the entry link; the first one is the id.
PLATFORM_PARAMETERS = {
    Study.Platform.PROLIFIC: ("PROLIFIC_PID", "STUDY_ID", "SESSION_ID"),
    Study.Platform.MTURK: ("workerId", "assignmentId", "hitId", "turkSubmitTo"),
    Study.Platform.LINK: ("pid",),
}
# The parameter naming the platform's session: a platform id continues in another browser
# only with the session it started in (elsewhere, only the browser's cookie continues it).
SESSION_PARAMETERS = {Study.Platform.PROLIFIC: "SESSION_ID", Study.Platform.MTURK: "assignmentId"}
PROLIFIC_COMPLETION_URL = "https://app.prolific.com/submissions/complete"
# Prolific fills these placeholders in a study URL; MTurk appends its own ids.
PROLIFIC_PLACEHOLDERS = "PROLIFIC_PID={{%PROLIFIC_PID%}}&STUDY_ID={{%STUDY_ID%}}&SESSION_ID={{%SESSION_ID%}}"
MTURK_SUBMIT_HOSTS = {"www.mturk.com", "workersandbox.mturk.com"}


def mturk_submit_url(platform_data: dict) -> str | None:
    """MTurk's external-submit URL from the link's turkSubmitTo, if that is MTurk's own site."""
    submit_to = platform_data.get("turkSubmitTo", "")
    parsed = urlparse(submit_to)
    if parsed.scheme == "https" and parsed.hostname in MTURK_SUBMIT_HOSTS:
        return f"{submit_to.rstrip('/')}/mturk/externalSubmit"
    return None


def entry_link(request: HttpRequest, study: Study) -> str:
    """The participants' entry link as the platform needs it."""
    base = request.build_absolute_uri(reverse("participant-enter", args=[study.key]))
    if study.platform == Study.Platform.PROLIFIC:
        return f"{base}?{PROLIFIC_PLACEHOLDERS}"
    if study.platform == Study.Platform.LINK:
        return f"{base}?{PLATFORM_PARAMETERS[Study.Platform.LINK][0]}=PARTICIPANT_ID"
    return base


__all__ = ["MTURK_SUBMIT_HOSTS", "PLATFORM_PARAMETERS", "PROLIFIC_COMPLETION_URL", "PROLIFIC_PLACEHOLDERS",
           "SESSION_PARAMETERS", "entry_link", "mturk_submit_url"]
