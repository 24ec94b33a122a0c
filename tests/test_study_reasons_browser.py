"""Reasons with the votes end to end in a real browser (headless Chromium): participants
tick reasons by their labels and write their own under "Other" on a pairwise study that
requires one; the researcher's export carries them in GENEA's columns, GENEA's vote file
written from it keeps them, and the in-app report shows each system's reason counts as a
table and a grouped bar chart."""

from __future__ import annotations

import csv
import io
from collections import Counter

import pandas as pd
import pytest
from django.conf import settings as django_settings
from django.test import Client
from django.urls import reverse

from analysis.cli import main
from analysis.reports.reasons import read_options
from studyapp.models import Participant, Rating
from studyapp.researchers.results.reports import report_folder
from tests.study_fixtures import current_page, make_study
from tests.test_study_browser import browser, clip_video  # noqa: F401 (fixtures)
from tests.test_study_design_browser import CLIP_SECONDS, DESKTOP, play_every_clip

REASONS = ["Motion smoothness", "Recognisable gestures", "Unrealistic motion", "Amount of motion"]
# Per participant, per page: the clip preferred ("none": no preference), the reasons ticked, the words under "Other".
ANSWERS = {
    "first": [("A", ["Motion smoothness"], ""), ("B", ["Motion smoothness", "Amount of motion"], ""),
              ("none", ["Unrealistic motion"], "")],
    "second": [("A", [], "the <b>arms</b> look stiff"), ("B", ["Recognisable gestures"], ""),
               ("A", ["Motion smoothness"], "")],
}


def answer_in_browser(browser, live_server, study, pid: str, answers: list) -> None:
    context = browser.new_context(**DESKTOP)
    page = context.new_page()
    page.goto(f"{live_server.url}/p/{study.key}/?PROLIFIC_PID={pid}&STUDY_ID=S1&SESSION_ID=X1")
    page.get_by_role("button", name="I agree to take part").click()
    page.get_by_role("button", name="Start").click()
    participant = Participant.objects.get(study=study, platform_id=pid)
    for number, (clip, ticked, other) in enumerate(answers):
        clips = current_page(participant)
        page.wait_for_selector("video[data-slot]")
        play_every_clip(page)
        button = "No preference" if clip == "none" else f"{clip} is better"
        if number == 0:  # a reason is required: the answer without one is refused and the page stays
            page.get_by_role("button", name=button).click()
            page.wait_for_selector("text=please tick at least one reason for your answer")
            assert not Rating.objects.filter(assignment__participant=participant).exists()
        for reason in ticked:  # each checkbox found by its label, as a screen reader names it
            page.get_by_role("checkbox", name=reason, exact=True).check()
        if other:
            page.get_by_role("checkbox", name="Other", exact=True).check()
            page.get_by_label("In your own words").fill(other)
        page.get_by_role("button", name=button).click()
        page.wait_for_function(f"() => !document.body.innerHTML.includes('{clips[0].token}')")
    page.wait_for_load_state()  # the last page has arrived, but may not be all there yet
    assert study.completion_code in page.inner_text("body")
    context.close()


@pytest.mark.slow
@pytest.mark.django_db(transaction=True)
def test_reasons_ticked_in_a_browser_reach_the_export_the_genea_file_and_the_reports_counts_and_plot(
        browser, live_server, clip_video, settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path / "media"
    study = make_study(video=clip_video, clip_seconds=CLIP_SECONDS, controls=1, design="pairwise",
                       pages_per_participant=3, training_clips=0, bad_checks=0, ratings_per_stimulus=10,
                       reasons="\n".join(REASONS), reasons_required=True)
    for pid, answers in ANSWERS.items():
        answer_in_browser(browser, live_server, study, pid, answers)

    # Stored with every rating of its page; "Other"'s words as plain text.
    expected = Counter()
    for rating in Rating.objects.filter(assignment__slot=1).select_related("assignment__participant"):
        pid, page = rating.assignment.participant.platform_id, rating.assignment.page
        clip, ticked, other = ANSWERS[pid][page]
        assert (rating.answer, rating.reasons) == ({"A": "left", "B": "right", "none": "none"}[clip], ticked)
        assert rating.other_reason == ("the arms look stiff" if other else "")
        if clip != "none":  # a reason counts for the system the vote chose
            chosen = system_at(rating.assignment.participant, page, 1 if clip == "A" else 2)
            expected.update((chosen, reason) for reason in ticked + (["Other"] if other else []))
    assert Rating.objects.count() == 12

    researcher = Client()
    researcher.force_login(study.owner)
    exported = researcher.get(reverse("study-export", args=[study.pk])).content.decode()
    rows = list(csv.DictReader(io.StringIO(exported)))
    assert {read_options(r["juiceOptions"]).count("Other") for r in rows} == {0, 1}
    assert {r["juiceOtherReason"] for r in rows} == {"", "the arms look stiff"}
    (tmp_path / "ratings.csv").write_text(exported)
    assert main(["genea-votes", str(tmp_path / "ratings.csv"), "--out", str(tmp_path / "genea")]) == 0
    votes = pd.read_csv(tmp_path / "genea" / "votes_genea.csv", dtype=str, keep_default_na=False)
    assert list(votes.columns)[-2:] == ["juiceOptions", "juiceOtherReason"] and len(votes) == 6
    assert sorted(votes["juiceOtherReason"]) == [""] * 5 + ["the arms look stiff"]

    response = researcher.post(reverse("study-report", args=[study.pk]))
    assert response.status_code == 302
    folder = report_folder(settings.MEDIA_ROOT, response["Location"].strip("/").split("/")[-1])
    counts = pd.read_csv(folder / "tables" / "reasons.csv")
    assert {(r.system, r.reason): r.count for r in counts.itertuples() if r.count} == dict(expected)
    tie = counts[counts["reason"] == "Unrealistic motion"].set_index("system")["ties"]
    assert tie.sum() == 2 and counts["count"].sum() == sum(expected.values())  # the tie: its two systems, apart

    context = browser.new_context(**DESKTOP)
    context.add_cookies([{"name": django_settings.SESSION_COOKIE_NAME, "value": researcher.cookies["sessionid"].value,
                          "url": live_server.url}])
    page = context.new_page()
    page.goto(f"{live_server.url}{response['Location']}")
    table = page.locator("h2", has_text="Reasons given per system").locator("xpath=following-sibling::div[1]")
    assert table.locator("tbody tr").count() == len(counts)
    image = page.locator('img[src$="figures/reasons.svg"]')
    assert image.count() == 1 and image.evaluate("img => img.complete && img.naturalWidth > 0")
    context.close()


def system_at(participant: Participant, page: int, slot: int) -> str:
    """The system of the clip at ``slot`` of the participant's ``page`` (as the export names it)."""
    return participant.assignments.get(page=page, slot=slot).stimulus.system.export_name
