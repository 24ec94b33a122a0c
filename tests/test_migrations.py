"""The study app's migrations: they describe the models, carry a study's rows from the first
schema to the last (their data migrations included) and undo to an empty database.

SQLite and PostgreSQL alter tables in different ways (SQLite copies a table into a new one,
PostgreSQL alters it in place and checks constraints on the rows already there), so these
run on both (tests.postgres_pass).
"""

from __future__ import annotations

import io
from datetime import timedelta

import pytest
from django.core.management import call_command
from django.db import connection
from django.db.migrations.executor import MigrationExecutor
from django.utils import timezone

pytestmark = pytest.mark.slow

FIRST = [("studyapp", "0001_initial")]


def migrate(targets: list[tuple[str, str | None]]) -> None:
    """Migrate the test database to ``targets`` (a name of None: before the app's first migration)."""
    MigrationExecutor(connection).migrate(targets)


def models_at(targets: list[tuple[str, str]]):
    """The models as they were at ``targets``."""
    return MigrationExecutor(connection).loader.project_state(targets).apps


def latest() -> list[tuple[str, str]]:
    return MigrationExecutor(connection).loader.graph.leaf_nodes("studyapp")


@pytest.mark.django_db
def test_the_migrations_describe_the_models_as_they_are():
    out = io.StringIO()
    try:
        call_command("makemigrations", "studyapp", "--check", "--dry-run", stdout=out)
    except SystemExit:
        pytest.fail(f"the models differ from their migrations:\n{out.getvalue()}")


@pytest.mark.django_db(transaction=True)
def test_a_study_from_the_first_schema_migrates_to_the_last_with_its_rows_and_back_to_nothing():
    last = latest()
    try:
        migrate(FIRST)
        old = models_at(FIRST)
        owner = old.get_model("auth", "User").objects.create(username="before-designs")
        study = old.get_model("studyapp", "Study").objects.create(title="From the first schema", owner_id=owner.pk)
        system = old.get_model("studyapp", "System").objects.create(study=study, name="MoGlow")
        stimuli = [old.get_model("studyapp", "Stimulus").objects.create(study=study, system=system,
                                                                        content_key=f"{i:064d}", status="done")
                   for i in range(3)]
        consented = timezone.now() - timedelta(minutes=10)
        finished = consented + timedelta(minutes=5)
        participant = old.get_model("studyapp", "Participant").objects.create(
            study=study, platform_id="p1", platform_data={"PROLIFIC_PID": "p1"}, consented_at=consented,
            finished_at=finished)
        under_way = old.get_model("studyapp", "Participant").objects.create(study=study, platform_id="p2")
        Assignment = old.get_model("studyapp", "Assignment")
        assignments = [Assignment.objects.create(participant=participant, stimulus=s, position=i)
                       for i, s in enumerate(stimuli)]
        old.get_model("studyapp", "Rating").objects.create(assignment=assignments[1], value=4)

        migrate(last)
        new = models_at(last)
        # The data migrations: each old clip is a page of its own, and who had consented
        # (finished) before questionnaires existed has passed them.
        moved = new.get_model("studyapp", "Assignment").objects.filter(participant_id=participant.pk)
        assert sorted(moved.values_list("position", "page", "slot")) == [(0, 0, 1), (1, 1, 1), (2, 2, 1)]
        after = new.get_model("studyapp", "Participant").objects.get(pk=participant.pk)
        assert (after.screened_at, after.surveyed_at, after.answers) == (consented, finished, {})
        assert new.get_model("studyapp", "Participant").objects.get(pk=under_way.pk).screened_at is None
        rating = new.get_model("studyapp", "Rating").objects.get(assignment_id=assignments[1].pk)
        assert (rating.value, rating.answer, rating.strength) == (4, "", None)
        assert new.get_model("studyapp", "Study").objects.get(pk=study.pk).design == "single"

        migrate([("studyapp", None)])  # every migration undone, rows and all
        assert not {"studyapp_study", "studyapp_rating"} & set(connection.introspection.table_names())
    finally:
        migrate(last)  # whatever happened, the tests after this one find the schema they expect


@pytest.mark.django_db(transaction=True)
def test_number_questions_made_before_their_range_keep_taking_any_finite_number():
    last, before = latest(), [("studyapp", "0012_appropriateness_design_and_mismatched_clips")]
    try:
        migrate(before)
        old = models_at(before)
        owner = old.get_model("auth", "User").objects.create(username="before-ranges")
        study = old.get_model("studyapp", "Study").objects.create(title="Running", owner_id=owner.pk)
        Question = old.get_model("studyapp", "Question")
        hours = Question.objects.create(study=study, part="after", name="hours", text="Hours?", kind="number")
        language = Question.objects.create(study=study, part="before", name="language", text="English?",
                                           choices="yes\nno")

        migrate(last)
        Question = models_at(last).get_model("studyapp", "Question")
        ranges = Question.objects.values_list("minimum", "maximum", "whole_numbers")
        assert ranges.get(pk=hours.pk) == (-1e9, 1e9, False)
        assert ranges.get(pk=language.pk) == (0, 120, True)
    finally:
        migrate(last)
