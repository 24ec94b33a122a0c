"""A leaderboard of three rounds end to end in a real browser (headless Chromium): the
researcher logs in, creates the board and adds each pairwise study as a round while the
rounds run; participants answer each round in the browser (the second round, which adds
VAE and ERD, is planned by adaptive pairing against the board); the board's table, downloaded,
equals a weighted logistic regression of every round's votes; a round is left out with a
reason; the public page, turned on, shows the board and no participant data.
Screenshots of both pages (desktop and phone) go to ``ROUNDS_SHOTS`` when it is set."""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from django.urls import reverse

from studyapp.leaderboards.models import Leaderboard, Round
from studyapp.models import Assignment, Participant, Stimulus
from tests.study_fixtures import make_study
from tests.test_leaderboard_rounds import NEW, OLD, logistic_elo, store_round_votes, stored_votes
from tests.test_study_browser import PASSWORD, browser, clip_video  # noqa: F401,F811 (fixtures)
from tests.test_study_design_browser import CLIP_SECONDS, PHONE
from tests.test_study_leaderboard_browser import answer_in_browser

pytestmark = pytest.mark.slow

DESKTOP = {"viewport": {"width": 1366, "height": 800}}
ANSWERS = [("A", "clearly"), ("B", "slightly"), "none"]


def shoot(page, name: str) -> None:
    folder = os.environ.get("ROUNDS_SHOTS")
    if folder:
        Path(folder).mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(Path(folder) / f"{name}.png"), full_page=True)


def round_study(number: int, systems, video, **fields):
    return make_study(title=f"Round {number} of locomotion", design="pairwise", controls=3, systems=systems,
                      video=video, clip_seconds=CLIP_SECONDS, pages_per_participant=len(ANSWERS),
                      preference_strengths=2, bad_checks=0, training_clips=0, ratings_per_stimulus=10, **fields)


def add_round(page, study) -> None:
    page.select_option("#id_study", label=str(study))
    page.get_by_role("button", name="Add round").click()
    page.wait_for_selector(f"text=Added {study.title} as round")


def browser_pages(study, pid: str) -> list[set[str]]:
    participant = Participant.objects.get(study=study, platform_id=pid)
    pages: dict[int, set[str]] = {}
    for a in Assignment.objects.filter(participant=participant).select_related("stimulus__system"):
        pages.setdefault(a.page, set()).add(a.stimulus.system.name)
    return list(pages.values())


@pytest.mark.django_db(transaction=True)
def test_a_leaderboard_of_three_rounds_runs_end_to_end_and_its_public_page_shows_no_participant_data(
        browser, live_server, clip_video, settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path / "media"
    first = round_study(1, OLD, clip_video)
    second = round_study(2, OLD + NEW, clip_video, adaptive_pairing=True)
    third = round_study(3, OLD + NEW, clip_video)
    owner = first.owner
    owner.is_staff = True
    owner.set_password(PASSWORD)
    owner.save()

    researcher = browser.new_context(**DESKTOP)
    page = researcher.new_page()
    page.goto(f"{live_server.url}{reverse('login')}")
    page.fill("input[name=username]", owner.username)
    page.fill("input[name=password]", PASSWORD)
    page.get_by_role("button", name="Log in").click()
    page.goto(f"{live_server.url}{reverse('study-list')}")
    page.get_by_role("link", name="Leaderboards").click()
    page.fill("#id_title", "Locomotion leaderboard")
    page.get_by_role("button", name="Create leaderboard").click()
    page.wait_for_selector("text=Created Locomotion leaderboard")
    board = Leaderboard.objects.get()
    assert board.owner == owner and not board.public
    board_url = page.url

    # Round 1: the three old systems, one participant in the browser and others before them.
    add_round(page, first)
    store_round_votes(first, seed=1, participants=8)
    answer_in_browser(browser, live_server, first, "browser-pid-1", ANSWERS)
    # Round 2 adds VAE and ERD; its pages are planned against the board's votes from the first participant on.
    add_round(page, second)
    answer_in_browser(browser, live_server, second, "browser-pid-2", ANSWERS)
    assert sum(bool(systems & {"VAE", "ERD"}) for systems in browser_pages(second, "browser-pid-2")) >= 2
    store_round_votes(second, seed=2)
    add_round(page, third)
    store_round_votes(third, seed=3)
    answer_in_browser(browser, live_server, third, "browser-pid-3", ANSWERS)

    page.goto(board_url)
    rows = page.locator("#board-systems tbody tr")
    assert rows.count() == 5
    text = page.inner_text("#board-systems")
    assert "round 2, " in text and "round 1, " in text
    vae = page.locator("#board-systems tbody tr", has_text="VAE").inner_text()
    assert "round 2, " in vae
    assert page.locator("#board-rounds tbody tr").count() == 3
    assert "ERD, VAE" in page.locator("#board-rounds tbody tr").nth(1).inner_text()
    with page.expect_download() as download:
        page.get_by_role("link", name="Download the table (CSV)").click()
    table = pd.read_csv(download.value.path())
    reference = logistic_elo(stored_votes(Round.objects.order_by("added")))
    ours = table.set_index("system")["elo"]
    np.testing.assert_allclose(ours[reference.index], reference, atol=1e-4)
    assert sorted(reference.index) == ["ERD", "MoGlow", "NAT", "RNN", "VAE"]
    shoot(page, "researcher-board-desktop")

    # Round 3 left out, with its reason; the board says so.
    third_round = Round.objects.get(study=third)
    page.locator(f"#id_round-{third_round.pk}-in_fit").uncheck()
    page.fill(f"#id_round-{third_round.pk}-left_out_because", "its clips were rendered with the old camera")
    with page.expect_navigation():  # the page before has the text too (a help text), and a long page arrives in parts
        page.get_by_role("button", name="Save round 3").click()
    page.wait_for_selector("text=is left out of the fit")
    assert "left out: its clips were rendered with the old camera" in page.inner_text("#board-rounds")

    # The public page, turned on: what the researcher's page previews, read without logging in.
    assert "The public page is off" in page.inner_text("#public-state")
    page.locator("#id_public").check()
    with page.expect_navigation():  # the preview, below the link, may not have arrived with it
        page.get_by_role("button", name="Save settings").click()
    page.wait_for_selector("#public-link")
    public_url = page.locator("#public-link").get_attribute("href")
    preview = page.inner_text("#public-preview")
    shoot(page, "researcher-board-desktop")
    visitor = browser.new_context(**DESKTOP)
    public = visitor.new_page()
    public.goto(public_url)
    assert public.inner_text("#public-board") == preview
    assert public.locator("#board-systems tbody tr").count() == 5
    assert "Elo with NAT at 1000" in public.inner_text("#board-scale")
    image = public.locator("#public-board img")
    assert image.evaluate("img => img.complete && img.naturalWidth > 0")
    assert "left out: its clips were rendered with the old camera" in public.inner_text("#board-rounds")
    with public.expect_download() as download:
        public.get_by_role("link", name="Download the table (CSV)").click()
    csv_text = Path(download.value.path()).read_text()
    assert sorted(pd.read_csv(io.StringIO(csv_text))["system"]) == ["ERD", "MoGlow", "NAT", "RNN", "VAE"]
    html = public.content()
    secrets = [*Participant.objects.values_list("platform_id", flat=True),
               *Participant.objects.values_list("code", flat=True), *Stimulus.objects.values_list("token", flat=True),
               first.key, second.key, third.key, "browser-pid", "secret-pid"]
    for secret in secrets:
        assert secret not in html and secret not in csv_text, secret
    shoot(public, "public-board-desktop")
    phone = browser.new_context(**PHONE)
    for name, url, context in (("public-board-phone", public_url, phone), ("researcher-board-phone", board_url, None)):
        if context is None:
            context = browser.new_context(**PHONE, storage_state=researcher.storage_state())
        view = context.new_page()
        view.goto(url)
        assert view.locator("#board-systems tbody tr").count() == 5
        shoot(view, name)
        context.close()
    visitor.close()
    researcher.close()
