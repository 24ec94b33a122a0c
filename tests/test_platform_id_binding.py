"""One participant per platform id, whatever the race: a platform id that enters from
several browsers at once continues only in the platform session it was enrolled with
(Prolific's SESSION_ID, MTurk's assignmentId), and an id is never cut to fit, so two ids
never become one participant.

The simultaneous entries go over HTTP to a live server on a real database; a barrier
holds every request after its look-up of the id (which finds no one) until all have made
it, so that each of them tries to enrol the id, as when they arrive in the same moment.
"""

from __future__ import annotations

import http.client
import threading
from concurrent.futures import ThreadPoolExecutor
from urllib.parse import urlencode, urlparse

import pytest
from django.test import Client
from django.urls import reverse

from studyapp.models import Participant, Study
from studyapp.participants import views
from studyapp.participants.views import MAX_ID_LENGTH
from tests.study_fixtures import make_study

BROWSERS = 8
MTURK_SUBMIT = "https://workersandbox.mturk.com"


def entry_link(platform: str, platform_id: str, session: str) -> dict[str, str]:
    if platform == Study.Platform.PROLIFIC:
        return {"PROLIFIC_PID": platform_id, "STUDY_ID": "S1", "SESSION_ID": session}
    return {"workerId": platform_id, "assignmentId": session, "hitId": "H1", "turkSubmitTo": MTURK_SUBMIT}


def enter_at_once(monkeypatch, live_url: str, study: Study, links: list[dict[str, str]]) -> list[tuple[int, bool]]:
    """Each link entered by a browser of its own, all at once: (status, whether a participant cookie came back)."""
    barrier = threading.Barrier(len(links), timeout=20)
    enrol = views.enrol

    def enrol_when_all_have_looked(*args, **kwargs):
        barrier.wait()
        return enrol(*args, **kwargs)

    monkeypatch.setattr(views, "enrol", enrol_when_all_have_looked)
    address = urlparse(live_url)

    def enter(link: dict[str, str]) -> tuple[int, bool]:
        connection = http.client.HTTPConnection(address.hostname, address.port, timeout=60)
        try:
            connection.request("GET", f"{reverse('participant-enter', args=[study.key])}?{urlencode(link)}")
            response = connection.getresponse()
            response.read()
            cookies = response.headers.get_all("Set-Cookie") or []
            return response.status, any(cookie.startswith(f"participant-{study.key}=") for cookie in cookies)
        finally:
            connection.close()

    with ThreadPoolExecutor(max_workers=len(links)) as pool:
        return list(pool.map(enter, links))


@pytest.mark.slow
@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("platform", [Study.Platform.PROLIFIC, Study.Platform.MTURK])
def test_one_platform_id_entering_from_eight_sessions_at_once_gets_one_browser(monkeypatch, live_server, platform):
    study = make_study(platform=platform)
    links = [entry_link(platform, "P1", f"session-{n}") for n in range(BROWSERS)]
    outcomes = enter_at_once(monkeypatch, live_server.url, study, links)
    admitted = [status for status, cookie in outcomes if cookie]
    assert admitted == [302], outcomes
    assert sorted(status for status, _ in outcomes) == [302] + [409] * (BROWSERS - 1)
    participant = Participant.objects.get(study=study)
    winner = next(link for link, (_, cookie) in zip(links, outcomes) if cookie)
    assert participant.platform_data == winner  # the session it continues in is the one that got in


@pytest.mark.slow
@pytest.mark.django_db(transaction=True)
def test_one_platform_session_entering_from_eight_browsers_at_once_continues_in_each(monkeypatch, live_server):
    study = make_study(platform=Study.Platform.PROLIFIC)
    outcomes = enter_at_once(monkeypatch, live_server.url, study,
                             [entry_link(Study.Platform.PROLIFIC, "P1", "session-0")] * BROWSERS)
    assert outcomes == [(302, True)] * BROWSERS
    assert Participant.objects.filter(study=study).count() == 1


@pytest.mark.django_db
@pytest.mark.parametrize("platform, parameter", [(Study.Platform.PROLIFIC, "PROLIFIC_PID"),
                                                 (Study.Platform.PROLIFIC, "SESSION_ID"),
                                                 (Study.Platform.MTURK, "workerId"),
                                                 (Study.Platform.MTURK, "assignmentId")])
def test_two_ids_that_differ_only_past_the_longest_id_are_refused_not_cut_into_one(platform, parameter):
    study = make_study(platform=platform)
    common = "x" * MAX_ID_LENGTH
    for last in "ab":
        link = {**entry_link(platform, "P1", "session-0"), parameter: common + last}
        response = Client().get(reverse("participant-enter", args=[study.key]), link)
        page = response.content.decode()
        assert response.status_code == 400 and f"The link&#x27;s {parameter} is longer than 100 characters" in page
    assert not Participant.objects.exists()
    at_the_limit = Client().get(reverse("participant-enter", args=[study.key]),
                                {**entry_link(platform, "P1", "session-0"), parameter: common})
    assert at_the_limit.status_code == 302 and Participant.objects.count() == 1
