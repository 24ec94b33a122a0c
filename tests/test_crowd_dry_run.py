"""The dry run's simulated participants follow the full-play rule as a browser does, on every design, walk
every study the app can build (device check, screening, questionnaires, practice, instructed checks) and count
how each ended."""

from __future__ import annotations

import pytest

from studyapp.models import Participant, Question, Rating, Study
from studyapp.participants.simulated import FAILED, SimulatedParticipant, main, run_participants, summary
from tests.appropriateness_fixtures import make_appropriateness_study
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


def add_questions(study) -> None:
    """A screening choice that turns "no" away, a number, and an optional comment after the ratings."""
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="language",
                            text="Is English your first language?", choices="yes\nno", accepted="yes")
    Question.objects.create(study=study, part=Question.Part.BEFORE, name="age", text="How old are you?",
                            kind=Question.Kind.NUMBER, minimum=18, maximum=99)
    Question.objects.create(study=study, part=Question.Part.AFTER, name="comments", text="Any comments?",
                            kind=Question.Kind.TEXT, required=False)


CAREFUL = {"device_check": True, "min_screen_width": 1600, "min_screen_height": 900, "instructed_checks": 1,
           "clip_seconds": 0.05}
DESIGNS = {
    "single": lambda: make_study(training_clips=1, ratings_per_stimulus=10, **CAREFUL),
    "side-by-side": lambda: make_study(design="side-by-side", controls=2, pages_per_participant=2, training_clips=1,
                                       scale_min=0, scale_max=100, bad_threshold=6.0, natural_threshold=0.0,
                                       ratings_per_stimulus=10, **CAREFUL),
    "pairwise": lambda: make_study(design="pairwise", controls=2, pages_per_participant=3, training_clips=1,
                                   preference_strengths=2, ratings_per_stimulus=10, **CAREFUL),
    "abx": lambda: make_study(design="pairwise", abx=True, controls=2, pages_per_participant=3, training_clips=1,
                              ratings_per_stimulus=10, **CAREFUL),
    "appropriateness": lambda: make_appropriateness_study(pages_per_participant=4, training_clips=1, **CAREFUL),
}


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("design", DESIGNS)
def test_the_dry_run_walks_a_careful_study_of_every_design(live_server, design, capsys):
    study = DESIGNS[design]()
    add_questions(study)
    assert main([f"{live_server.url}/p/{study.key}/", "-n", "6", "--concurrency", "1"]) == 0
    said = capsys.readouterr()
    participants = Participant.objects.filter(study=study)
    finished, screened_out = participants.filter(finished_at__isnull=False), participants.filter(
        screened_out_at__isnull=False)
    assert finished.count() + screened_out.count() == 6 and finished.exists()
    assert not participants.filter(failed_checks__gt=0).exists(), "the instructed checks answered as they ask"
    assert all(p.device_checked_at and p.answers["age"] >= 18 for p in finished)
    assert f"6 participants: {finished.count()} finished, {screened_out.count()} screened out, 0 refused because " \
           "the study was full, 0 failed" in said.out
    assert said.err == ""


@pytest.mark.django_db(transaction=True)
@pytest.mark.parametrize("design", ["single", "side-by-side", "pairwise"])
def test_the_dry_run_reads_a_german_studys_pages_as_an_english_ones(live_server, design, capsys):
    """The instructed checks and the endings are read in no language (data-expected, data-ending)."""
    study = DESIGNS[design]()
    study.language = Study.Language.GERMAN
    study.save(update_fields=["language"])
    add_questions(study)
    assert main([f"{live_server.url}/p/{study.key}/", "-n", "4", "--concurrency", "1"]) == 0
    participants = Participant.objects.filter(study=study)
    finished, screened_out = participants.filter(finished_at__isnull=False), participants.filter(
        screened_out_at__isnull=False)
    assert not participants.filter(failed_checks__gt=0).exists(), "the instructed checks answered as they ask"
    assert f"4 participants: {finished.count()} finished, {screened_out.count()} screened out, 0 refused because " \
           "the study was full, 0 failed" in capsys.readouterr().out and finished.exists()
    full = make_study(owner_name="other", controls=1, clips_per_participant=3, ratings_per_stimulus=1,
                      training_clips=0, bad_checks=0, natural_checks=0, clip_seconds=0.05,
                      language=Study.Language.GERMAN)
    assert main([f"{live_server.url}/p/{full.key}/", "-n", "2", "--concurrency", "1"]) == 0
    assert "2 participants: 1 finished, 0 screened out, 1 refused because the study was full, 0 failed" in \
        capsys.readouterr().out


@pytest.mark.django_db(transaction=True)
def test_the_dry_run_counts_those_refused_because_the_study_was_full(live_server, capsys):
    study = make_study(controls=1, clips_per_participant=3, ratings_per_stimulus=1, training_clips=0, bad_checks=0,
                       natural_checks=0, clip_seconds=0.05)
    assert main([f"{live_server.url}/p/{study.key}/", "-n", "3", "--concurrency", "1"]) == 0
    assert "3 participants: 1 finished, 0 screened out, 2 refused because the study was full, 0 failed" in \
        capsys.readouterr().out


class Unanswering(SimulatedParticipant):
    """Sends the questionnaire without answering it."""

    def _questions_answer(self, form: str) -> dict:
        return {}


@pytest.mark.django_db(transaction=True)
def test_a_participant_the_app_refuses_is_a_failure_with_the_apps_own_reason(live_server):
    study = make_study(clip_seconds=0.05)
    add_questions(study)
    outcome = Unanswering(f"{live_server.url}/p/{study.key}/", "sim-1").run()
    assert outcome.ending == FAILED and outcome.error == (
        f"HTTP 400 on /p/{study.key}/screening/: That did not work: “Is English your first language?”: please "
        "answer this question")
    assert summary([outcome]) == ("1 participants: 0 finished, 0 screened out, 0 refused because the study was "
                                  "full, 1 failed")
