"""Prolific's API misbehaving, served for real by the local stand-in (``platform_standins``)
on 127.0.0.1: slow, server errors, broken or cut JSON, HTML, bytes that are not HTTP,
another submission's id, redirects, a listing that links to itself, to another host or to
a file, and rate limits with a ``Retry-After`` that means nothing. Whatever it answers, no
page is a server error, nothing is recorded as done that Prolific's answer does not
confirm (it stays pending and the page says so), the token goes to no other host and
reaches no log, and a token or key with a control character is never kept."""

from __future__ import annotations

import html
import json
import logging
import time
from datetime import datetime, timezone

import pytest
from django.test import Client
from django.urls import reverse
from django.utils.timezone import now

from studyapp.models import PlatformAction, Study
from studyapp.platforms import credentials, prolific as prolific_api
from tests.platform_standins import Elsewhere, Raw, http_answer
from tests.test_platform_api import (ACCESS_KEY, SECRET_KEY, TOKEN, apply, dry_run, mturk, mturk_study,  # noqa: F401
                                     participant, prolific, prolific_study, researcher, ticked)

pytestmark = pytest.mark.django_db

LISTING = "/api/v1/studies/PS1/submissions/"


def done_keys() -> list[str]:
    return list(PlatformAction.objects.filter(outcome=PlatformAction.Outcome.DONE).values_list("key", flat=True))


def approve_good(client: Client, study: Study) -> str:
    """Send only the approval of "good" (the dry run's first request); the results page."""
    return html.unescape(apply(client, study, ticked(dry_run(client, study))[:1]))


def read_back(client: Client, study: Study) -> str:
    response = client.post(reverse("study-platform-read", args=[study.pk]), follow=True)
    assert response.status_code == 200
    return html.unescape(response.content.decode())


def mturk_client(study: Study) -> Client:
    client = Client()
    client.force_login(study.owner)
    client.post(reverse("study-platform", args=[study.pk]), {"access_key_id": ACCESS_KEY,
                                                             "secret_access_key": SECRET_KEY})
    return client


def assert_pending(client: Client, study: Study, result: str, why: str) -> None:
    """The approval of "good" is reported as not confirmed, kept as failed, and planned again."""
    assert "<td>not confirmed</td>" in result and why in result, result[-3000:]
    assert "It is not recorded as done: look on Prolific's own pages" in result
    assert done_keys() == []
    action = PlatformAction.objects.get(key="approve:sub-good")
    assert action.outcome == PlatformAction.Outcome.FAILED and action.response["error"].startswith("not confirmed: ")
    assert ticked(dry_run(client, study))[:1]  # still to send


# Answers that must not count as done ------------------------------------------------------

NOT_CONFIRMING = {
    "an HTML page with 200": ((200, b"<html><body>Maintenance</body></html>", {"Content-Type": "text/html"}),
                              "with text/html, not JSON"),
    "a JSON error with 200": ((200, {"error": {"status": 400, "detail": "Not allowed."}}, {}), "with an error"),
    "another submission's id": ((200, {"id": "sub-cheat", "status": "APPROVED"}, {}), "about another submission"),
    "the submission still awaiting review": ((200, {"id": "sub-good", "status": "AWAITING REVIEW"}, {}),
                                             "with the status AWAITING REVIEW, not APPROVED"),
    "a JSON list": ((200, [], {}), "not an object"),
    "204 without a body": ((204, b"", {}), "with broken or cut JSON"),
    "a server error": ((500, {"error": {"detail": "Internal error"}}, {}), "Prolific answered 500"),
    "a bad gateway in HTML": ((502, b"<h1>502 Bad Gateway</h1>", {"Content-Type": "text/html"}),
                              "Prolific answered 502"),
    "broken JSON with 200": ((200, b'{"id": "sub-good", "status": ', {}), "with broken or cut JSON"),
    "NaN in the JSON": ((200, b'{"id": "sub-good", "status": "APPROVED", "fee": NaN}', {}), "broken or cut JSON"),
    "bytes that are not UTF-8": ((200, b'{"id": "\xff\xfe"}', {}), "broken or cut JSON"),
    "JSON nested past any depth": ((200, b"[" * 100_000 + b"]" * 100_000, {}), "broken or cut JSON"),
    "an answer cut short": (Raw(http_answer(200, b'{"id": "sub-good", "st', length=400)), "cut short"),
    "bytes that are not HTTP": (Raw(b"SSH-2.0-OpenSSH_9.6\r\n"), "gave no answer that is HTTP"),
    "the connection closed without a word": (Raw(b""), "gave no answer that is HTTP"),
}


@pytest.mark.parametrize("answer, why", NOT_CONFIRMING.values(), ids=NOT_CONFIRMING.keys())
def test_an_answer_that_does_not_confirm_an_approval_leaves_it_pending_and_says_so(prolific, answer, why):
    study = prolific_study()
    client = researcher(study)
    prolific.refuse_next.append(answer)
    assert_pending(client, study, approve_good(client, study), why)


def test_a_redirect_is_not_followed_and_the_token_goes_to_no_other_host(prolific):
    study = prolific_study()
    client = researcher(study)
    with Elsewhere({"id": "sub-good", "status": "APPROVED"}) as elsewhere:
        transition = f"{elsewhere.url}/api/v1/submissions/sub-good/transition/"
        prolific.refuse_next.append((307, b"", {"Location": transition}))
        result = approve_good(client, study)
        assert elsewhere.requests == []
    assert_pending(client, study, result, f"Prolific answered 307 to '{elsewhere.url}/api/v1/submissions/sub-good")


def test_a_slow_answer_is_given_up_as_unconfirmed_within_the_time_allowed(prolific, monkeypatch):
    monkeypatch.setattr("studyapp.platforms.json_exchange.TIMEOUT_S", 0.5)
    study = prolific_study()
    client = researcher(study)
    prolific.refuse_next.append(Raw(http_answer(200, b'{"id": "sub-good", "status": "APPROVED"}'), delay_s=2.0))
    started = time.monotonic()
    result = approve_good(client, study)
    assert time.monotonic() - started < 1.9
    assert_pending(client, study, result, "Prolific gave no answer in time (0.5 s)")


def test_a_bonus_set_up_answered_without_an_id_is_not_done_and_its_payment_waits(prolific):
    study = prolific_study()
    client = researcher(study)
    data = {"kind": "bonuses", "bonuses": "good,1.00"}
    page = dry_run(client, study, **data)
    prolific.refuse_next.append((201, {"study": "PS1", "amount": 100}, {}))
    result = html.unescape(apply(client, study, ticked(page), **data))
    assert "<td>not confirmed</td>" in result and "without the id of the bonus payment" in result
    assert "<td>not sent</td>" in result and "it needs the answer to bonus:PS1:" in result
    assert done_keys() == [] and [r["path"] for r in prolific.sent()] == ["/api/v1/submissions/bonus-payments/"]
    again = dry_run(client, study, **data)
    assert len(ticked(again)) == 2  # the set-up and its payment are both still to send
    result = html.unescape(apply(client, study, ticked(again), **data))
    assert result.count("<td>sent</td>") == 2 and prolific.bulk_bonuses["bulk-1"]["paid"]


@pytest.mark.parametrize("answer", [(201, {"id": "../../studies/PS1", "study": "PS1"}, {}),
                                    (201, {"id": 7, "study": "PS1"}, {}),
                                    (201, {"id": "bulk-9", "study": "ANOTHER"}, {})],
                         ids=["an id that is a path", "an id that is a number", "another study's set-up"])
def test_a_bonus_set_up_answered_with_an_id_unfit_for_its_payment_is_not_done(prolific, answer):
    study = prolific_study()
    client = researcher(study)
    data = {"kind": "bonuses", "bonuses": "good,1.00"}
    prolific.refuse_next.append(answer)
    result = html.unescape(apply(client, study, ticked(dry_run(client, study, **data)), **data))
    assert "<td>not confirmed</td>" in result and done_keys() == [] and len(prolific.sent()) == 1


def test_a_payment_answered_with_a_server_error_stays_pending_and_is_paid_on_the_retry(prolific):
    study = prolific_study()
    client = researcher(study)
    data = {"kind": "bonuses", "bonuses": "good,1.00"}
    page = dry_run(client, study, **data)
    prolific.misbehave = lambda method, path, body, headers: (
        (503, b"Service Unavailable", {"Content-Type": "text/plain"}) if path.endswith("/pay/") else None)
    result = html.unescape(apply(client, study, ticked(page), **data))
    assert "<td>sent</td>" in result and "<td>not confirmed</td>" in result and "Prolific answered 503" in result
    assert [key.split(":")[0] for key in done_keys()] == ["bonus"]
    prolific.misbehave = None
    again = dry_run(client, study, **data)
    assert len(ticked(again)) == 1  # only the payment
    assert "<td>sent</td>" in apply(client, study, ticked(again), **data) and prolific.bulk_bonuses["bulk-1"]["paid"]


# Rate limits -------------------------------------------------------------------------------

@pytest.mark.parametrize("retry_after", ["abc", "-5", "nan", "inf", "1e9", "Wed, 99 Foo 2026"])
def test_a_rate_limit_with_a_retry_after_that_means_nothing_is_waited_out_for_a_second(prolific, retry_after):
    study = prolific_study()
    client = researcher(study)
    prolific.refuse_next.append((429, {"error": {"detail": "Request was throttled."}}, {"Retry-After": retry_after}))
    started = time.monotonic()
    result = approve_good(client, study)
    assert 0.9 < time.monotonic() - started < 5
    assert "<td>sent</td>" in result and done_keys() == ["approve:sub-good"]


def test_a_retry_after_is_read_as_seconds_or_a_date_and_bounded():
    from studyapp.platforms import json_exchange  # imported here: the tests above run against any client
    from studyapp.platforms.json_exchange import retry_after_s

    noon = datetime(2026, 12, 1, 12, 0, 0, tzinfo=timezone.utc)
    assert retry_after_s("3", noon) == 3.0
    assert retry_after_s("0", noon) == 0.0
    assert retry_after_s("9" * 5000, noon) == json_exchange.LONGEST_WAIT_S
    assert retry_after_s("Tue, 01 Dec 2026 12:00:04 GMT", noon) == 4.0
    assert retry_after_s("Tue, 01 Dec 2026 11:00:00 GMT", noon) == 0.0  # already past
    assert retry_after_s("Tue, 01 Dec 2099 12:00:00 GMT", noon) == json_exchange.LONGEST_WAIT_S
    for meaningless in ("abc", "-5", "nan", "NaN", "inf", "-inf", "1.5", "1e9", "", " ", None, "\x00", "\u0663",
                        "0x10", "+3", "3 s", "Wed, 99 Foo 2026", "Tue, 01 Dec 99999 12:00:00 GMT"):
        assert retry_after_s(meaningless, noon) == json_exchange.DEFAULT_WAIT_S, meaningless


def test_a_rate_limit_that_lasts_is_reported_after_the_retries_and_nothing_is_done(prolific):
    study = prolific_study()
    client = researcher(study)
    prolific.refuse_next += [(429, {"error": {"detail": "Request was throttled."}}, {"Retry-After": "0"})] * 3
    result = approve_good(client, study)
    assert "<td>refused</td>" in result and "Prolific answered 429, asked too often" in result
    assert len(prolific.sent()) == 3 and done_keys() == []


# Reading back ------------------------------------------------------------------------------

def listing_page(prolific, path: str, following: object) -> tuple[int, dict, dict]:
    """The stand-in's own answer to the listing ``path``, with ``following`` as its next link."""
    status, page, headers = prolific.answer("GET", path, {}, {"Authorization": f"Token {TOKEN}"})
    return status, {**page, "_links": {"next": following}}, headers


def test_a_listing_whose_next_page_is_on_another_host_is_not_followed(prolific):
    study = prolific_study()
    client = researcher(study)
    with Elsewhere({"results": [{"id": "sub-good", "status": "FORGED"}]}) as elsewhere:
        prolific.misbehave = lambda method, path, body, headers: listing_page(
            prolific, path, {"href": f"{elsewhere.url}{LISTING}?page=2"})
        page = read_back(client, study)
        assert elsewhere.requests == []
    assert "Nothing was read: Prolific's listing names a next page outside" in page and "FORGED" not in page
    assert not PlatformAction.objects.filter(action="read").exists()


@pytest.mark.parametrize("following", ["//evil.example/api/v1/x", "http://user@{host}/api/v1/x",
                                       "https://{host}/api/v1/x", "/elsewhere/x", "javascript:alert(1)",
                                       "ftp://{host}/api/v1/x"])
def test_a_listing_whose_next_page_leaves_the_apis_own_address_is_not_followed(prolific, following):
    study = prolific_study()
    client = researcher(study)
    href = following.format(host=prolific.url.removeprefix("http://"))
    prolific.misbehave = lambda method, path, body, headers: listing_page(prolific, path, {"href": href})
    page = read_back(client, study)
    assert "Nothing was read: Prolific's listing names a next page outside" in page
    assert len(prolific.sent("GET")) == 1


def test_a_listing_whose_next_page_is_a_file_is_not_read(prolific, tmp_path):
    study = prolific_study()
    client = researcher(study)
    forged = tmp_path / "listing.json"
    forged.write_text(json.dumps({"results": [{"id": "sub-good", "status": "FORGED"}]}))
    prolific.misbehave = lambda method, path, body, headers: listing_page(prolific, path, {"href": forged.as_uri()})
    page = read_back(client, study)
    assert "Nothing was read: Prolific's listing names a next page outside" in page and "FORGED" not in page


def test_a_listing_whose_next_page_is_itself_is_read_once(prolific):
    study = prolific_study()
    client = researcher(study)
    # After 50 pages the stand-in ends the listing, so that a client that follows it does not loop for ever.
    prolific.misbehave = lambda method, path, body, headers: listing_page(
        prolific, path, None if len(prolific.requests) > 50 else {"href": f"{prolific.url}{path}"})
    page = read_back(client, study)
    assert "Nothing was read: Prolific's listing links to a page it gave already" in page
    assert len(prolific.sent("GET")) == 1


def test_a_listing_of_endless_pages_is_read_to_its_bound_of_pages_and_of_time(prolific, monkeypatch):
    study = prolific_study()
    client = researcher(study)
    monkeypatch.setattr(prolific_api, "MAX_PAGES", 5)

    def endless(method, path, body, headers):
        if len(prolific.requests) > 50:
            return None
        return listing_page(prolific, path, {"href": f"{prolific.url}{LISTING}?page={len(prolific.requests) + 1}"})

    prolific.misbehave = endless
    assert "Nothing was read: Prolific's listing goes on past 5 pages" in read_back(client, study)
    assert len(prolific.sent("GET")) == 5

    prolific.requests.clear()
    monkeypatch.setattr(prolific_api, "MAX_PAGES", 1000)
    monkeypatch.setattr(prolific_api, "READ_DEADLINE_S", 1.0)
    prolific.misbehave = lambda method, path, body, headers: time.sleep(0.3) or endless(method, path, body, headers)
    started = time.monotonic()
    page = read_back(client, study)
    assert "Nothing was read: Prolific gave no answer in time" in page
    assert time.monotonic() - started < 2 and len(prolific.sent("GET")) <= 5


MALFORMED_LISTINGS = {
    "no results": {"_links": {"next": None}},
    "results not a list": {"results": {"id": "sub-good"}},
    "a result without an id": {"results": [{"status": "APPROVED"}]},
    "a result whose id is a number": {"results": [{"id": 5, "status": "APPROVED"}]},
    "a result that is text": {"results": ["sub-good"]},
    "a result without a status": {"results": [{"id": "sub-good"}]},
    "a status that is not text": {"results": [{"id": "sub-good", "status": {"a": 1}}]},
    "a status of 10,000 characters": {"results": [{"id": "sub-good", "status": "A" * 10_000}]},
    "links that are text": {"results": [], "_links": "next"},
    "a next link that is a number": {"results": [], "_links": {"next": {"href": 5}}},
    "a listing that is a list": [],
}


@pytest.mark.parametrize("listing", MALFORMED_LISTINGS.values(), ids=MALFORMED_LISTINGS.keys())
def test_a_malformed_listing_is_reported_and_nothing_is_read(prolific, listing):
    study = prolific_study()
    client = researcher(study)
    prolific.refuse_next.append((200, listing, {}))
    page = read_back(client, study)
    assert "Nothing was read: Prolific's listing" in page
    assert "Prolific answered 404" not in page
    assert not PlatformAction.objects.filter(action="read").exists()


@pytest.mark.parametrize("answer", [(200, b"<html>Log in</html>", {"Content-Type": "text/html"}),
                                    (500, b"oops", {}), Raw(b"\x16\x03\x01\x02\x00"),
                                    Raw(http_answer(200, b'{"results": [', length=90))],
                         ids=["HTML", "500", "not HTTP", "cut short"])
def test_a_listing_that_is_not_the_apis_answer_is_reported_and_nothing_is_read(prolific, answer):
    study = prolific_study()
    client = researcher(study)
    prolific.refuse_next.append(answer)
    assert "Nothing was read: Prolific" in read_back(client, study)
    assert not PlatformAction.objects.filter(action="read").exists()


def test_a_listing_redirected_to_another_host_is_not_followed(prolific):
    study = prolific_study()
    client = researcher(study)
    with Elsewhere({"results": [{"id": "sub-good", "status": "FORGED"}]}) as elsewhere:
        prolific.refuse_next.append((302, b"", {"Location": f"{elsewhere.url}{LISTING}"}))
        page = read_back(client, study)
        assert elsewhere.requests == []
    assert f"Nothing was read: Prolific answered 302 to '{elsewhere.url}{LISTING}'" in page and "FORGED" not in page


def test_an_mturk_listing_of_assignments_without_ids_is_reported_and_nothing_is_read(mturk):
    study = mturk_study()
    client = mturk_client(study)
    mturk.refuse_next.append((200, {"NumResults": 1, "Assignments": [{"AssignmentStatus": "Approved"}]}, {}))
    assert "Nothing was read: MTurk's listing has an assignment without an id" in read_back(client, study)


# The token ---------------------------------------------------------------------------------

@pytest.mark.parametrize("token", [f"{TOKEN}\r\nX-Injected: 1", f"{TOKEN}\nmore", f"{TOKEN}\rmore",
                                   f"{TOKEN} {TOKEN}", f"{TOKEN}\x7f", f"{TOKEN}é", f"{TOKEN}\u2028{TOKEN}",
                                   f"{TOKEN}\x1b[2J", f"{TOKEN}\tmore"])
def test_a_token_with_a_control_character_or_a_space_is_refused_and_never_kept_or_logged(prolific, caplog, token):
    caplog.set_level(logging.DEBUG)
    study = prolific_study()
    client = Client()
    client.force_login(study.owner)
    response = client.post(reverse("study-platform", args=[study.pk]), {"token": token})
    page = response.content.decode()
    assert response.status_code == 400 and "which no platform&#x27;s token or key has" in page
    assert credentials.read(client.session, study.platform) is None
    assert TOKEN not in page and TOKEN not in caplog.text and prolific.requests == []


def test_a_token_kept_before_tokens_were_checked_is_asked_for_again_and_never_sent(prolific, caplog):
    caplog.set_level(logging.DEBUG)
    study = prolific_study()
    client = Client(raise_request_exception=False)
    client.force_login(study.owner)
    session = client.session
    credentials.keep(session, study.platform, {"token": f"{TOKEN}\r\nX-Injected: 1"})
    session.save()
    response = client.post(reverse("study-platform-apply", args=[study.pk]), {"kind": "decisions", "call": ["x"]})
    assert response.status_code == 302 and response.url == reverse("study-platform", args=[study.pk])
    assert prolific.requests == [] and TOKEN not in caplog.text
    assert credentials.read(client.session, study.platform) is None


@pytest.mark.parametrize("field", ["access_key_id", "secret_access_key"])
def test_an_mturk_key_with_a_line_break_is_refused_and_never_kept(field):
    study = mturk_study()
    client = Client()
    client.force_login(study.owner)
    form = {"access_key_id": ACCESS_KEY, "secret_access_key": SECRET_KEY}
    form[field] += "\r\nX-Injected: 1"
    response = client.post(reverse("study-platform", args=[study.pk]), form)
    assert response.status_code == 400 and SECRET_KEY not in response.content.decode()
    assert credentials.read(client.session, study.platform) is None


def test_the_token_reaches_no_log_and_no_message_whatever_prolific_answers(prolific, caplog):
    caplog.set_level(logging.DEBUG)
    study = prolific_study()
    client = researcher(study)
    echoed = {"error": {"detail": f"Your header was Authorization: Token {TOKEN}\r\n2026 CRITICAL forged line"}}
    prolific.refuse_next += [(400, echoed, {}), (200, echoed, {})]
    result = html.unescape(apply(client, study, ticked(dry_run(client, study))[:2]))
    assert "<td>refused</td>" in result and "<td>not confirmed</td>" in result
    assert "Your header was Authorization: Token [the token] 2026 CRITICAL forged line" in result
    assert TOKEN not in result and TOKEN not in caplog.text
    assert TOKEN not in json.dumps(list(PlatformAction.objects.values_list("response", flat=True)))
    assert all("\r" not in record.getMessage() and "\n" not in record.getMessage() for record in caplog.records
               if record.name == "studyapp.platforms")


# MTurk, through boto3 ---------------------------------------------------------------------

MTURK_NOT_CONFIRMING = {
    "an HTML page with 200": ((200, b"<html>Sign in</html>", {"Content-Type": "text/html"}), "with text/html"),
    "broken JSON with 200": ((200, b'{"a": ', {}), "not its JSON"),
    "an answer cut short": (Raw(http_answer(200, b'{"a"', content_type="application/x-amz-json-1.1", length=90)),
                            "not its JSON"),
    "a server error": ((500, {"__type": "ServiceUnavailableException", "Message": "Down."}, {}),
                       "MTurk answered 500, which confirms nothing: Down."),
    "a redirect": ((302, b"", {"Location": "http://127.0.0.1:9/"}), "MTurk answered 302"),
    "bytes that are not HTTP": (Raw(b"SSH-2.0-OpenSSH_9.6\r\n"), "MTurk gave no whole answer"),
}


@pytest.mark.parametrize("answer, why", MTURK_NOT_CONFIRMING.values(), ids=MTURK_NOT_CONFIRMING.keys())
def test_an_mturk_answer_that_does_not_confirm_an_approval_leaves_it_pending_and_says_so(mturk, answer, why):
    study = mturk_study()
    client = mturk_client(study)
    mturk.refuse_next += [answer] * 4  # botocore's own retries of a server error meet it too
    result = html.unescape(apply(client, study, ticked(dry_run(client, study))[:1]))
    assert "<td>not confirmed</td>" in result and why in result, result[-2000:]
    assert done_keys() == [] and mturk.assignments["A-W-good"]["AssignmentStatus"] == "Submitted"


def test_an_mturk_listing_of_endless_pages_is_read_to_its_bound(mturk, monkeypatch):
    monkeypatch.setattr("studyapp.platforms.mturk.MAX_PAGES", 5)
    study = mturk_study()
    client = mturk_client(study)
    # A new NextToken on every page; after 50 the stand-in ends, so that a client that follows it does not loop for ever.
    mturk.misbehave = lambda method, path, body, headers: None if len(mturk.requests) > 50 else (
        200, {"NumResults": 0, "Assignments": [], "NextToken": f"t{len(mturk.requests)}"}, {})
    assert "Nothing was read: MTurk's listing goes on past 5 pages" in read_back(client, study)
    assert len(mturk.requests) == 6  # the pages to the bound, and the one that went past it


# Ids from the entry link -------------------------------------------------------------------

def test_a_submission_or_study_id_no_platform_gives_never_goes_into_a_request(prolific):
    study = prolific_study()
    finished = {"finished_at": now()}
    for pid, session, group in (("climber", "../../../studies/PS1", "PS1"), ("asker", "sub-x?page=2", "PS1"),
                                ("reader", "sub-r", "../../workspaces/W1")):
        participant(study, pid, {"PROLIFIC_PID": pid, "STUDY_ID": group, "SESSION_ID": session}, **finished)
    client = researcher(study)
    page = html.unescape(dry_run(client, study))
    assert "Not listed: climber, asker." in page and "../" not in page.split('id="unsendable"')[0]
    apply(client, study, ticked(page))
    read_back(client, study)
    bonus = client.post(reverse("study-platform-dry-run", args=[study.pk]), {"kind": "bonuses",
                                                                             "bonuses": "reader,1.00"})
    assert bonus.status_code == 400 and "came without a submission id and study id" in html.unescape(
        bonus.content.decode())
    assert all(".." not in r["path"] and "?" not in r["path"].removesuffix("?page=2") for r in prolific.requests)
