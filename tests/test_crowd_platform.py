"""What a crowd platform needs: a study opens only when participants can be paid, a
platform id continues only in its own session, and the researcher's participant list."""

from __future__ import annotations

import csv
import io
from datetime import timedelta

import pytest
from django.contrib.auth.models import User
from django.test import Client
from django.urls import reverse
from django.utils import timezone

from studyapp.models import Assignment, Participant, Rating, Stimulus, Study, System
from studyapp.researchers.crowd.participant_list import participant_rows, spreadsheet_safe
from tests.study_fixtures import make_study

pytestmark = pytest.mark.django_db


def open_it(client: Client, study: Study):
    response = client.post(reverse("study-open", args=[study.pk]), {"open": "1"}, follow=True)
    study.refresh_from_db()
    return response.content.decode()


@pytest.mark.parametrize("platform, fields, https, reason", [
    (Study.Platform.PROLIFIC, {"completion_code": "", "redirect_url": ""}, False, "set the completion code"),
    (Study.Platform.MTURK, {}, False, "HTTPS=1"),
    (Study.Platform.LINK, {}, False, "no finished clip to rate"),
])
def test_a_study_opens_only_with_what_its_platform_needs_and_clips(settings, platform, fields, https, reason):
    settings.HTTPS = https
    study = make_study(platform=platform, is_open=False, **fields)
    if platform == Study.Platform.LINK:  # only BAD clips are finished: nothing to rate
        Stimulus.objects.exclude(system__role=System.Role.BAD).update(status=Stimulus.Status.QUEUED)
    client = Client()
    client.force_login(study.owner)
    monitor = client.get(reverse("study-monitor", args=[study.pk])).content.decode()
    assert reason in monitor and 'disabled aria-describedby="open-problems"' in monitor
    assert reason in open_it(client, study) and not study.is_open


@pytest.mark.parametrize("platform, fields, https", [
    (Study.Platform.PROLIFIC, {"completion_code": "", "redirect_url": "https://app.prolific.com/x"}, False),
    (Study.Platform.PROLIFIC, {"completion_code": "C0DE"}, False),
    (Study.Platform.MTURK, {}, True),
    (Study.Platform.LINK, {"completion_code": ""}, False),
])
def test_a_study_with_clips_and_its_platforms_needs_opens(settings, platform, fields, https):
    settings.HTTPS = https
    study = make_study(platform=platform, is_open=False, **fields)
    client = Client()
    client.force_login(study.owner)
    assert "open-problems" not in client.get(reverse("study-monitor", args=[study.pk])).content.decode()
    assert "The study is open." in open_it(client, study) and study.is_open


def enter(client: Client, study: Study, **parameters):
    return client.get(reverse("participant-enter", args=[study.key]), parameters, follow=True)


def test_a_prolific_id_continues_only_in_its_own_session_or_browser():
    study = make_study(platform=Study.Platform.PROLIFIC)
    first = Client()
    assert enter(first, study, PROLIFIC_PID="P1", STUDY_ID="S", SESSION_ID="A").status_code == 200
    first.post(reverse("participant-consent", args=[study.key]), {"agree": "yes"})
    intruder = Client()
    response = enter(intruder, study, PROLIFIC_PID="P1", STUDY_ID="S", SESSION_ID="B")
    assert response.status_code == 409 and "Already started elsewhere" in response.content.decode()
    assert intruder.get(reverse("participant-page", args=[study.key])).status_code == 403  # no cookie was given
    assert enter(Client(), study, PROLIFIC_PID="P1", STUDY_ID="S").status_code == 409  # no session at all
    same_session = Client()  # the same Prolific session in another browser continues it
    page = enter(same_session, study, PROLIFIC_PID="P1", STUDY_ID="S", SESSION_ID="A").content.decode()
    assert "Instructions" in page
    assert enter(first, study, PROLIFIC_PID="P1", STUDY_ID="S", SESSION_ID="B").status_code == 200  # its cookie
    assert Participant.objects.count() == 1


def test_a_plain_link_id_continues_only_in_its_browser():
    study = make_study(platform=Study.Platform.LINK)
    assert enter(Client(), study, pid="someone").status_code == 200
    assert enter(Client(), study, pid="someone").status_code == 409


def test_an_mturk_worker_continues_only_in_their_assignment():
    study = make_study(platform=Study.Platform.MTURK)
    link = {"workerId": "W1", "hitId": "H", "turkSubmitTo": "https://www.mturk.com"}
    assert enter(Client(), study, assignmentId="A1", **link).status_code == 200
    assert enter(Client(), study, assignmentId="A1", **link).status_code == 200
    assert enter(Client(), study, assignmentId="A2", **link).status_code == 409


def finish(participant: Participant, values: list[tuple[str, int, bool]], minutes: float) -> None:
    """Store ``values`` as (system, rating, early) ratings and mark the participant finished."""
    now = timezone.now()
    for position, (system, value, early) in enumerate(values):
        stimulus = Stimulus.objects.get(study=participant.study, system__name=system, control__name="control-0")
        assignment = Assignment.objects.create(participant=participant, stimulus=stimulus, position=position,
                                               page=position)
        Rating.objects.create(assignment=assignment, value=value, answered_before_end=early)
    Participant.objects.filter(pk=participant.pk).update(started_at=now - timedelta(minutes=minutes), finished_at=now)


def test_the_participant_list_suggests_approvals_and_its_csv_is_safe_in_a_spreadsheet():
    study = make_study(platform=Study.Platform.PROLIFIC, reservation_minutes=10)
    create = Participant.objects.create
    good = create(study=study, platform_id="good", platform_data={"SESSION_ID": "s-good"})
    finish(good, [("MoGlow", 4, False), ("NAT", 5, True)], minutes=12.25)
    careless = create(study=study, platform_id="=HYPERLINK(\"http://x\")", platform_data={"SESSION_ID": "@s"},
                      excluded=True, exclusion_reason="rated a BAD clip high", refused_early=3)
    finish(careless, [("BAD", 5, False)], minutes=3)
    create(study=study, platform_id="going", platform_data={"SESSION_ID": "s-going"})
    idle = create(study=study, platform_id="gone", platform_data={"SESSION_ID": "s-gone"})
    Participant.objects.filter(pk=idle.pk).update(last_seen=timezone.now() - timedelta(minutes=11))

    rows = {row.platform_id: row for row in participant_rows(study)}
    assert (rows["good"].status, rows["good"].minutes_taken, rows["good"].ratings) == ("finished", 12.2, 2)
    assert (rows["good"].early_answers, rows["good"].suggested_action, rows["good"].session) == (1, "approve", "s-good")
    hostile = rows['=HYPERLINK("http://x")']
    # Excluded from the analysis for a quality judgement, which is no ground for refusing payment.
    assert (hostile.early_answers, hostile.suggested_action, hostile.exclusion_reason) == (
        3, "approve", "rated a BAD clip high")
    assert (rows["going"].status, rows["going"].suggested_action) == ("in progress", "")
    assert rows["gone"].status == "idle"

    client = Client()
    client.force_login(study.owner)
    page = client.get(reverse("study-participants", args=[study.pk])).content.decode()
    assert "rated a BAD clip high" in page and "s-going" in page and "&quot;http://x&quot;" in page
    response = client.get(reverse("study-participants-csv", args=[study.pk]))
    assert response["Content-Disposition"] == f'attachment; filename="participants-study-{study.pk}.csv"'
    table = list(csv.DictReader(io.StringIO(response.content.decode())))
    assert [r["platform_id"] for r in table] == ["good", "'=HYPERLINK(\"http://x\")", "going", "gone"]
    assert table[1]["session"] == "'@s" and table[0]["suggested_action"] == "approve"
    assert not any(cell.startswith(("=", "+", "-", "@")) for row in table for cell in row.values())


def test_spreadsheet_safe_neutralises_every_formula_start_and_nothing_else():
    assert [spreadsheet_safe(v) for v in ("=1+1", "+1", "-1", "@x", "\t=x", "\r=x")] == [
        "'=1+1", "'+1", "'-1", "'@x", "'\t=x", "'\r=x"]
    assert [spreadsheet_safe(v) for v in ("a=b", "", 1.5, -2)] == ["a=b", "", 1.5, -2]


def test_only_the_owner_sees_the_participant_list():
    study = make_study()
    urls = [reverse("study-participants", args=[study.pk]), reverse("study-participants-csv", args=[study.pk])]
    for url in urls:
        assert Client().get(url).status_code == 302  # to the login page
    stranger = Client()
    stranger.force_login(User.objects.create(username="stranger"))
    assert [stranger.get(url).status_code for url in urls] == [404, 404]
