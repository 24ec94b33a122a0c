"""The researcher's pages: the steps of a study with what is done, the preview that records
nothing, the monitor's means per control class."""

from __future__ import annotations

import math

import pytest
from django.contrib.auth.models import User
from django.test import Client
from django.urls import reverse
from django.utils import timezone
from scipy import stats

from studyapp.models import Assignment, Participant, Question, Rating, Study
from studyapp.researchers.setup.checklist import checklist
from studyapp.researchers.setup.forms import StudyForm
from studyapp.researchers.results.monitor import study_monitor
from tests.study_fixtures import make_study

pytestmark = pytest.mark.django_db


def test_the_checklist_says_what_is_done_and_what_is_missing():
    study = make_study(is_open=False, completion_code="")
    empty = Study.objects.create(owner=study.owner, title="Empty")
    assert [(s.name, s.done) for s in checklist(empty)] == [
        ("Settings", True), ("Systems", False), ("Controls", False), ("Stimuli", False), ("Preview", False),
        ("Open", False)]
    assert [s.note for s in checklist(empty)][1:4] == ["no model system yet", "none yet", "none generated"]
    steps = checklist(study)
    assert [s.done for s in steps] == [True, True, True, True, False, False]  # the preview is not seen yet
    assert steps[4].note == "see the pages as a participant"
    assert steps[3].note == "12 of 12 clips finished" and "completion code" in steps[5].note  # why it cannot open
    client = Client()
    client.force_login(study.owner)
    page = client.get(reverse("study-systems", args=[study.pk])).content.decode()
    assert '<ol class="steps"' in page and 'aria-current="page"' in page and "12 of 12 clips finished" in page
    assert client.get(reverse("study-preview", args=[study.pk])).status_code == 200
    study.refresh_from_db()
    assert checklist(study)[4].done and checklist(study)[4].note == "seen"


def test_the_settings_item_of_a_pairwise_study_names_no_scale():
    assert "scale" not in checklist(make_study(design="pairwise"))[0].note
    assert "scale 1–5" in checklist(make_study(owner_name="other"))[0].note


def test_the_preview_shows_every_page_in_order_and_records_nothing():
    study = make_study(device_check=True, min_screen_width=300)
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="l", text="First language?", choices="a\nb")
    Question.objects.create(study=study, part=Question.Part.AFTER, name="c", text="Comments?", kind="text")
    client = Client()
    client.force_login(study.owner)
    names = []
    url = reverse("study-preview", args=[study.pk])
    while True:
        page = client.get(url).content.decode()
        assert "nothing is recorded" in page and 'document.addEventListener("submit"' in page
        names.append(page.split("Preview ")[1].split(":")[0])
        if "Next page" not in page:
            break
        url = page.split('<a href="')[1].split('"')[0]
    assert names == ["1 of 8 (device check)", "2 of 8 (consent)", "3 of 8 (screening)", "4 of 8 (instructions)",
                     "5 of 8 (practice)", "6 of 8 (a page to rate)", "7 of 8 (closing questions)", "8 of 8 (completion)"]
    assert "C0MPL3TE" in page
    assert (Participant.objects.count(), Assignment.objects.count(), Rating.objects.count()) == (0, 0, 0)
    stranger = Client()
    stranger.force_login(User.objects.create(username="stranger"))
    assert stranger.get(reverse("study-preview", args=[study.pk])).status_code == 404


def rate(study: Study, ratings: list[tuple[str, str, int]]) -> None:
    """Store (system, control, value) ratings, each by a participant of its own."""
    for i, (system, control, value) in enumerate(ratings):
        participant = Participant.objects.create(study=study, platform_id=f"p{i}")
        stimulus = study.stimuli.get(system__name=system, control__name=control)
        Rating.objects.create(assignment=Assignment.objects.create(participant=participant, stimulus=stimulus,
                                                                   position=0), value=value)


def test_the_monitor_splits_means_by_control_class_and_keeps_intervals_on_the_scale():
    study = make_study(controls=2)
    study.controls.filter(name="control-1").update(origin="synthetic")
    rate(study, [("MoGlow", "control-0", 1), ("MoGlow", "control-0", 5), ("MoGlow", "control-1", 4),
                 ("MoGlow", "control-1", 4), ("MoGlow", "control-1", 3)])
    monitor = study_monitor(study)
    by_class = {name: {row.system: row for row in rows} for name, rows in monitor.means_by_class.items()}
    assert sorted(by_class) == ["held-out", "synthetic"]
    held_out, synthetic = by_class["held-out"]["MoGlow"], by_class["synthetic"]["MoGlow"]
    assert (held_out.n, held_out.mean, synthetic.n, synthetic.mean) == (2, 3.0, 3, pytest.approx(11 / 3))
    half = stats.t.ppf(0.975, 1) * stats.tstd([1, 5]) / math.sqrt(2)  # 25.4: far past both ends
    assert held_out.ci_low == pytest.approx(3 - half) and (held_out.shown_low, held_out.shown_high) == (1, 5)
    client = Client()
    client.force_login(study.owner)
    page = client.get(reverse("study-monitor", args=[study.pk])).content.decode()
    assert 'id="means-held-out"' in page and 'id="means-synthetic"' in page
    assert f"1.000 – 5.000 (± {half:.3f})" in page and 'id="copy-link"' in page


def test_the_study_list_shows_each_studys_progress_towards_its_target():
    study = make_study(controls=2, ratings_per_stimulus=2)  # MoGlow, RNN and NAT on 2 controls: 12 ratings needed
    rate(study, [("MoGlow", "control-0", 3), ("RNN", "control-1", 4), ("NAT", "control-0", 5), ("BAD", "control-0", 1)])
    Participant.objects.filter(platform_id="p0").update(finished_at=timezone.now())
    client = Client()
    client.force_login(study.owner)
    page = client.get(reverse("study-list")).content.decode()
    assert "1 / 4" in page and "3 of 12 (25 %)" in page  # the BAD rating counts towards nothing


def test_the_settings_come_in_sections_with_the_camera_as_fields():
    study = make_study(camera={"azimuth": 10.0})
    client = Client()
    client.force_login(study.owner)
    url = reverse("study-edit", args=[study.pk])
    page = client.get(url).content.decode()
    for title in ("Question and scale", "Crowd platform", "Device check", "Video and camera"):
        assert f"<legend>{title}</legend>" in page
    assert 'name="camera_azimuth" value="10.0"' in page and 'name="camera_elevation" value="18.0"' in page
    form = StudyForm(instance=study)
    posted = {name: value for name, value in {**form.initial, **{f.name: f.value() for f in form}}.items()
              if value is not None and value is not False}
    refused = client.post(url, {**posted, "camera_elevation": 95})
    assert refused.status_code == 400 and "elevation must be strictly between -90 and 90" in refused.content.decode()
    assert client.post(url, {**posted, "camera_elevation": 30}).status_code == 302
    study.refresh_from_db()
    assert (study.camera["azimuth"], study.camera["elevation"]) == (10.0, 30.0)


def test_systems_and_controls_can_be_removed_with_their_clips_until_someone_starts(settings, tmp_path):
    settings.MEDIA_ROOT = tmp_path
    study = make_study(controls=2)
    rnn = study.systems.get(name="RNN")
    files = [s.video_path() for s in rnn.stimuli.all()]
    for path in files:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(b"video")
    client = Client()
    client.force_login(study.owner)
    assert 'aria-label="Remove RNN"' in client.get(reverse("study-systems", args=[study.pk])).content.decode()
    response = client.post(reverse("study-remove", args=[study.pk, "systems", rnn.pk]), follow=True)
    assert "Removed RNN and its 2 clip(s)." in response.content.decode()
    assert not study.systems.filter(name="RNN").exists() and not any(path.exists() for path in files)
    control = study.controls.get(name="control-1")
    client.post(reverse("study-remove", args=[study.pk, "controls", control.pk]))
    assert list(study.controls.values_list("name", flat=True)) == ["control-0"] and study.stimuli.count() == 3
    Participant.objects.create(study=study, platform_id="first")
    moglow = study.systems.get(name="MoGlow")
    refused = client.post(reverse("study-remove", args=[study.pk, "systems", moglow.pk]), follow=True)
    assert "MoGlow stays: participants have started" in refused.content.decode()
    assert study.systems.filter(name="MoGlow").exists()
    stranger = Client()
    stranger.force_login(User.objects.create(username="stranger"))
    assert stranger.post(reverse("study-remove", args=[study.pk, "systems", moglow.pk])).status_code == 404
    assert client.post(reverse("study-remove", args=[study.pk, "studies", moglow.pk])).status_code == 404


@pytest.mark.parametrize("fields, per_page_s, pages, practice", [
    # single: 8 clips of 6 s, 4 practice clips; a clip and a rating (5 s) a page
    ({"clips_per_participant": 8, "training_clips": 4}, 6 + 5, 8, 4),
    # pairwise: 8 pages of 2 clips and one choice; 4 practice clips make 2 practice pages
    ({"design": "pairwise", "pages_per_participant": 8, "training_clips": 4}, 2 * 6 + 5, 8, 2),
], ids=["single", "pairwise"])
def test_the_settings_card_says_how_long_to_advertise_and_how_it_was_reckoned(fields, per_page_s, pages, practice):
    study = make_study(clip_seconds=6.0, controls=4, **fields)
    Question.objects.create(study=study, part=Question.Part.AFTER, name="c", text="Comments?", kind="text")
    seconds = (pages + practice) * per_page_s + 60 + 15  # and a minute to start, 15 s a question
    note = checklist(study)[0].note
    assert f"advertise about {math.ceil(seconds / 60)} min" in note
    assert f"{pages} " in note and f"and {practice} practice" in note and "6.0 s" in note
    clips = "1 clip" if study.design == "single" else "2 clips"
    assert f"each with {clips} of about 6.0 s to watch and 1 answer of about 5 s to give" in note
    assert "15 s for the question" in note and not any(sign in note for sign in ("×", "(s)", "+"))  # words, no formula
    assert ("scale 1–5" in note) is (study.design == "single")  # a preference has no scale

