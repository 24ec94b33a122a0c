"""Crowd operations in a real browser (headless Debian Chromium, as test_study_browser drives it):
the rating buttons unlock only when the clip has played to its end, with the keyboard and on
a phone, and the server refuses an answer sent sooner than the clip lasts, whatever the page;
another session of a platform id cannot continue the first one's; the researcher's
participant list and its CSV."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import pytest
from django.urls import reverse

from studyapp.models import Participant, Rating, Stimulus
from studyapp.ratings import current_assignment
from tests.study_fixtures import make_study
from tests.test_study_browser import CLIP_SECONDS, PASSWORD, browser, clip_video, wait_for_clip_end  # noqa: F401 (fixtures)

PHONE = {"viewport": {"width": 390, "height": 844}, "is_mobile": True, "has_touch": True}


def first_clip(browser, live_server, study, pid: str, **context_options):
    """A new browser context past consent and instructions, on the first rated clip."""
    context = browser.new_context(**context_options)
    page = context.new_page()
    page.goto(f"{live_server.url}/p/{study.key}/?PROLIFIC_PID={pid}&STUDY_ID=S1&SESSION_ID=session-{pid}")
    page.get_by_role("button", name="I agree to take part").click()
    page.get_by_role("button", name="Start").click()
    page.wait_for_selector("#clip")
    return context, page


def on_screen(page) -> str:
    return page.get_attribute("input[name=assignment]", "value")


def scale_buttons_disabled(page) -> list[bool]:
    return page.eval_on_selector_all("button[name=value]", "buttons => buttons.map(b => b.disabled)")


@pytest.fixture()
def media(settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path / "media"


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("phone", [False, True], ids=["keyboard", "phone"])
def test_the_rating_buttons_unlock_when_the_clip_has_played_to_its_end(browser, live_server, clip_video, media, phone):
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, clips_per_participant=3, training_clips=0,
                       bad_checks=0, natural_checks=0)
    context, page = first_clip(browser, live_server, study, "unlock", **(PHONE if phone else {}))
    page.evaluate("() => { const v = document.getElementById('clip'); v.pause(); v.currentTime = 0; }")
    token = on_screen(page)
    assert scale_buttons_disabled(page) == [True] * 5 and page.is_visible("#lock-hint")
    if phone:
        page.tap("button[name=value][value='3']", force=True)  # a tap on a locked button
    else:
        page.keyboard.press("3")
    page.wait_for_timeout(300)
    assert on_screen(page) == token and Rating.objects.count() == 0
    page.evaluate("() => document.getElementById('clip').play()")
    wait_for_clip_end(page)
    assert scale_buttons_disabled(page) == [False] * 5 and not page.is_visible("#lock-hint")
    if phone:
        page.tap("button[name=value][value='3']")
    else:
        page.keyboard.press("3")
    page.wait_for_function(f"() => document.querySelector('input[name=assignment]')?.value !== '{token}'")
    rating = Rating.objects.get()
    assert rating.assignment.token == token and rating.value == 3 and not rating.answered_before_end
    context.close()


@pytest.mark.django_db(transaction=True)
def test_the_server_refuses_an_answer_sooner_than_the_clip_and_the_page_says_why(browser, live_server, clip_video,
                                                                                   media):
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, clips_per_participant=3, training_clips=0,
                       bad_checks=0, natural_checks=0)
    Stimulus.objects.update(duration_s=60.0)  # as if each clip lasted a minute: every answer here is too soon
    context, page = first_clip(browser, live_server, study, "speeder")
    token = on_screen(page)
    # A scripted client: the form posted straight away, with the times a finished clip would report.
    status = page.evaluate("""async () => {
        const form = new FormData(document.getElementById('rating-form'));
        form.set('value', '5'); form.set('started_s', '0.1'); form.set('ended_s', '60.2'); form.set('answered_s', '61');
        const response = await fetch(document.getElementById('rating-form').action, {method: 'POST', body: form});
        return response.status; }""")
    assert status == 409
    # Buttons unlocked by hand in the page: the refusal is a page of its own, which leads back to the clip.
    page.evaluate("() => document.querySelectorAll('button[name=value]').forEach(b => { b.disabled = false; })")
    page.click("button[name=value][value='4']")
    page.wait_for_selector("text=Please watch the clip to its end")
    assert "it lasts 60.0 s" in page.inner_text("body")
    page.get_by_role("link", name="Back to the study").click()
    page.wait_for_selector("#clip")
    assert on_screen(page) == token and Rating.objects.count() == 0
    participant = Participant.objects.get(platform_id="speeder")
    assert participant.refused_early == 2 and current_assignment(participant).token == token
    context.close()


def log_in(browser, live_server, user):
    user.set_password(PASSWORD)
    user.save()
    context = browser.new_context(accept_downloads=True)
    page = context.new_page()
    page.goto(f"{live_server.url}{reverse('login')}")
    page.fill("input[name=username]", user.username)
    page.fill("input[name=password]", PASSWORD)
    page.click("input[type=submit]")
    return context, page


@pytest.mark.django_db(transaction=True)
def test_another_session_of_the_same_prolific_id_cannot_continue_and_the_researcher_lists_both(
        browser, live_server, clip_video, media):
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, clips_per_participant=2, training_clips=0,
                       bad_checks=0, natural_checks=0)
    context, page = first_clip(browser, live_server, study, "P1")
    for _ in range(2):
        wait_for_clip_end(page)
        page.keyboard.press("4")
        page.wait_for_load_state()
    assert study.completion_code in page.inner_text("body")
    context.close()

    other = browser.new_context()
    intruder = other.new_page()
    response = intruder.goto(f"{live_server.url}/p/{study.key}/?PROLIFIC_PID=P1&STUDY_ID=S1&SESSION_ID=another")
    text = intruder.inner_text("body")
    assert response.status == 409 and "Already started elsewhere" in text and study.completion_code not in text
    assert intruder.goto(f"{live_server.url}/p/{study.key}/now/").status == 403
    other.close()

    context, page = log_in(browser, live_server, study.owner)
    page.goto(f"{live_server.url}{reverse('study-participants', args=[study.pk])}")
    cells = page.locator("#participants tr").nth(1).locator("td").all_inner_texts()
    assert cells[:3] == ["P1", "session-P1", "finished"] and cells[-1] == "approve"
    with page.expect_download() as download:
        page.get_by_role("link", name="Download as CSV").click()
    table = list(csv.DictReader(io.StringIO(Path(download.value.path()).read_text())))
    assert [(r["platform_id"], r["suggested_action"]) for r in table] == [("P1", "approve")]
    context.close()
