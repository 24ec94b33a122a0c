"""One request per answer in a real browser (headless Chromium), for every design, on a
desktop and on a phone.

A participant goes through several pages: between them the document is never loaded
anew (a mark left on the window at the first page survives to the last), each page's
next clips were requested from the server and loaded before the answer, and the page
that follows shows those very video elements (nothing fetched again). An answer forced
before the clips have played is refused by the server (409) through the script, and the
page says so and stays; the last answer leads to the completion page by navigation. The
database holds each rating exactly once.
"""

from __future__ import annotations

import pytest

from studyapp.models import Participant, Rating, Stimulus, Study
from tests.appropriateness_fixtures import make_appropriateness_study
from tests.study_fixtures import current_page, make_study
from tests.test_study_browser import browser, clip_video  # noqa: F401 (fixtures)
from tests.test_study_design_browser import PHONE, play_every_clip

CLIP_SECONDS = 1.0
DESKTOP = {"viewport": {"width": 1366, "height": 768}}
DESIGNS = {
    "single": {"clips_per_participant": 4},
    "side-by-side": {"design": "side-by-side", "scale_min": 0, "scale_max": 100, "pages_per_participant": 3},
    "pairwise": {"design": "pairwise", "pages_per_participant": 3},
    "pairwise graded": {"design": "pairwise", "pages_per_participant": 3, "preference_strengths": 3},
    "appropriateness": {"design": "appropriateness", "pages_per_participant": 3},
}
UPCOMING_LOADED = ("() => { const next = [...document.querySelectorAll('video[data-upcoming]')];"
                   " return next.length > 0 && next.every((v) => v.readyState >= HTMLMediaElement.HAVE_ENOUGH_DATA); }")


def study_of(design: str, video) -> Study:
    fields = {**DESIGNS[design], "training_clips": 0, "ratings_per_stimulus": 10}
    if fields.get("design") == "appropriateness":
        return make_appropriateness_study(video=video, clip_seconds=CLIP_SECONDS, **fields)
    return make_study(video=video, clip_seconds=CLIP_SECONDS, controls=3, **fields)


def on_screen(page, token: str) -> None:
    page.wait_for_selector(f"main input[type=hidden][value='{token}']", state="attached")


def play_and_answer(page, study: Study) -> None:
    if study.design == "single":
        page.wait_for_function("() => document.getElementById('clip').ended", timeout=20_000)
        page.locator("#rating-form button[value='3']").click()
        return
    play_every_clip(page)
    if study.design == "side-by-side":
        move_every_slider(page)
        page.locator("#page-form button[type=submit]").click()
        return
    page.locator("#page-form button[name=answer][value=left]").click()
    strengths = page.locator("#page-form button[name=strength]")
    if strengths.count():  # asked once the choice is made; its button sends the answer
        strengths.first.click()


def move_every_slider(page) -> None:
    """Move each clip's slider as a participant does (on a phone most sit in hidden tabs)."""
    page.evaluate("document.querySelectorAll('input[type=range]').forEach((slider) => {"
                  " slider.value = 70; slider.dispatchEvent(new Event('input', {bubbles: true})); })")


def answer_too_soon(page) -> None:
    """Unlock the answer buttons and answer at once, as a participant forcing the page would."""
    move_every_slider(page)
    page.evaluate("document.querySelectorAll('form[data-next-page] button').forEach((b) => { b.disabled = false; })")
    page.locator("form[data-next-page] button[type=submit]").first.click()
    strengths = page.locator("form[data-next-page] button[name=strength]")
    if strengths.count():  # A chosen: how strong, which sends the answer
        strengths.first.click()


@pytest.mark.slow
@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("screen", [DESKTOP, PHONE], ids=["desktop", "phone"])
@pytest.mark.parametrize("design", DESIGNS)
def test_pages_follow_each_other_without_a_reload_their_next_clips_already_loaded(
        browser, live_server, clip_video, settings, tmp_path, design, screen):  # noqa: F811
    settings.MEDIA_ROOT = tmp_path / "media"
    study = study_of(design, clip_video)
    context = browser.new_context(**screen)
    page = context.new_page()
    requested: list[str] = []
    page.on("request", lambda request: requested.append(request.url))
    page.goto(f"{live_server.url}/p/{study.key}/?PROLIFIC_PID=p1&STUDY_ID=S1&SESSION_ID=X1")
    page.get_by_role("button", name="I agree to take part").click()
    page.get_by_role("button", name="Start").click()
    participant = Participant.objects.get(study=study)
    pages = participant.assignments.values("page").distinct().count()
    assert pages >= 3

    clips = current_page(participant)
    on_screen(page, clips[0].token)
    page.wait_for_load_state()  # next-page.js set up, or the forced answer below is posted as a plain form
    page.evaluate("window.loadedOnce = true")  # gone if the document is ever loaded anew
    # Too soon by the server's clock however slow this machine is: the clips last a minute while it answers.
    first = Stimulus.objects.filter(assignments__in=clips)
    first.update(duration_s=60.0)
    answer_too_soon(page)
    page.get_by_role("alert").filter(has_text="Please watch").wait_for()
    first.update(duration_s=CLIP_SECONDS)
    assert page.evaluate("window.loadedOnce") is True
    assert Participant.objects.get(pk=participant.pk).refused_early == 1 and Rating.objects.count() == 0

    for number in range(1, pages + 1):
        clips = current_page(participant)
        on_screen(page, clips[0].token)
        assert page.evaluate("window.loadedOnce") is True  # swapped in, not loaded
        assert page.inner_text("p.meta").endswith(f"{number} of {pages}")
        if number > 1:  # these very elements had loaded their clips while the page before played
            assert page.eval_on_selector_all("main video:not([data-upcoming])",
                                             "videos => videos.every((v) => v.loadedBefore)")
        if number < pages:
            page.wait_for_function(UPCOMING_LOADED, timeout=20_000)
            upcoming = [clip.stimulus.video_url for clip in current_page_after(participant)]
            assert all(any(url.endswith(video) for url in requested) for video in upcoming)
            page.evaluate("document.querySelectorAll('video[data-upcoming]').forEach((v) => { v.loadedBefore = true; })")
        if screen is PHONE:
            assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth")
        play_and_answer(page, study)
        page.wait_for_function(f"() => !document.querySelector('main input[value=\"{clips[0].token}\"]')")

    page.wait_for_selector(f"text={study.completion_code}")  # the end, by navigation
    assert page.evaluate("window.loadedOnce") is None
    context.close()
    stored = Rating.objects.filter(assignment__participant=participant)
    assert stored.count() == participant.assignments.count() == stored.values("assignment").distinct().count()
    assert Participant.objects.get(pk=participant.pk).refused_early == 1
    assert not stored.filter(answered_before_end=True).exists()


def current_page_after(participant: Participant):
    """The clips of the page after the one on screen."""
    pages = sorted({a.page for a in participant.assignments.filter(rating__isnull=True)})
    return list(participant.assignments.filter(page=pages[1]).select_related("stimulus")) if len(pages) > 1 else []
