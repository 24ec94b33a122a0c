"""An appropriateness study built from the researcher's web pages alone, for the demo's
kinds of system (MoGlow, RNN, VAE and NAT, the models trained for seconds on real clips),
rendered for real, taken in a real browser on a desktop and a phone, and reported.

The clips are dataset 1's walks, sidesteps left and sidesteps right, one of each held
out: the sidesteps are each other's partners (and NAT's attention partners), the slow
walk has none. Careful participants prefer the matched clip clearly, on NAT's pages as
on the others; a careless one prefers the mismatched take of a check and is excluded.
"""

from __future__ import annotations

import io
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
import torch
from django.contrib.auth.models import User
from django.core.files.uploadedfile import SimpleUploadedFile
from django.test import Client

from analysis.stats.matching import appropriateness_pages, appropriateness_scores, matched_preference
from analysis.ratings.exclusions import apply_exclusions, compared_ratings
from analysis.cli import main as analysis_main
from analysis.ratings.schema import read_ratings
from generation.motion.data.dataset import build_dataset
from generation.motion.data.dataset_options import DatasetOptions
from generation.render.camera import Camera
from generation.train import TrainOptions, train
from studyapp.designs.rules import StudyRules
from studyapp.models import Participant, Stimulus, Study
from studyapp.researchers.results.export import ratings_csv
from studyapp.stimuli.clips import over_shown_control, motion_row
from studyapp.stimuli.motion_export import write_motion
from studyapp.stimuli.sources import source_of
from tests.study_fixtures import current_page
from tests.study_setup import link_clips, train_tiny_moglow
from tests.test_study_browser import browser  # noqa: F401 (fixture)
from tests.test_study_design_browser import DESKTOP as LAPTOP
from tests.test_study_design_browser import PHONE, one_plays_at_a_time, play_every_clip
from tests.test_study_researcher import queue, run_task  # noqa: F401 (fixture)

CLIPS = ["walk_normal_001", "walk_happy_001", "walk_old_002", "walk-left_normal_001", "walk-left_happy_001",
         "walk-right_normal_001", "walk-right_happy_001"]
DESKTOP = {**LAPTOP, "viewport": {"width": 1366, "height": 768}}


@pytest.fixture(scope="module")
def demo_kinds(motion_data, tmp_path_factory) -> SimpleNamespace:
    """The clip folder, its dataset cache, and a MoGlow, an RNN and a VAE trained on it for seconds."""
    root = tmp_path_factory.mktemp("appropriateness")
    clips = link_clips(motion_data, root / "clips", CLIPS)
    cache = root / "var" / "cache"
    dataset = build_dataset(clips, DatasetOptions(), cache_dir=cache, progress=False)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        models = {"MoGlow": train_tiny_moglow(clips, root / "moglow.safetensors", 20, cache)}
        for name, kind in (("RNN", "rnn"), ("VAE", "vae")):
            models[name] = root / f"{kind}.safetensors"
            train(kind, "cpu", dataset, models[name], TrainOptions(steps=2, eval_every=2), progress=False)
    finally:
        torch.set_num_threads(threads)
    return SimpleNamespace(root=root, clips=clips, models=models)


@pytest.fixture
def site(settings, tmp_path, demo_kinds) -> Path:
    settings.MEDIA_ROOT = tmp_path / "media"
    settings.CHECKPOINT_ROOT = tmp_path / "checkpoints"
    settings.VAR_DIR = tmp_path / "var"
    settings.VAR_DIR.mkdir()
    (settings.VAR_DIR / "cache").symlink_to(demo_kinds.root / "var" / "cache")
    settings.MOTION_DATA = demo_kinds.clips
    return tmp_path


STUDY_FORM = {
    "title": "Do they follow the path?", "design": "appropriateness", "pages_per_participant": 4, "bad_checks": 1,
    "question": "Which fits?", "scale_min": 1, "scale_max": 5, "label_min": "no", "label_max": "yes",
    "instructions": "Two clips of one character each page: which follows the orange path better?",
    "consent_text": "OK?", "clips_per_participant": 12, "ratings_per_stimulus": 10, "training_clips": 2,
    "natural_checks": 0, "bad_threshold": 4, "natural_threshold": 2, "discard_early": "on", "require_full_play": "on",
    "reservation_minutes": 60, "platform": "prolific", "completion_code": "C0MPL3TE", "redirect_url": "",
    "preference_strengths": 0, "instructed_checks": 0, "stop_after_failed_checks": 0,
    "video_width": 320, "video_height": 240,
    **{f"camera_{name}": value for name, value in Camera().to_dict().items() if value is not None},
}


def build_from_the_web_pages(client: Client, demo_kinds) -> Study:
    """Every step a researcher takes, on the study pages: settings, systems, controls, stimuli, open."""
    assert client.post("/studies/new/", STUDY_FORM).status_code == 302
    study = Study.objects.get()
    for name, path in demo_kinds.models.items():
        upload = SimpleUploadedFile(path.name, path.read_bytes())
        response = client.post(f"/studies/{study.pk}/systems/", {"action": "checkpoint", "name": name, "role": "model",
                                                                 "temperature": "1.0", "checkpoint": upload})
        assert response.status_code == 302, response.content.decode()[-500:]
    assert client.post(f"/studies/{study.pk}/systems/", {"action": "natural", "name": "NAT"}).status_code == 302
    assert client.post(f"/studies/{study.pk}/controls/",
                       {"action": "held_out", "seconds": "1", "count": ""}).status_code == 302
    assert client.post(f"/studies/{study.pk}/stimuli/", {"seed": "0"}).status_code == 302
    for stimulus in Stimulus.objects.filter(study=study):  # as the workers would
        assert run_task(stimulus)["status"] == "done", Stimulus.objects.get(pk=stimulus.pk).error
    stimuli_page = client.get(f"/studies/{study.pk}/stimuli/").content.decode()
    assert "Mismatched pairs" in stimuli_page and "within the speed band" in stimuli_page  # the slow walk's reason
    # The models' 20 fps beside NAT's 30 fps is listed before the study opens (the figure resamples them).
    refused = client.post(f"/studies/{study.pk}/open/", {"open": "1"}, follow=True).content.decode()
    assert "different frame rates" in refused and not Study.objects.get(pk=study.pk).is_open
    assert client.post(f"/studies/{study.pk}/open/", {"open": "1", "despite_warnings": "1"}).status_code == 302
    study.refresh_from_db()
    assert study.is_open
    return study


def take_part(browser, live_server, study: Study, pid: str, screen: dict, shots: Path,  # noqa: F811
              careful: bool = True) -> str:
    context = browser.new_context(**screen)
    page = context.new_page()
    page.goto(f"{live_server.url}/p/{study.key}/?PROLIFIC_PID={pid}&STUDY_ID=S1&SESSION_ID=X1")
    page.get_by_role("button", name="I agree to take part").click()
    page.get_by_role("button", name="Start").click()
    participant = Participant.objects.get(study=study, platform_id=pid)
    while Participant.objects.get(pk=participant.pk).training_done < len(participant.training):
        page.wait_for_selector("text=(not recorded)")
        heading = page.inner_text("p.meta")
        play_every_clip(page)
        page.get_by_role("button", name="A fits better").click()
        page.get_by_role("button", name="slightly", exact=True).click()
        page.wait_for_function(f"() => !document.body.innerText.includes({heading!r})")
    first = True
    while clips := current_page(participant):
        page.wait_for_selector("video[data-slot]")
        if first:
            assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth")  # no sideways scroll
            assert one_plays_at_a_time(page)
            page.screenshot(path=shots / f"{pid}.png", full_page=True)
            first = False
        matched = "A" if clips[0].stimulus.shown_control_id is None else "B"
        mismatched = "B" if matched == "A" else "A"
        play_every_clip(page)
        chosen = mismatched if clips[0].is_check and not careful else matched
        page.get_by_role("button", name=f"{chosen} fits better").click()  # the choice first, then how much better
        page.get_by_role("button", name="clearly", exact=True).click()
        page.wait_for_function(f"() => !document.body.innerHTML.includes('{clips[0].token}')")
    page.wait_for_load_state()  # the last page has arrived, but may not be all there yet
    text = page.inner_text("body")
    context.close()
    return text


@pytest.mark.slow
@pytest.mark.django_db(transaction=True)
def test_an_appropriateness_study_built_from_the_web_pages_runs_in_a_browser_and_reports_its_scores(
        browser, live_server, site, queue, demo_kinds):  # noqa: F811
    researcher = User.objects.create_user("researcher", password="pw-for-tests")
    client = Client()
    client.force_login(researcher)
    study = build_from_the_web_pages(client, demo_kinds)

    # Both clips of a page are drawn over the shown control's path, the one clip's motion made for the other path.
    mismatched = Stimulus.objects.filter(study=study, shown_control__isnull=False).select_related(
        "study", "system", "control", "shown_control")
    assert {s.system.name for s in mismatched} == {"MoGlow", "RNN", "VAE", "NAT"}
    for clip in mismatched:
        own = motion_row(clip)
        assert (own.system, own.control, own.shown_control) == (clip.system, clip.control, None)
        matched = Stimulus.objects.select_related("study", "system", "control").get(
            study=study, system=clip.system, control=clip.shown_control, shown_control=None)
        drawn = [over_shown_control(s, source_of(s.system).clip(motion_row(s)))[2] for s in (matched, clip)]
        assert np.array_equal(*drawn)
        assert clip.duration_s == pytest.approx(matched.duration_s)

    shots = site / "screenshots"
    shots.mkdir()
    for pid, screen in (("careful-desktop", DESKTOP), ("careful-phone", PHONE)):
        assert study.completion_code in take_part(browser, live_server, study, pid, screen, shots)
    take_part(browser, live_server, study, "careless", DESKTOP, shots, careful=False)
    people = {p.platform_id: p for p in Participant.objects.filter(study=study)}
    assert {pid: p.excluded for pid, p in people.items()} == {"careful-desktop": False, "careful-phone": False,
                                                              "careless": True}

    table = read_ratings(io.StringIO(ratings_csv(study).decode()))
    rules = StudyRules.of(study).exclusion
    flagged = apply_exclusions(table, rules)
    kept_pages = appropriateness_pages(flagged[flagged["kept"]])
    nat_against_wrong_take = kept_pages[kept_pages["system"] == "BAD"]  # the checks: NAT's take against another
    assert len(nat_against_wrong_take) == 2 and (nat_against_wrong_take["score"] == 2).all()
    compared = compared_ratings(flagged, rules)
    shares = matched_preference(compared, groupby=()).set_index("system")
    scores = appropriateness_scores(compared, groupby=()).set_index("system")
    assert (shares["share_matched"] == 1.0).all() and (scores["mean_score"] == 2.0).all()
    report = client.post(f"/studies/{study.pk}/report/", follow=True).content.decode()
    assert "Mean appropriateness score" in report
    for system in shares.index:
        assert f"<td>{system}</td>" in report

    # The control adherence of the study's own motion, in the app and from its export on the command line.
    adherence_page = client.get(f"/studies/{study.pk}/adherence/").content.decode()
    assert "Pearson correlation across systems" in adherence_page
    assert all(f"<td>{system}</td>" in adherence_page for system in ("MoGlow", "RNN", "VAE", "NAT"))
    write_motion(study, site / "motion")
    (site / "ratings.csv").write_bytes(ratings_csv(study))
    assert analysis_main(["objective", str(site / "motion"), "--out", str(site / "objective"),
                          "--appropriateness", str(site / "ratings.csv")]) == 0
    adherence = pd.read_csv(site / "objective" / "tables" / "control_adherence.csv").set_index("system")
    assert set(adherence.index) == {"MoGlow", "RNN", "VAE", "NAT"}
    assert adherence.loc["NAT", "position_error_mean"] < 5  # a take follows the path taken from it
    assert (site / "objective" / "tables" / "adherence_correlation.csv").is_file()
