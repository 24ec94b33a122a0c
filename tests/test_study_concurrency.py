"""Many participants at once, over HTTP against a live server and a real database file."""

from __future__ import annotations

import threading
import time
from collections import Counter

import pytest
from django.db import connection, transaction

from studyapp.models import Participant, Rating, Stimulus, Study, System
from studyapp.participants.simulated import run_participants
from studyapp.server.db.sqlite_backend.base import DatabaseWrapper
from tests.study_fixtures import make_study

pytestmark = pytest.mark.slow


@pytest.mark.django_db(transaction=True)
def test_simultaneous_participants_never_pass_a_target_and_lose_no_rating(live_server):
    # 4 controls x 3 rated systems = 12 stimuli x 3 ratings = 36 places; each participant
    # rates 4 of them (plus one BAD check), so exactly 9 participants fit. Thresholds
    # that exclude nobody keep every rating counting towards the targets.
    study = make_study(controls=4, clips_per_participant=5, ratings_per_stimulus=3, bad_checks=1, natural_checks=0,
                       training_clips=1, clip_seconds=0.01, bad_threshold=6.0, natural_threshold=0.0)
    outcomes = run_participants(f"{live_server.url}/p/{study.key}/", count=24)

    assert [o.error for o in outcomes if o.error] == []
    finished = [o for o in outcomes if o.finished]
    turned_away = [o for o in outcomes if "The study is full" in o.final_page]
    assert (len(finished), len(turned_away)) == (9, 15)
    assert Participant.objects.filter(study=study).count() == 9

    # Every rating the participants sent is stored, once.
    assert Rating.objects.count() == sum(o.ratings for o in outcomes) == 9 * 5
    per_stimulus = Counter(Rating.objects.values_list("assignment__stimulus_id", flat=True))
    rated = Stimulus.objects.filter(study=study).exclude(system__role=System.Role.BAD)
    assert all(per_stimulus[s.id] == study.ratings_per_stimulus for s in rated)


@pytest.mark.django_db(transaction=True)
def test_watching_participants_on_the_embedded_database_lose_nothing(live_server):
    # The demo's setup in small: a threaded server and SQLite (WAL, immediate transactions).
    assert connection.vendor != "sqlite" or connection.cursor().execute("PRAGMA journal_mode").fetchone() == ("wal",)
    study = make_study(controls=10, clips_per_participant=5, ratings_per_stimulus=30, bad_checks=1,
                       natural_checks=1, training_clips=1, clip_seconds=0.01)
    outcomes = run_participants(f"{live_server.url}/p/{study.key}/", count=30, watch_s=0.3)

    assert [o.error for o in outcomes if o.error] == []
    assert all(o.finished for o in outcomes)
    assert Rating.objects.count() == Rating.objects.values("assignment").distinct().count() == 30 * 5
    assert sum(o.ratings for o in outcomes) == 30 * 5


@pytest.mark.django_db(transaction=True)
def test_participants_all_answering_at_once_on_the_embedded_database_lose_nothing(live_server):
    # Saturation: 30 participants enter together and answer every page the moment it
    # arrives, so enrolments and ratings write at once.
    study = make_study(controls=10, clips_per_participant=6, ratings_per_stimulus=30, bad_checks=1,
                       natural_checks=1, training_clips=1, clip_seconds=0.01)
    outcomes = run_participants(f"{live_server.url}/p/{study.key}/", count=30)

    assert [o.error for o in outcomes if o.error] == []
    assert all(o.finished for o in outcomes)
    assert Rating.objects.count() == Rating.objects.values("assignment").distinct().count() == 30 * 6
    assert sum(o.ratings for o in outcomes) == 30 * 6


@pytest.mark.skipif(connection.vendor != "sqlite", reason="the turns are the embedded database's")
@pytest.mark.django_db(transaction=True)
def test_a_write_waits_for_its_turn_behind_a_transaction_of_the_same_process_without_polling_out():
    study = make_study()
    held = threading.Event()

    def hold_the_database() -> None:
        with transaction.atomic():
            Study.objects.filter(pk=study.pk).update(title="first")
            held.set()
            time.sleep(0.5)
        connection.close()

    holder = threading.Thread(target=hold_the_database)
    holder.start()
    held.wait(5)
    # A connection whose busy timeout (0.05 s) alone would give up ten times over.
    impatient = DatabaseWrapper({**connection.settings_dict,
                                 "OPTIONS": {**connection.settings_dict["OPTIONS"], "timeout": 0.05}}, "impatient")
    try:
        with impatient.cursor() as cursor:
            cursor.execute("UPDATE studyapp_study SET title = %s WHERE id = %s", ["second", study.pk])
    finally:
        impatient.close()
        holder.join()
    assert Study.objects.get(pk=study.pk).title == "second"  # written after the transaction, not refused
