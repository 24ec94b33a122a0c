"""Every researcher page in a real browser (headless Debian Chromium), on a desktop
(1366×768) and a phone (390×844): nothing is wider than the screen, so no page needs
sideways scrolling. With $SHOTS_DIR set, each page is also saved there as a PNG, to be
looked at."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from django.urls import reverse

from studyapp.models import Assignment, Participant, Question, Rating
from tests.study_fixtures import make_study
from tests.test_study_browser import PASSWORD, browser  # noqa: F401 (fixture)

DESKTOP = {"viewport": {"width": 1366, "height": 768}}
PHONE = {"viewport": {"width": 390, "height": 844}, "is_mobile": True, "has_touch": True}
SHOTS = os.environ.get("SHOTS_DIR")


def rated_study():
    """A study with questions and a few participants' ratings, so that every table has rows."""
    study = make_study(controls=2, ratings_per_stimulus=2, title="Naturalness of generated locomotion, held-out paths")
    study.owner.set_password(PASSWORD)
    study.owner.save()
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="vision",
                            text="Do you have normal or corrected-to-normal vision?", choices="yes\nno", accepted="yes")
    Question.objects.create(study=study, part=Question.Part.AFTER, name="comments", text="Any comments?",
                            kind=Question.Kind.TEXT, required=False)
    for i, stimulus in enumerate(study.stimuli.order_by("pk")):
        participant = Participant.objects.get_or_create(study=study, platform_id=f"6543a1b2c3d4e5f6{i % 3:08d}")[0]
        assignment = Assignment.objects.create(participant=participant, stimulus=stimulus, position=i, page=i)
        Rating.objects.create(assignment=assignment, value=1 + (i * 7) % 5, client_answered_s=5.0, played_until_s=4.0)
    return study


def researcher_urls(study) -> dict[str, str]:
    system, control = study.systems.get(name="RNN"), study.controls.first()
    per_study = ("study-edit", "study-systems", "study-controls", "study-stimuli", "study-questions", "study-monitor",
                 "study-participants")
    return {
        "study-list": reverse("study-list"), "study-create": reverse("study-create"),
        **{name: reverse(name, args=[study.pk]) for name in per_study},
        "study-preview": reverse("study-preview-page", args=[study.pk, 4]),
        "edit-system": reverse("study-item-edit", args=[study.pk, "systems", system.pk]),
        "edit-control": reverse("study-item-edit", args=[study.pk, "controls", control.pk]),
        "analysis": reverse("analysis"), "gallery": reverse("gallery"), "health": reverse("health"),
    }


def log_in(context, live_server, study):
    page = context.new_page()
    page.goto(f"{live_server.url}{reverse('login')}")
    page.fill("input[name=username]", study.owner.username)
    page.fill("input[name=password]", PASSWORD)
    page.click("input[type=submit]")
    return page


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("device", ["desktop", "phone"])
def test_every_researcher_page_fits_the_screen(browser, live_server, settings, tmp_path, device):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = rated_study()
    context = browser.new_context(**(PHONE if device == "phone" else DESKTOP))
    page = log_in(context, live_server, study)
    too_wide = {}
    for name, url in researcher_urls(study).items():
        response = page.goto(f"{live_server.url}{url}")
        assert response.status == 200, name
        if SHOTS:
            Path(SHOTS).mkdir(parents=True, exist_ok=True)
            page.screenshot(path=f"{SHOTS}/{name}-{device}.png", full_page=True)
        width = page.evaluate("document.documentElement.scrollWidth")
        if width > page.viewport_size["width"]:
            too_wide[name] = width
    context.close()
    assert too_wide == {}
