"""The platform's API from the participant list, against local stand-ins of Prolific's API
and MTurk's (``platform_standins``): the researcher's credentials are kept encrypted in
the session only; every action is a dry run first that lists exactly what is then sent;
applying sends each request once (a retry sends only what failed), keeps and logs each,
and reports the platform's refusals in its words; bonuses and reading back; owner checks."""

from __future__ import annotations

import html
import io
import json
import logging
import re
from datetime import timedelta

import pytest
from django.contrib.auth.models import User
from django.contrib.sessions.models import Session
from django.core.management import call_command
from django.test import Client
from django.urls import reverse
from django.utils import timezone

from studyapp.models import Participant, PlatformAction, Study
from studyapp.platforms.prolific import MIN_REJECTION_MESSAGE, rejection_message
from tests.platform_standins import MTurkStandIn, ProlificStandIn
from tests.study_fixtures import make_study

pytestmark = pytest.mark.django_db

TOKEN = "prolific-token-9f8e7d6c5b4a"
ACCESS_KEY, SECRET_KEY = "AKIDSTANDIN", "mturk-secret-0a1b2c3d4e5f"


def participant(study: Study, pid: str, data: dict, minutes: float = 10, **fields) -> Participant:
    now = timezone.now()
    created = Participant.objects.create(study=study, platform_id=pid, platform_data=data)
    Participant.objects.filter(pk=created.pk).update(started_at=now - timedelta(minutes=minutes), **fields)
    return created


def prolific_study() -> Study:
    """Done: one to approve, one to reject (two failed checks), one stopped to ask back; one still going."""
    study = make_study(platform=Study.Platform.PROLIFIC, instructed_checks=3, stop_after_failed_checks=2)
    now = timezone.now()
    for pid, fields in (("good", {"finished_at": now}), ("cheat", {"finished_at": now, "failed_checks": 2}),
                        ("slip", {"finished_at": now, "stopped_at": now, "failed_checks": 1}), ("going", {})):
        participant(study, pid, {"PROLIFIC_PID": pid, "STUDY_ID": "PS1", "SESSION_ID": f"sub-{pid}"}, **fields)
    return study


def prolific_submissions(*pids: str) -> dict[str, dict]:
    return {f"sub-{pid}": {"id": f"sub-{pid}", "participant_id": pid, "study_id": "PS1",
                           "status": "ACTIVE" if pid == "going" else "AWAITING REVIEW"} for pid in pids}


@pytest.fixture()
def prolific(settings):
    with ProlificStandIn(TOKEN, prolific_submissions("good", "cheat", "slip", "going")) as stand_in:
        settings.PROLIFIC_API_URL = stand_in.url
        yield stand_in


def researcher(study: Study, token: str = TOKEN) -> Client:
    client = Client()
    client.force_login(study.owner)
    assert client.post(reverse("study-platform", args=[study.pk]), {"token": token}).status_code == 302
    return client


def dry_run(client: Client, study: Study, **data) -> str:
    response = client.post(reverse("study-platform-dry-run", args=[study.pk]), {"kind": "decisions", **data})
    assert response.status_code == 200, response.content.decode()[:2000]
    return response.content.decode()


def ticked(page: str) -> list[str]:
    return re.findall(r'name="call" value="([0-9a-f]{64})" checked', page)


def shown_requests(page: str) -> list[tuple[str, dict]]:
    """Each planned request's operation and body as the dry run shows them."""
    plan = page[page.index('id="plan"'):]
    rows = re.findall(r'<code class="operation">([^<]+)</code>(?:.|\n)*?(?:<pre class="request">([^<]*)</pre>|</li>)',
                      plan)
    return [(html.unescape(operation), json.loads(html.unescape(body)) if body else {}) for operation, body in rows]


def apply(client: Client, study: Study, calls: list[str], **data) -> str:
    response = client.post(reverse("study-platform-apply", args=[study.pk]), {"kind": "decisions", "call": calls, **data})
    return response.content.decode()


def test_the_dry_run_lists_exactly_what_is_then_sent_and_sends_nothing_itself(prolific):
    study = prolific_study()
    client = researcher(study)
    page = dry_run(client, study)
    assert prolific.requests == []  # a dry run sends nothing
    shown = shown_requests(page)
    assert [operation for operation, _ in shown] == [
        "POST /api/v1/submissions/sub-good/transition/", "POST /api/v1/submissions/sub-cheat/transition/",
        "POST /api/v1/submissions/sub-slip/request-return/"]
    assert shown[0][1] == {"action": "APPROVE"}
    assert shown[1][1] == {"action": "REJECT", "message": rejection_message(2), "rejection_category": "FAILED_CHECK"}
    assert shown[2][1]["request_return_reasons"] == [
        "The study stopped after answers that did not follow the instructions shown on the page, so it was not finished."]

    result = apply(client, study, ticked(page))
    sent = prolific.sent()
    assert [(r["method"] + " " + r["path"], r["body"]) for r in sent] == shown  # byte for byte what was shown
    assert all(r["headers"]["Authorization"] == f"Token {TOKEN}" for r in sent)
    assert [prolific.submissions[f"sub-{pid}"]["status"] for pid in ("good", "cheat", "slip", "going")] == [
        "APPROVED", "REJECTED", "AWAITING REVIEW", "ACTIVE"]
    assert "return_requested" in prolific.submissions["sub-slip"] and result.count("<td>sent</td>") == 3
    assert list(PlatformAction.objects.values_list("action", "outcome")) == [
        ("approve", "done"), ("reject", "done"), ("request return", "done")]


def test_a_rejection_message_is_as_long_as_prolific_requires():
    assert all(len(rejection_message(n)) >= MIN_REJECTION_MESSAGE for n in (1, 2, 7))


def test_only_the_ticked_requests_are_sent_and_a_retry_sends_only_what_was_not_done(prolific):
    study = prolific_study()
    del prolific.submissions["sub-cheat"]  # Prolific does not know this one: 404
    client = researcher(study)
    page = dry_run(client, study)
    good, cheat, slip = ticked(page)
    result = apply(client, study, [good, cheat])  # the return request left unticked
    assert "Prolific knows no such submission" in result and "Submission sub-cheat not found." in result
    assert [r["path"] for r in prolific.sent()] == ["/api/v1/submissions/sub-good/transition/",
                                                   "/api/v1/submissions/sub-cheat/transition/"]
    assert PlatformAction.objects.filter(key="reject:sub-cheat").get().outcome == "failed"

    prolific.submissions.update(prolific_submissions("cheat"))
    page = dry_run(client, study)
    assert page.count('class="request done"') == 1 and "Dry run: 2 requests" in page
    prolific.requests.clear()
    apply(client, study, ticked(page))
    assert [r["path"] for r in prolific.sent()] == ["/api/v1/submissions/sub-cheat/transition/",
                                                   "/api/v1/submissions/sub-slip/request-return/"]
    prolific.requests.clear()
    assert apply(client, study, [good]).count("sent before: not sent again") == 1  # the same form posted again
    assert prolific.sent() == []


def test_a_participant_whose_link_brought_no_submission_id_is_named_instead_of_planned(prolific):
    study = prolific_study()
    participant(study, "no-session", {"PROLIFIC_PID": "no-session", "STUDY_ID": "PS1"}, finished_at=timezone.now())
    page = dry_run(researcher(study), study)
    assert "Not listed: no-session." in page and "Dry run: 3 requests" in page


def test_a_plan_that_changed_since_the_dry_run_sends_nothing(prolific):
    study = prolific_study()
    client = researcher(study)
    page = dry_run(client, study)
    Participant.objects.filter(platform_id="good").update(failed_checks=2)  # now to be rejected
    response = client.post(reverse("study-platform-apply", args=[study.pk]), {"kind": "decisions",
                                                                              "call": ticked(page)})
    assert response.status_code == 409 and "differ from the dry run" in response.content.decode()
    assert prolific.requests == [] and not PlatformAction.objects.exists()


def test_prolifics_refusals_are_reported_in_its_words_and_a_rate_limit_is_waited_out(prolific):
    study = prolific_study()
    client = researcher(study, token="not-the-token")
    result = apply(client, study, ticked(dry_run(client, study))[:1])
    assert "Prolific answered 401, the token was not accepted" in result and "Invalid token." in result

    client = researcher(study)
    prolific.submissions["sub-good"]["status"] = "RETURNED"
    prolific.refuse_next.append((429, {"error": {"detail": "Request was throttled."}}, {"Retry-After": "0"}))
    result = apply(client, study, ticked(dry_run(client, study))[:2])
    assert "Cannot transition a submission with status RETURNED." in result  # after the 429, asked again
    assert prolific.submissions["sub-cheat"]["status"] == "REJECTED"
    log = client.get(reverse("study-platform", args=[study.pk])).content.decode()
    assert "Cannot transition a submission with status RETURNED." in log and log.count(">failed<") == 2


def test_the_token_is_kept_only_encrypted_in_the_session_and_reaches_no_log_page_or_table(prolific, caplog):
    caplog.set_level(logging.INFO)
    study = prolific_study()
    client = researcher(study)
    page = dry_run(client, study)
    apply(client, study, ticked(page))
    platform_page = client.get(reverse("study-platform", args=[study.pk])).content.decode()
    assert "token is kept" in platform_page
    dump = io.StringIO()
    call_command("dumpdata", stdout=dump)
    sessions = [session.get_decoded() for session in Session.objects.all()]
    assert "platform_credentials" in json.dumps(sessions)
    for text in (dump.getvalue(), json.dumps(sessions), caplog.text, page, platform_page):
        assert TOKEN not in text
    assert "reject reject:sub-cheat sent to Prolific" in caplog.text  # what was sent is logged

    client.post(reverse("study-platform", args=[study.pk]), {"action": "forget"})
    response = client.post(reverse("study-platform-dry-run", args=[study.pk]), {"kind": "decisions"})
    assert response.status_code == 302 and response.url == reverse("study-platform", args=[study.pk])


def test_bonuses_are_set_up_then_paid_once_and_a_bad_line_is_named(prolific):
    study = prolific_study()
    client = researcher(study)
    bad = client.post(reverse("study-platform-dry-run", args=[study.pk]), {
        "kind": "bonuses", "bonuses": "good,1.50\nnobody,2"})
    assert bad.status_code == 400 and "line 2: &#x27;nobody&#x27; is not a participant of this study" in (
        bad.content.decode())
    for lines, problem in (("good,-1", "above 0"), ("good,1.505", "in cents at most"), ("good,x", "not a number"),
                           ("good,1\ngood,2", "listed twice"), ("", "This field is required")):
        answer = client.post(reverse("study-platform-dry-run", args=[study.pk]), {"kind": "bonuses", "bonuses": lines})
        assert answer.status_code == 400 and problem in html.unescape(answer.content.decode())
    assert prolific.requests == []

    data = {"kind": "bonuses", "bonuses": "good,1.50\nslip, 0.25\n", "reason": ""}
    page = dry_run(client, study, **data)
    shown = shown_requests(page)
    assert shown == [("POST /api/v1/submissions/bonus-payments/",
                      {"study_id": "PS1", "csv_bonuses": "sub-good,1.50\nsub-slip,0.25\n"}),
                     ("POST /api/v1/bulk-bonus-payments/{id}/pay/", {})]
    result = apply(client, study, ticked(page), **data)
    assert [r["path"] for r in prolific.sent()] == ["/api/v1/submissions/bonus-payments/",
                                                   "/api/v1/bulk-bonus-payments/bulk-1/pay/"]
    assert prolific.bulk_bonuses["bulk-1"]["paid"] and result.count("<td>sent</td>") == 2
    prolific.requests.clear()
    again = dry_run(client, study, **data)
    assert again.count('class="request done"') == 2 and ticked(again) == []
    apply(client, study, ticked(page), **data)
    assert prolific.sent() == []  # the same list is the same payment: never paid twice


def test_a_bonus_set_up_but_not_paid_is_paid_on_retry_without_a_second_set_up(prolific):
    study = prolific_study()
    client = researcher(study)
    data = {"kind": "bonuses", "bonuses": "good,1.00"}
    page = dry_run(client, study, **data)
    setup, pay = ticked(page)
    apply(client, study, [setup], **data)  # only the set-up ticked
    apply(client, study, [pay], **data)
    assert [r["path"] for r in prolific.sent()] == ["/api/v1/submissions/bonus-payments/",
                                                   "/api/v1/bulk-bonus-payments/bulk-1/pay/"]
    assert len(prolific.bulk_bonuses) == 1 and prolific.bulk_bonuses["bulk-1"]["paid"]


def test_reading_back_sets_prolifics_status_beside_the_list_following_its_pages(prolific):
    study = prolific_study()
    prolific.submissions["sub-good"]["status"] = "APPROVED"
    client = researcher(study)
    page = client.post(reverse("study-platform-read", args=[study.pk])).content.decode()
    rows = re.findall(r"<tr><td>([^<]+)</td><td>([^<]+)</td><td>([^<]+)</td>\s*<td>([^<]+)</td><td>([^<]+)</td></tr>",
                      page)
    assert rows == [("good", "sub-good", "finished", "approve", "APPROVED"),
                    ("cheat", "sub-cheat", "finished", "reject", "AWAITING REVIEW"),
                    ("slip", "sub-slip", "stopped by checks", "request return", "AWAITING REVIEW"),
                    ("going", "sub-going", "in progress", "–", "ACTIVE")]
    assert [r["path"] for r in prolific.sent("GET")] == [
        "/api/v1/studies/PS1/submissions/", "/api/v1/studies/PS1/submissions/?page=2"]
    assert PlatformAction.objects.get(action="read").response["statuses"]["sub-slip"] == "AWAITING REVIEW"


def test_only_the_owner_of_a_prolific_or_mturk_study_reaches_its_platform_pages(prolific):
    study = prolific_study()
    link_study = make_study(owner_name="researcher", platform=Study.Platform.LINK)
    pages = [("get", "study-platform"), ("post", "study-platform-dry-run"), ("post", "study-platform-apply"),
             ("post", "study-platform-read")]
    for method, name in pages:
        assert getattr(Client(), method)(reverse(name, args=[study.pk])).status_code == 302  # to the login page
    stranger = Client()
    stranger.force_login(User.objects.create(username="stranger"))
    owner = Client()
    owner.force_login(study.owner)
    for method, name in pages:
        assert getattr(stranger, method)(reverse(name, args=[study.pk])).status_code == 404
        assert getattr(owner, method)(reverse(name, args=[link_study.pk])).status_code == 404
    assert Client().post(reverse("study-platform", args=[study.pk]), {"token": TOKEN}).status_code == 302
    assert prolific.requests == [] and Session.objects.filter(session_data__contains="platform").count() == 0


# MTurk, through boto3, against a local stand-in of its requester API.

def mturk_study() -> Study:
    study = make_study(platform=Study.Platform.MTURK, instructed_checks=3)
    now = timezone.now()
    for worker, fields in (("W-good", {"finished_at": now}), ("W-cheat", {"finished_at": now, "failed_checks": 2}),
                           ("W-slip", {"finished_at": now, "stopped_at": now, "failed_checks": 1})):
        participant(study, worker, {"workerId": worker, "assignmentId": f"A-{worker}", "hitId": "HIT1",
                                    "turkSubmitTo": "https://workersandbox.mturk.com"}, **fields)
    return study


@pytest.fixture()
def mturk(settings):
    assignments = {f"A-{w}": {"AssignmentId": f"A-{w}", "WorkerId": w, "HITId": "HIT1", "AssignmentStatus": "Submitted"}
                   for w in ("W-good", "W-cheat", "W-slip")}
    with MTurkStandIn(ACCESS_KEY, assignments) as stand_in:
        settings.MTURK_SANDBOX_API_URL = stand_in.url
        settings.MTURK_API_URL = "http://127.0.0.1:9/the-real-marketplace"
        yield stand_in


def mturk_researcher(study: Study, **extra) -> Client:
    client = Client()
    client.force_login(study.owner)
    response = client.post(reverse("study-platform", args=[study.pk]),
                           {"access_key_id": ACCESS_KEY, "secret_access_key": SECRET_KEY, **extra})
    assert response.status_code == 302
    return client


def test_mturk_decisions_go_to_its_sandbox_through_boto3_signed_with_the_researchers_key(mturk, caplog):
    caplog.set_level(logging.INFO)
    study = mturk_study()
    client = mturk_researcher(study)
    assert "sandbox" in client.get(reverse("study-platform", args=[study.pk])).content.decode()
    page = dry_run(client, study)
    assert mturk.requests == [] and mturk.url in page
    shown = shown_requests(page)
    assert [operation for operation, _ in shown] == ["ApproveAssignment", "RejectAssignment", "ApproveAssignment"]
    assert shown[1][1] == {"AssignmentId": "A-W-cheat", "RequesterFeedback": (
        "Rejected because 2 attention checks in the task were not answered as the page asked: each told you which "
        "answer to give, whatever you thought of the video.")}
    apply(client, study, ticked(page))
    assert [(r["headers"]["X-Amz-Target"].rpartition(".")[2], r["body"]) for r in mturk.sent("POST")] == shown
    assert all(f"Credential={ACCESS_KEY}/" in r["headers"]["Authorization"] for r in mturk.requests)
    assert [a["AssignmentStatus"] for a in mturk.assignments.values()] == ["Approved", "Rejected", "Approved"]
    mturk.requests.clear()
    assert "sent before" in apply(client, study, ticked(page)) and mturk.requests == []

    dump = io.StringIO()
    call_command("dumpdata", stdout=dump)
    sessions = json.dumps([session.get_decoded() for session in Session.objects.all()])
    for text in (dump.getvalue(), sessions, caplog.text, page):
        assert SECRET_KEY not in text


def test_mturk_bonuses_carry_their_reason_and_a_token_that_mturk_refuses_twice(mturk):
    study = mturk_study()
    client = mturk_researcher(study)
    refused = client.post(reverse("study-platform-dry-run", args=[study.pk]), {"kind": "bonuses",
                                                                               "bonuses": "W-good,0.50"})
    assert refused.status_code == 400 and "MTurk shows each bonus with its reason" in refused.content.decode()
    data = {"kind": "bonuses", "bonuses": "W-good,0.50", "reason": "For finishing every page."}
    page = dry_run(client, study, **data)
    (operation, body), = shown_requests(page)
    assert operation == "SendBonus" and body["BonusAmount"] == "0.50" and body["Reason"] == "For finishing every page."
    apply(client, study, ticked(page), **data)
    assert mturk.bonuses == [body]
    PlatformAction.objects.all().delete()  # as if the record were lost: MTurk itself refuses the same token
    result = apply(client, study, ticked(page), **data)
    assert "MTurk refused: The bonus with this UniqueRequestToken was already paid." in result
    assert len(mturk.bonuses) == 1


def test_mturk_submissions_are_read_back_across_pages_and_the_real_marketplace_only_when_asked(mturk):
    study = mturk_study()
    client = mturk_researcher(study)
    page = client.post(reverse("study-platform-read", args=[study.pk])).content.decode()
    assert page.count("Submitted") == 3 and len(mturk.requests) == 2  # two pages
    live = mturk_researcher(study, live="on")
    assert "the-real-marketplace" in dry_run(live, study)
    answer = live.post(reverse("study-platform-read", args=[study.pk]), follow=True).content.decode()
    assert "Nothing was read: MTurk could not be reached at http://127.0.0.1:9/the-real-marketplace" in answer
