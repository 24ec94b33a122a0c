"""The participant list's suggested payment follows the platform's published rules, apart
from the analysis: a participant stopped by failed instructed checks is listed as such, a
quality judgement (a BAD clip rated high) excludes from the analysis but is approved, and
a rejection needs as many failed instructed checks as Prolific's attention-check policy
(one under 5 minutes, two from 5) or MTurk's guidance (two) ask for."""

from __future__ import annotations

import csv
import io
from datetime import timedelta

import pytest
from django.test import Client
from django.urls import reverse
from django.utils import timezone

from studyapp.models import Participant, Study
from studyapp.platforms.rules import (APPROVE, NOTHING, REJECT, REQUEST_RETURN, Standing, Submission,
                                      checks_for_rejection, suggest)
from studyapp.researchers.crowd.participant_list import participant_rows
from tests.study_fixtures import make_study

pytestmark = pytest.mark.django_db


def participant(study: Study, pid: str, minutes: float | None = None, **fields) -> Participant:
    """A participant who started ``minutes`` ago and ended now (None: still going)."""
    now = timezone.now()
    created = Participant.objects.create(study=study, platform_id=pid, platform_data={"SESSION_ID": f"s-{pid}"})
    ended = {"finished_at": now} if minutes is not None else {}
    Participant.objects.filter(pk=created.pk).update(started_at=now - timedelta(minutes=minutes or 0),
                                                     **ended, **fields)
    return created


def rows_of(study: Study) -> dict:
    return {row.platform_id: row for row in participant_rows(study)}


def test_a_participant_stopped_by_failed_checks_is_listed_as_stopped_with_the_reason_in_the_page_and_csv():
    study = make_study(platform=Study.Platform.PROLIFIC, instructed_checks=3, stop_after_failed_checks=2)
    participant(study, "careful", minutes=12)
    participant(study, "stopped", minutes=4, failed_checks=2, stopped_at=timezone.now())
    rows = rows_of(study)
    stopped = rows["stopped"]
    assert (stopped.status, stopped.failed_checks, stopped.suggested_action) == ("stopped by checks", 2, REJECT)
    assert "failed 2 instructed attention checks" in stopped.action_reason
    assert "Prolific's attention-check policy (a study of 12.0 min) allows a rejection after 2" in stopped.action_reason
    assert (rows["careful"].status, rows["careful"].suggested_action) == ("finished", APPROVE)

    client = Client()
    client.force_login(study.owner)
    page = client.get(reverse("study-participants", args=[study.pk])).content.decode()
    assert "stopped by checks" in page and "failed 2 instructed attention checks" in page
    table = {r["platform_id"]: r for r in csv.DictReader(io.StringIO(
        client.get(reverse("study-participants-csv", args=[study.pk])).content.decode()))}
    assert (table["stopped"]["status"], table["stopped"]["failed_checks"], table["stopped"]["suggested_action"]) == (
        "stopped by checks", "2", "reject")
    assert "failed 2 instructed attention checks" in table["stopped"]["action_reason"]
    assert table["careful"]["excluded"] == "False" and table["careful"]["suggested_action"] == "approve"


def test_a_bad_clip_rated_high_excludes_from_the_analysis_and_is_still_approved():
    study = make_study(platform=Study.Platform.PROLIFIC)
    participant(study, "harsh", minutes=10, excluded=True, exclusion_reason="rated a BAD clip 5")
    row = rows_of(study)["harsh"]
    assert (row.excluded, row.exclusion_reason, row.suggested_action) == (True, "rated a BAD clip 5", APPROVE)
    assert "excluded from the analysis (rated a BAD clip 5)" in row.action_reason
    assert "no ground for refusing payment" in row.action_reason


@pytest.mark.parametrize("finished_minutes, failed, expected", [
    ([3.0, 4.0, 4.5], 1, REJECT),  # a study under 5 minutes: one failed check is enough
    ([3.0, 6.0, 8.0], 1, REQUEST_RETURN),  # 5 minutes or more (the median of those who finished): one is not
    ([3.0, 6.0, 8.0], 2, REJECT),
    ([], 1, REQUEST_RETURN),  # no one has finished: the length is unknown, two are asked for
])
def test_prolific_rejects_after_one_failed_check_under_five_minutes_and_two_from_five(finished_minutes, failed,
                                                                                      expected):
    study = make_study(platform=Study.Platform.PROLIFIC, instructed_checks=2, stop_after_failed_checks=failed)
    for i, minutes in enumerate(finished_minutes):
        participant(study, f"other-{i}", minutes=minutes)
    participant(study, "slip", minutes=1, failed_checks=failed, stopped_at=timezone.now())
    row = rows_of(study)["slip"]
    assert row.suggested_action == expected
    if expected == REQUEST_RETURN:
        assert "allows a rejection only after 2" in row.action_reason and "ask for a return" in row.action_reason


@pytest.mark.parametrize("platform, standing, failed, codes, expected", [
    # Prolific: stopped below the policy's count is asked to return, never rejected.
    (Study.Platform.PROLIFIC, Standing.STOPPED, 1, {}, REQUEST_RETURN),
    (Study.Platform.PROLIFIC, Standing.STOPPED, 2, {}, REJECT),
    (Study.Platform.PROLIFIC, Standing.SCREENED_OUT, 0, {"screen_out_code": "SCR33N"}, NOTHING),
    (Study.Platform.PROLIFIC, Standing.SCREENED_OUT, 0, {}, REQUEST_RETURN),
    (Study.Platform.PROLIFIC, Standing.IN_PROGRESS, 3, {}, NOTHING),
    (Study.Platform.PROLIFIC, Standing.IDLE, 0, {}, NOTHING),
    # MTurk: no return request; a single slip is approved.
    (Study.Platform.MTURK, Standing.STOPPED, 1, {}, APPROVE),
    (Study.Platform.MTURK, Standing.FINISHED, 1, {}, APPROVE),
    (Study.Platform.MTURK, Standing.FINISHED, 2, {}, REJECT),
    (Study.Platform.MTURK, Standing.SCREENED_OUT, 0, {}, APPROVE),
    (Study.Platform.LINK, Standing.FINISHED, 1, {}, APPROVE),
])
def test_each_platforms_rules_decide_from_the_failed_instructed_checks(platform, standing, failed, codes, expected):
    study = Study(platform=platform, **codes)
    suggestion = suggest(study, Submission(standing, failed, exclusion_reason="rated a BAD clip 5"), minutes=12.0)
    assert suggestion.action == expected and suggestion.reason


def test_a_quality_exclusion_never_turns_into_a_rejection_on_any_platform():
    for platform in Study.Platform.values:
        study = Study(platform=platform)
        for standing in (Standing.FINISHED, Standing.STOPPED):
            submission = Submission(standing, failed_checks=0, exclusion_reason="rated a NAT clip 1")
            assert suggest(study, submission, minutes=2.0).action != REJECT
        assert checks_for_rejection(study, None) == 2
