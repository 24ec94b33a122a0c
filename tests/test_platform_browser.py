"""The platform's rules, codes and API in a real browser (headless Debian Chromium), on a
desktop (1366×768) and a phone (390×844): the participant list shows who was stopped by
checks and why, apart from the analysis; the screened-out and the stopped leave with their
own codes; and the researcher sends the suggested decisions to a local stand-in of
Prolific's API through a dry run."""

from __future__ import annotations

from datetime import timedelta

import pytest
from django.urls import reverse
from django.utils import timezone

from studyapp.models import Participant, Question, Study
from tests.platform_standins import ProlificStandIn
from tests.study_fixtures import make_study
from tests.test_crowd_browser import log_in
from tests.test_study_browser import browser  # noqa: F401 (fixture)

pytestmark = pytest.mark.slow

DESKTOP = {"viewport": {"width": 1366, "height": 768}}
PHONE = {"viewport": {"width": 390, "height": 844}, "is_mobile": True, "has_touch": True}
SIZES = pytest.mark.parametrize("size", [DESKTOP, PHONE], ids=["desktop", "phone"])
TOKEN = "prolific-token-in-a-browser"


def researcher_page(browser, live_server, study: Study, size: dict):
    context, page = log_in(browser, live_server, study.owner)
    page.set_viewport_size(size["viewport"])
    return context, page


def within_width(page, selector: str) -> bool:
    """Whether the element's box lies inside the window's width (a table may scroll inside its box)."""
    return page.evaluate(f"""() => {{ const box = document.querySelector({selector!r}).getBoundingClientRect();
        return box.left >= 0 && box.right <= window.innerWidth + 1; }}""")


def table_rows(page, selector: str) -> list[dict]:
    page.locator(selector).wait_for()  # after a click the next page may not have arrived yet
    headers = page.locator(f"{selector} tr").nth(0).locator("th").all_inner_texts()
    return [dict(zip(headers, row.locator("td").all_inner_texts()))
            for row in page.locator(f"{selector} tr").all()[1:]]


def participant(study: Study, pid: str, minutes: float, **fields) -> None:
    now = timezone.now()
    created = Participant.objects.create(study=study, platform_id=pid,
                                         platform_data={"PROLIFIC_PID": pid, "STUDY_ID": "PS1", "SESSION_ID": f"sub-{pid}"})
    Participant.objects.filter(pk=created.pk).update(started_at=now - timedelta(minutes=minutes), **fields)


def reviewed_study() -> Study:
    study = make_study(platform=Study.Platform.PROLIFIC, instructed_checks=3, stop_after_failed_checks=2,
                       screen_out_code="SCR33N", stopped_code="ST0PP3D")
    now = timezone.now()
    participant(study, "careful", 12, finished_at=now)
    participant(study, "harsh", 11, finished_at=now, excluded=True, exclusion_reason="rated a BAD clip 5")
    participant(study, "stopped", 6, finished_at=now, stopped_at=now, failed_checks=2)
    participant(study, "slip", 4, finished_at=now, stopped_at=now, failed_checks=1)
    return study


@pytest.mark.django_db(transaction=True)
@SIZES
def test_the_participant_list_shows_who_was_stopped_by_checks_and_why_apart_from_the_analysis(browser, live_server,
                                                                                             size):
    study = reviewed_study()
    context, page = researcher_page(browser, live_server, study, size)
    page.goto(f"{live_server.url}{reverse('study-participants', args=[study.pk])}")
    rows = {row["Platform id"]: row for row in table_rows(page, "#participants")}
    assert (rows["stopped"]["Status"], rows["stopped"]["Failed checks"], rows["stopped"]["Suggested payment"]) == (
        "stopped by checks", "2", "reject")
    assert "failed 2 instructed attention checks" in rows["stopped"]["Why"]
    assert (rows["slip"]["Status"], rows["slip"]["Suggested payment"]) == ("stopped by checks", "request return")
    assert (rows["harsh"]["Analysis"], rows["harsh"]["Suggested payment"]) == ("excluded: rated a BAD clip 5", "approve")
    assert "no ground for refusing payment" in rows["harsh"]["Why"]
    assert rows["careful"]["Analysis"] == "kept"
    why = page.locator("#participants tr", has_text="stopped by checks").first.locator("td.reason")
    why.scroll_into_view_if_needed()
    assert why.is_visible() and within_width(page, ".table-scroll")
    context.close()


@pytest.mark.django_db(transaction=True)
@SIZES
def test_the_screened_out_and_the_stopped_leave_with_their_own_codes(browser, live_server, size):
    study = make_study(platform=Study.Platform.PROLIFIC, completion_code="C0MPL3TE", screen_out_code="SCR33N",
                       stopped_code="ST0PP3D", instructed_checks=1, stop_after_failed_checks=1)
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="language",
                            text="Is English your first language?", choices="yes\nno", accepted="yes")
    context = browser.new_context(**size)
    page = context.new_page()
    page.goto(f"{live_server.url}/p/{study.key}/?PROLIFIC_PID=elsewhere&STUDY_ID=S1&SESSION_ID=A")
    page.get_by_role("button", name="I agree to take part").click()
    page.get_by_label("no").check()
    page.get_by_role("button", name="Continue").click()
    page.wait_for_selector("#completion-code")
    assert page.inner_text("#completion-code") == "SCR33N" and "ends here for you" in page.inner_text("body")
    link = page.get_by_role("link", name="Return to Prolific")
    assert link.get_attribute("href") == "https://app.prolific.com/submissions/complete?cc=SCR33N"
    assert link.is_visible() and within_width(page, "#completion-link") and "C0MPL3TE" not in page.content()
    assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth")

    other = context.new_page()
    other.goto(f"{live_server.url}/p/{study.key}/?PROLIFIC_PID=inattentive&STUDY_ID=S1&SESSION_ID=B")
    other.get_by_role("button", name="I agree to take part").click()
    now = timezone.now()  # as if past the questions and the practice, and stopped on a failed check
    inattentive = Participant.objects.get(platform_id="inattentive")
    Participant.objects.filter(pk=inattentive.pk).update(
        screened_at=now, instructed_at=now, training_done=len(inattentive.training), failed_checks=1, stopped_at=now,
        finished_at=now)
    other.goto(f"{live_server.url}/p/{study.key}/now/")
    assert other.inner_text("#completion-code") == "ST0PP3D" and "Thank you for your time" in other.inner_text("body")
    assert other.get_by_role("link", name="Return to Prolific").get_attribute("href").endswith("cc=ST0PP3D")
    assert other.evaluate("document.documentElement.scrollWidth <= window.innerWidth")
    context.close()


@pytest.mark.django_db(transaction=True)
@SIZES
def test_the_researcher_sends_the_suggested_decisions_to_prolific_through_a_dry_run(browser, live_server, settings,
                                                                                    size):
    study = reviewed_study()
    submissions = {f"sub-{pid}": {"id": f"sub-{pid}", "participant_id": pid, "study_id": "PS1",
                                  "status": "AWAITING REVIEW"} for pid in ("careful", "harsh", "stopped", "slip")}
    with ProlificStandIn(TOKEN, submissions) as prolific:
        settings.PROLIFIC_API_URL = prolific.url
        context, page = researcher_page(browser, live_server, study, size)
        page.goto(f"{live_server.url}{reverse('study-participants', args=[study.pk])}")
        page.get_by_role("link", name="Send the decisions and bonuses to Prolific").click()
        page.get_by_label("Prolific API token").fill(TOKEN)
        page.get_by_role("button", name="Keep for this session").click()
        assert "Your API token is kept" in page.inner_text("#credentials-kept")
        page.get_by_role("button", name="Dry run: list the requests").first.click()
        page.wait_for_url(f"**{reverse('study-platform-dry-run', args=[study.pk])}")  # h1 is on the page before too
        assert "Dry run: 4 requests to Prolific" in page.inner_text("h1") and prolific.requests == []
        plan = page.locator("#plan li").all()
        assert [item.locator("p.what").inner_text().strip() for item in plan] == [
            "approve · careful", "approve · harsh", "reject · stopped", "request return · slip"]
        assert '"rejection_category": "FAILED_CHECK"' in plan[2].locator("pre").inner_text()
        assert within_width(page, "#plan") and all(within_width(page, f"#plan li:nth-child({i}) pre") for i in (1, 3))
        assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth")
        page.get_by_role("checkbox", name="send reject stopped").uncheck()  # the researcher holds one back
        page.get_by_role("button", name="Send the ticked requests").click()
        results = table_rows(page, "#results")
        assert [(row["Participant"], row["Outcome"]) for row in results] == [
            ("careful", "sent"), ("harsh", "sent"), ("slip", "sent")]
        assert [request["path"] for request in prolific.sent()] == [
            "/api/v1/submissions/sub-careful/transition/", "/api/v1/submissions/sub-harsh/transition/",
            "/api/v1/submissions/sub-slip/request-return/"]
        page.get_by_role("link", name="Participants").last.click()
        sent = {row["Platform id"]: row["Sent"] for row in table_rows(page, "#participants")}
        assert sent == {"careful": "approve", "harsh": "approve", "stopped": "–", "slip": "request return"}
        context.close()
