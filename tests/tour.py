"""The screenshots of docs/running-a-study.md, taken by the tests' browser: `make tour`.

Not part of the test run (its name does not start with test_): it builds a small study
on real motion capture, goes through it as a researcher and as participants on a desktop
and a phone, and writes each page to docs/tour/ (or $TOUR_DIR), so that the tour always
shows the pages as they are.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from django.urls import reverse

from studyapp.models import Participant, Question
from tests.study_fixtures import make_study
from tests.test_crowd_browser import PHONE
from tests.test_study_browser import CLIP_SECONDS, PASSWORD, browser, clip_video, wait_for_clip_end  # noqa: F401 (fixtures)

OUT = Path(os.environ.get("TOUR_DIR", Path(__file__).resolve().parents[1] / "docs" / "tour"))
DESKTOP = {"viewport": {"width": 1200, "height": 800}}


def shot(page, name: str) -> None:
    page.screenshot(path=OUT / f"{name}.jpg", type="jpeg", quality=85)


@pytest.mark.django_db(transaction=True)
def test_tour(browser, live_server, clip_video, settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path / "media"
    OUT.mkdir(parents=True, exist_ok=True)
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, clips_per_participant=3, training_clips=1,
                       bad_checks=1, natural_checks=0, device_check=True, min_screen_width=360, min_screen_height=500,
                       title="Naturalness of generated locomotion")
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="vision",
                            text="Do you have normal or corrected-to-normal vision?", choices="yes\nno", accepted="yes")
    Question.objects.create(study=study, part=Question.Part.AFTER, name="comments", text="Any comments on the study?",
                            kind=Question.Kind.TEXT, required=False)
    link = f"{live_server.url}/p/{study.key}/?PROLIFIC_PID=%s&STUDY_ID=S1&SESSION_ID=%s"

    # A participant on a phone, from the device check to the completion code.
    context = browser.new_context(**PHONE)
    page = context.new_page()
    page.goto(link % ("phone-1", "s1"))
    wait_for_clip_end(page)
    shot(page, "participant-device-check")
    page.get_by_role("button", name="Continue").click()
    shot(page, "participant-consent")
    page.get_by_role("button", name="I agree to take part").click()
    page.get_by_label("yes").check()
    shot(page, "participant-screening")
    page.get_by_role("button", name="Continue").click()
    page.get_by_role("button", name="Start").click()
    for clip in range(1 + study.clips_per_participant):  # the practice clip, then the rated ones
        page.wait_for_selector("#clip")
        page.evaluate("() => { const v = document.getElementById('clip'); v.pause(); v.currentTime = 0.5; }")
        if clip == 1:
            shot(page, "participant-clip-locked")
        # From the start again: the server refuses an answer sooner after the page than the clip lasts.
        page.evaluate("() => { const v = document.getElementById('clip'); v.currentTime = 0; v.play(); }")
        wait_for_clip_end(page)
        token = page.input_value("input[name=assignment]")
        page.tap("button[name=value][value='4']")  # the next clip's page comes in place, the last by navigation
        page.wait_for_load_state()
        page.wait_for_function(f"() => !document.body.innerHTML.includes('{token}')")
    page.get_by_role("button", name="Continue").click()
    shot(page, "participant-done")
    context.close()

    # The same study on a desktop, answered with the keyboard.
    context = browser.new_context(**DESKTOP)
    page = context.new_page()
    page.goto(link % ("desktop-2", "s2"))
    wait_for_clip_end(page)
    page.get_by_role("button", name="Continue").click()
    page.get_by_role("button", name="I agree to take part").click()
    page.get_by_label("yes").check()
    page.get_by_role("button", name="Continue").click()
    page.get_by_role("button", name="Start").click()
    wait_for_clip_end(page)
    shot(page, "participant-clip-desktop")
    context.close()
    assert Participant.objects.filter(study=study).count() == 2

    # The researcher's pages.
    study.owner.set_password(PASSWORD)
    study.owner.save()
    context = browser.new_context(**DESKTOP)
    page = context.new_page()
    page.goto(f"{live_server.url}{reverse('login')}")
    shot(page, "researcher-login")
    page.fill("input[name=username]", study.owner.username)
    page.fill("input[name=password]", PASSWORD)
    page.click("input[type=submit]")
    for name, view in (("study-list", "study-list"), ("settings", "study-edit"), ("systems", "study-systems"),
                       ("stimuli", "study-stimuli"), ("questions", "study-questions"), ("preview", "study-preview"),
                       ("monitor", "study-monitor"), ("participants", "study-participants")):
        page.goto(f"{live_server.url}{reverse(view, args=[] if view == 'study-list' else [study.pk])}")
        shot(page, f"researcher-{name}")
    context.close()
