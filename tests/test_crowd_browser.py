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

from tests.study_fixtures import current_clip
from studyapp.models import Participant, Question, Rating, Stimulus
from tests.study_fixtures import make_study
from tests.test_study_browser import CLIP_SECONDS, PASSWORD, browser, clip_video, wait_for_clip_end  # noqa: F401 (fixtures)

pytestmark = pytest.mark.slow

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
    with page.expect_navigation():  # the page left has #clip and the token too
        page.get_by_role("link", name="Back to the study").click()
    page.wait_for_selector("#clip")
    assert on_screen(page) == token and Rating.objects.count() == 0
    participant = Participant.objects.get(platform_id="speeder")
    assert participant.refused_early == 2 and current_clip(participant).token == token
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
    for _ in range(2):  # the second page comes in place of the first; the end by navigation
        wait_for_clip_end(page)
        token = page.input_value("input[name=assignment]")
        page.keyboard.press("4")
        page.wait_for_load_state()
        page.wait_for_function(f"() => !document.body.innerHTML.includes('{token}')")
    page.wait_for_load_state()  # the end page has arrived, but may not be all there yet
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
    headers = page.locator("#participants tr").nth(0).locator("th").all_inner_texts()
    cells = dict(zip(headers, page.locator("#participants tr").nth(1).locator("td").all_inner_texts()))
    assert [cells["Platform id"], cells["Session"], cells["Status"]] == ["P1", "session-P1", "finished"]
    assert (cells["Analysis"], cells["Suggested payment"]) == ("kept", "approve")
    with page.expect_download() as download:
        page.get_by_role("link", name="Download as CSV").click()
    table = list(csv.DictReader(io.StringIO(Path(download.value.path()).read_text())))
    assert [(r["platform_id"], r["suggested_action"]) for r in table] == [("P1", "approve")]
    context.close()


@pytest.mark.django_db(transaction=True)
def test_a_clip_that_fails_to_load_says_so_and_plays_after_a_retry(browser, live_server, clip_video, media):
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, clips_per_participant=2, training_clips=0,
                       bad_checks=0, natural_checks=0)
    # Every clip file is missing when the participant arrives, and back before they retry.
    videos = [s.video_path() for s in Stimulus.objects.filter(study=study)]
    hidden = [path.rename(path.with_suffix(".gone")) for path in videos]
    context, page = first_clip(browser, live_server, study, "unlucky")
    page.wait_for_selector("#load-error", state="visible")
    assert "The clip did not load" in page.inner_text("#load-error")
    for away, path in zip(hidden, videos):
        away.rename(path)
    page.get_by_role("button", name="Try again").click()
    wait_for_clip_end(page)
    assert page.is_hidden("#load-error") and scale_buttons_disabled(page) == [False] * 5
    context.close()


@pytest.mark.django_db(transaction=True)
def test_the_next_clip_is_fetched_while_the_current_one_plays(browser, live_server, clip_video, media):
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, clips_per_participant=2, training_clips=0,
                       bad_checks=0, natural_checks=0)
    context = browser.new_context()
    page = context.new_page()
    requested: list[str] = []
    page.on("request", lambda request: requested.append(request.url))
    page.goto(f"{live_server.url}/p/{study.key}/?PROLIFIC_PID=ahead&STUDY_ID=S1&SESSION_ID=S")
    page.get_by_role("button", name="I agree to take part").click()
    page.get_by_role("button", name="Start").click()
    page.wait_for_selector("#clip")
    first, second = Participant.objects.get(platform_id="ahead").assignments.order_by("position")
    page.wait_for_function("() => document.getElementById('clip').readyState >= 2")
    page.wait_for_timeout(300)
    assert f"{live_server.url}{second.stimulus.video_url}" in requested  # before any answer
    assert on_screen(page) == first.token
    context.close()


@pytest.mark.django_db(transaction=True)
def test_a_stale_second_tab_moves_to_the_current_page(browser, live_server, clip_video, media):
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, clips_per_participant=2, training_clips=0,
                       bad_checks=0, natural_checks=0)
    context, page = first_clip(browser, live_server, study, "two-tabs")
    second_tab = context.new_page()
    second_tab.goto(f"{live_server.url}/p/{study.key}/now/")
    first_token = on_screen(second_tab)
    assert on_screen(page) == first_token
    wait_for_clip_end(page)
    page.keyboard.press("3")
    page.wait_for_function(f"() => document.querySelector('input[name=assignment]')?.value !== '{first_token}'")
    # The second tab, untouched, now shows the clip the first one moved on to.
    second_tab.wait_for_function(f"() => document.querySelector('input[name=assignment]')?.value !== '{first_token}'")
    assert on_screen(second_tab) == on_screen(page)
    context.close()


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("phone", [False, True], ids=["desktop", "phone"])
def test_the_code_copies_keys_are_offered_only_with_a_keyboard_and_the_clip_enlarges(browser, live_server, clip_video,
                                                                                     media, phone):
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, clips_per_participant=1, training_clips=0,
                       bad_checks=0, natural_checks=0)
    context, page = first_clip(browser, live_server, study, f"copy-{phone}", **(PHONE if phone else {}))
    assert page.is_visible("#keys-hint") == (not phone)
    page.evaluate("() => { const v = document.getElementById('clip'); v.pause(); v.currentTime = 0; }")
    page.get_by_role("button", name="Enlarge").click()
    page.wait_for_function("() => document.fullscreenElement?.id === 'stage'")
    page.evaluate("() => document.getElementById('clip').play()")
    wait_for_clip_end(page)
    page.wait_for_function("() => document.fullscreenElement === null")  # back to the buttons at the end
    page.get_by_role("button", name="3", exact=True).click()
    page.wait_for_selector("#copy-code")
    context.grant_permissions(["clipboard-read", "clipboard-write"], origin=live_server.url)
    page.get_by_role("button", name="Copy the code").click()
    page.wait_for_selector("text=Copied.")
    assert page.evaluate("() => navigator.clipboard.readText()") == study.completion_code
    context.close()


@pytest.mark.django_db(transaction=True)
def test_unknown_links_and_closed_studies_show_plain_pages(browser, live_server, settings):
    settings.DEBUG = True
    study = make_study(is_open=False)
    context = browser.new_context()
    page = context.new_page()
    response = page.goto(f"{live_server.url}/p/{study.key}/?PROLIFIC_PID=late")
    assert response.status == 404 and "This study is closed" in page.inner_text("body")
    response = page.goto(f"{live_server.url}/p/nothing-here/?PROLIFIC_PID=lost")
    assert response.status == 404 and "There is no study at this address" in page.inner_text("body")
    assert "Traceback" not in page.content() and "Django" not in page.content()
    context.close()


@pytest.mark.django_db(transaction=True)
def test_device_check_and_questionnaires_in_a_browser_and_the_answers_reach_the_export(browser, live_server,
                                                                                         clip_video, media):
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, clips_per_participant=1, training_clips=0,
                       bad_checks=0, natural_checks=0, device_check=True, min_screen_width=600, min_screen_height=300)
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="language",
                            text="Is English your first language?", choices="yes\nno", accepted="yes")
    Question.objects.create(study=study, part=Question.Part.AFTER, name="age", text="How old are you?",
                            kind=Question.Kind.NUMBER)
    link = f"{live_server.url}/p/{study.key}/?PROLIFIC_PID=%s&STUDY_ID=S1&SESSION_ID=S"

    phone = browser.new_context(**PHONE)  # 390 pixels wide: too narrow for this study
    page = phone.new_page()
    page.goto(link % "narrow")
    wait_for_clip_end(page)
    assert page.is_disabled("#device-ok") and "at least 600 × 300 pixels" in page.inner_text("#device-problem")
    phone.close()

    context = browser.new_context(viewport={"width": 1024, "height": 768})
    page = context.new_page()
    page.goto(link % "wide")
    wait_for_clip_end(page)
    page.get_by_role("button", name="Continue").click()
    page.get_by_role("button", name="I agree to take part").click()
    page.get_by_label("yes").check()
    page.get_by_role("button", name="Continue").click()
    page.get_by_role("button", name="Start").click()
    page.wait_for_selector("#clip")  # wait_for_clip_end throws on a page without it
    wait_for_clip_end(page)
    page.keyboard.press("4")
    page.get_by_label("How old are you?").fill("37")
    page.get_by_role("button", name="Continue").click()
    page.wait_for_selector("#completion-code")  # "body" is on the questions page too
    assert study.completion_code in page.inner_text("body")
    context.close()

    context, page = log_in(browser, live_server, study.owner)
    with page.expect_download() as download:
        page.goto(f"{live_server.url}{reverse('study-participants', args=[study.pk])}")
        page.get_by_role("link", name="Download as CSV").click()
    table = list(csv.DictReader(io.StringIO(Path(download.value.path()).read_text())))
    assert [(r["platform_id"], r["status"], r["answer_language"], r["answer_age"]) for r in table] == [
        ("narrow", "in progress", "", ""), ("wide", "finished", "yes", "37")]  # an age: a whole number
    context.close()


@pytest.mark.django_db(transaction=True)
def test_the_researcher_previews_as_a_participant_and_nothing_is_recorded(browser, live_server, clip_video, media):
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, is_open=False)
    context, page = log_in(browser, live_server, study.owner)
    page.goto(f"{live_server.url}{reverse('study-monitor', args=[study.pk])}")
    page.get_by_role("link", name="Preview").click()
    page.get_by_role("button", name="I agree to take part").click()
    page.get_by_role("button", name="Start").click()
    for name in ("practice", "a page to rate"):  # practice is the rating page too, not recorded
        page.wait_for_selector(f"text=({name})")
        wait_for_clip_end(page)
        page.keyboard.press("4")
    page.wait_for_selector("text=You have finished the study")
    assert "Preview 5 of 5" in page.inner_text(".preview-banner")
    assert (Participant.objects.count(), Rating.objects.count()) == (0, 0)
    context.close()


@pytest.mark.django_db(transaction=True)
def test_the_researchers_pages_fit_a_phone(browser, live_server):
    study = make_study(title="A study with a long title that must wrap rather than push the page sideways")
    study.owner.set_password(PASSWORD)
    study.owner.save()
    context = browser.new_context(**PHONE)
    page = context.new_page()
    page.goto(f"{live_server.url}{reverse('login')}")
    page.fill("input[name=username]", study.owner.username)
    page.fill("input[name=password]", PASSWORD)
    page.click("input[type=submit]")
    for view, args in (("study-list", []), ("study-monitor", [study.pk]), ("study-participants", [study.pk]),
                       ("study-edit", [study.pk]),
                       ("study-item-edit", [study.pk, "systems", study.systems.first().pk])):
        page.goto(f"{live_server.url}{reverse(view, args=args)}")
        assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth"), view
    context.close()
