"""A graded pairwise study (GENEA's five levels) end to end in a real browser (headless
Chromium): participants answer clearly, slightly or with no preference, and the
researcher's in-app report shows the leaderboard with its intervals and the heat maps."""

from __future__ import annotations

import pandas as pd
import pytest
from django.conf import settings as django_settings
from django.test import Client
from django.urls import reverse

from studyapp.models import Participant, Rating
from studyapp.researchers.results.reports import report_folder
from tests.study_fixtures import current_page, make_study
from tests.test_study_browser import browser, clip_video  # noqa: F401 (fixtures)
from tests.test_study_design_browser import CLIP_SECONDS, DESKTOP, play_every_clip

# Per participant, per page: (clip, strength label) or "none". The second one has no
# preference at all, so every pair has a tie and the leaderboard's fit exists.
ANSWERS = {"clear-and-slight": [("A", "clearly"), ("B", "slightly"), ("A", "slightly")],
           "undecided": ["none", "none", "none"]}


def answer_in_browser(browser, live_server, study, pid: str, answers: list) -> None:
    context = browser.new_context(**DESKTOP)
    page = context.new_page()
    page.goto(f"{live_server.url}/p/{study.key}/?PROLIFIC_PID={pid}&STUDY_ID=S1&SESSION_ID=X1")
    page.get_by_role("button", name="I agree to take part").click()
    page.get_by_role("button", name="Start").click()
    participant = Participant.objects.get(study=study, platform_id=pid)
    for answer in answers:
        clips = current_page(participant)
        page.wait_for_selector("video[data-slot]")
        strengths = page.locator('button[name="strength"]')
        assert strengths.all_inner_texts() == ["slightly", "clearly"]  # five levels with none
        play_every_clip(page)
        if answer == "none":
            page.get_by_role("button", name="No preference").click()
        else:
            clip, strength = answer
            page.get_by_role("button", name=f"{clip} is better").click()  # the choice first, then its strength
            page.get_by_role("button", name=strength, exact=True).click()
        page.wait_for_function(f"() => !document.body.innerHTML.includes('{clips[0].token}')")
    page.wait_for_load_state()  # the last page has arrived, but may not be all there yet
    assert study.completion_code in page.inner_text("body")
    context.close()


@pytest.mark.slow
@pytest.mark.django_db(transaction=True)
def test_a_graded_pairwise_study_answered_in_a_browser_reports_its_leaderboard_and_heat_maps(
        browser, live_server, clip_video, settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=1, design="pairwise",
                       pages_per_participant=3, preference_strengths=2, training_clips=0, bad_checks=0,
                       ratings_per_stimulus=10)
    for pid, answers in ANSWERS.items():
        answer_in_browser(browser, live_server, study, pid, answers)
    stored = sorted((r.answer, r.strength) for r in Rating.objects.filter(assignment__slot=1))
    assert stored == sorted([("left", 2), ("right", 1), ("left", 1)] + [("none", None)] * 3)

    researcher = Client()
    researcher.force_login(study.owner)
    response = researcher.post(reverse("study-report", args=[study.pk]))
    assert response.status_code == 302
    folder = report_folder(settings.MEDIA_ROOT, response["Location"].strip("/").split("/")[-1])
    for name in ("win_fraction", "battles"):
        assert (folder / "figures" / f"{name}.png").stat().st_size > 0
        assert (folder / "figures" / f"{name}.svg").stat().st_size > 0
    board = pd.read_csv(folder / "tables" / "leaderboard.csv")
    # Two participants are too few for a bootstrap: the board has its Elo ratings and says why it has no intervals.
    assert sorted(board["system"]) == ["MoGlow", "NAT", "RNN"] and board["resamples_used"].eq(0).all()
    assert board["ci_low"].isna().all()
    assert board["warning"].str.startswith("too few ratings: from 2 participants").all()

    # The report page in the browser: the leaderboard's table with its intervals, the heat maps drawn.
    context = browser.new_context(**DESKTOP)
    context.add_cookies([{"name": django_settings.SESSION_COOKIE_NAME, "value": researcher.cookies["sessionid"].value,
                          "url": live_server.url}])
    page = context.new_page()
    page.goto(f"{live_server.url}{response['Location']}")
    text = page.inner_text("body")
    assert "Leaderboard (bradley-terry): Elo with NAT at 1000, 400 points odds of 10 to 1" in text  # anchor, origin
    assert "95 % bootstrap intervals over participants" in text
    assert "a preference of strength k counts 2k wins of the preferred system" in text  # the summary's method
    table = page.locator("h2", has_text="Leaderboard (bradley-terry)").locator("xpath=following-sibling::div[1]")
    headers = table.locator("th").all_inner_texts()
    assert {"System", "elo", "CI low", "CI high"} <= set(headers), headers
    assert table.locator("tbody tr").count() == 3  # MoGlow, RNN, NAT
    assert "No intervals on the leaderboard for " in text and "a bootstrap interval needs at least" in text
    for name in ("win_fraction", "battles"):
        image = page.locator(f'img[src$="figures/{name}.svg"]')
        assert image.count() == 1 and image.evaluate("img => img.complete && img.naturalWidth > 0")
    context.close()
