"""End to end in a real browser: Debian's headless Chromium, driven by Playwright.

Three participants take a study from its entry link: one completes it properly (on a
phone-sized screen, answering with the keyboard), one rates a BAD clip highly and is
flagged excluded, one answers before a clip has finished and that rating is flagged
discarded. Then the researcher logs in and exports the ratings table, which must hold
exactly those ratings.
"""

from __future__ import annotations

import csv
import io
import os
import shutil
from pathlib import Path

import pytest
from django.urls import reverse

from tests.study_fixtures import current_clip
from studyapp.models import Participant, Rating, System
from tests.study_fixtures import make_study, render_clip_video

pytestmark = pytest.mark.slow

CLIP_SECONDS = 1.0
PASSWORD = "a-long-test-password"


def chromium_path() -> str:
    path = os.environ.get("CHROMIUM") or shutil.which("chromium")
    if not path:
        message = "Debian's chromium is not installed (scripts/ensure-chromium.sh installs it)"
        pytest.fail(message) if os.environ.get("CI") else pytest.skip(message)
    return path


@pytest.fixture(scope="session")
def clip_video(motion_data, tmp_path_factory) -> Path:
    bvh = motion_data / "data" / "dataset-1_walk_normal_001.bvh"
    return render_clip_video(bvh, tmp_path_factory.mktemp("video") / "clip.mp4", CLIP_SECONDS)


@pytest.fixture(scope="module")
def browser():
    """One headless Chromium for a module's tests (starting one costs about a second of
    CPU); each test opens a context of its own, with its own cookies, and closes it."""
    # Playwright's sync API runs an event loop in this thread; the ORM calls the tests
    # make between browser steps are still synchronous and safe.
    from playwright.sync_api import sync_playwright

    with pytest.MonkeyPatch.context() as patch, sync_playwright() as playwright:
        patch.setenv("DJANGO_ALLOW_ASYNC_UNSAFE", "true")
        # Without a GPU process: no page draws with WebGL, and SwiftShader's rasterising
        # costs more CPU than drawing in the renderer (about a tenth of a browser test's).
        browser = playwright.chromium.launch(executable_path=chromium_path(), args=["--no-sandbox", "--disable-gpu"])
        yield browser
        browser.close()


def wait_for_clip_end(page) -> None:
    """Wait until the clip has ended and, on a page that records it, its end is in the form
    (the "ended" event runs a moment after ``ended`` turns true)."""
    page.wait_for_function("""() => {
        const ended = document.querySelector("input[name=ended_s]");
        return document.getElementById("clip").ended && (!ended || ended.value !== "");
    }""", timeout=20_000)


def take_part(browser, live_server, study, pid: str, value_for, early_at: int | None = None,
              phone: bool = False, keyboard: bool = False) -> str:
    """Go through the study as participant ``pid``; ``value_for(role)`` picks each rating.

    ``early_at``: the position of the clip answered at once, before it has ended.
    Returns the text of the final page.
    """
    options = {"viewport": {"width": 390, "height": 844}, "is_mobile": True, "has_touch": True} if phone else {}
    context = browser.new_context(**options)
    page = context.new_page()
    page.goto(f"{live_server.url}/p/{study.key}/?PROLIFIC_PID={pid}&STUDY_ID=S1&SESSION_ID=X1")
    page.get_by_role("button", name="I agree to take part").click()
    page.get_by_role("button", name="Start").click()
    participant = Participant.objects.get(study=study, platform_id=pid)
    for number, _ in enumerate(participant.training, start=1):
        # Pages of clips follow each other without a reload: wait for the page, not for a load.
        page.wait_for_selector(f"text=/Practice \\w+ {number} of/")
        assert "not recorded" in page.content()
        wait_for_clip_end(page)
        page.get_by_role("button", name="3", exact=True).click()
    if phone:  # everything fits the width of a phone: no sideways scrolling
        assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth")
    while (assignment := current_clip(participant)) is not None:
        page.wait_for_selector(f"input[name=assignment][value='{assignment.token}']", state="attached")
        if assignment.position != early_at:
            wait_for_clip_end(page)
        value = str(value_for(assignment.stimulus.system.role))
        if keyboard:
            page.keyboard.press(value)
        else:
            page.get_by_role("button", name=value, exact=True).click()
        page.wait_for_load_state()
        page.wait_for_function(f"() => !document.body.innerHTML.includes('{assignment.token}')")
    page.wait_for_load_state()  # the last page has arrived, but may not be all there yet
    text = page.inner_text("body")
    context.close()
    return text


@pytest.mark.django_db(transaction=True)
def test_three_participants_and_the_researchers_export(browser, live_server, clip_video, settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path / "media"
    # Without the full-play rule, so that an early answer is stored and flagged (as data from other tools are).
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, clips_per_participant=4, training_clips=1,
                       bad_checks=1, natural_checks=1, ratings_per_stimulus=10, require_full_play=False)
    study.owner.is_staff = True  # the login page is the admin's
    study.owner.set_password(PASSWORD)
    study.owner.save()

    def moderate(role):
        return 1 if role == System.Role.BAD else 4

    done = take_part(browser, live_server, study, "good-1", moderate, phone=True, keyboard=True)
    assert "You have finished the study" in done and study.completion_code in done
    take_part(browser, live_server, study, "careless-2", lambda role: 5)
    take_part(browser, live_server, study, "hasty-3", moderate, early_at=1)

    good, careless, hasty = (Participant.objects.get(platform_id=p) for p in ("good-1", "careless-2", "hasty-3"))
    assert [p.finished_at is not None for p in (good, careless, hasty)] == [True, True, True]
    assert (good.excluded, careless.excluded, hasty.excluded) == (False, True, False)
    assert careless.exclusion_reason == "rated a BAD clip high"
    early = Rating.objects.filter(answered_before_end=True).select_related("assignment")
    assert [(r.assignment.participant_id, r.assignment.position) for r in early] == [(hasty.pk, 1)], [
        (r.assignment.position, r.answered_at - r.assignment.shown_at, r.client_started_s, r.client_ended_s,
         r.client_answered_s) for r in early]  # which clock flagged it

    # The researcher logs in through the login page and downloads the table.
    context = browser.new_context(accept_downloads=True)
    page = context.new_page()
    page.goto(f"{live_server.url}{reverse('login')}")
    page.fill("input[name=username]", study.owner.username)
    page.fill("input[name=password]", PASSWORD)
    page.click("input[type=submit]")
    response = page.request.get(f"{live_server.url}{reverse('study-export', args=[study.pk])}")
    assert response.status == 200
    rows = list(csv.DictReader(io.StringIO(response.text())))
    context.close()

    stored = Rating.objects.select_related("assignment__participant", "assignment__stimulus")
    assert sorted((r["participant"], r["stimulus"], int(r["value"])) for r in rows) == sorted(
        (r.assignment.participant.code, r.assignment.stimulus.token, r.value) for r in stored)
    assert len(rows) == 12
    by_participant = {p.code: p for p in (good, careless, hasty)}
    for row in rows:
        participant = by_participant[row["participant"]]
        assert (row["excluded_participant"] == "True") == participant.excluded
    assert sum(row["discarded_early"] == "True" for row in rows) == 1
