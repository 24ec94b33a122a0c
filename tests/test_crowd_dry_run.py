"""The dry run's simulated participants follow the full-play rule as a browser does, on every design."""

from __future__ import annotations

import pytest

from studyapp.models import Participant, Rating
from studyapp.participants.simulated import main, run_participants
from tests.study_fixtures import make_study


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("locked", [True, False])
def test_simulated_participants_play_every_clip_to_its_end_locked_or_not(live_server, locked):
    study = make_study(clips_per_participant=3, bad_checks=0, natural_checks=0, training_clips=1, clip_seconds=0.5,
                       require_full_play=locked)
    (outcome,) = run_participants(f"{live_server.url}/p/{study.key}/", count=1)
    assert outcome.error == "" and outcome.finished and outcome.ratings == 3
    assert Participant.objects.get().refused_early == 0
    assert not Rating.objects.filter(answered_before_end=True).exists()


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("design", ["side-by-side", "pairwise"])
def test_simulated_participants_play_every_clip_of_a_page_to_its_end(live_server, design):
    study = make_study(design=design, controls=2, pages_per_participant=2, bad_checks=0, training_clips=0,
                       clip_seconds=0.5, scale_min=0, scale_max=100, bad_threshold=6.0, natural_threshold=0.0)
    (outcome,) = run_participants(f"{live_server.url}/p/{study.key}/", count=1)
    assert outcome.error == "" and outcome.finished and outcome.ratings == 2
    assert Rating.objects.exists() and not Rating.objects.filter(answered_before_end=True).exists()


@pytest.mark.parametrize("arguments", [["-n", "0"], ["--concurrency", "-1"], ["--watch", "-5"], ["--watch", "nan"]])
def test_the_dry_run_refuses_a_count_or_watch_time_that_makes_no_sense_with_one_line(capsys, arguments):
    with pytest.raises(SystemExit) as exit_:
        main(["http://127.0.0.1:9/p/KEY/", *arguments])
    assert exit_.value.code == 2 and "Traceback" not in capsys.readouterr().err
