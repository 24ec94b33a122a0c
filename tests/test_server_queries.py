"""The participant pages' queries: compiled once per process (``compiled_queries``); in
enrolment, sent in one pipeline under the study's lock (``round_trips``), after the
rendered clips that are read again only when they changed (``study_cache``)."""

from __future__ import annotations

import threading

import pytest
from django.db import IntegrityError, connection, connections, transaction
from django.db.models import F
from django.test import Client

from studyapp.models import Assignment, Participant, Stimulus, Study, System
from studyapp.participants.assignment import enrol
from studyapp.participants.study_cache import rendered_clips
from studyapp.server.db.compiled_queries import CompiledQuery
from studyapp.server.db.round_trips import draw_id, insert, lock_rows, pipeline, updated_count
from tests.study_fixtures import make_study
from tests.test_study_next_page import rate, study_of, through_instructions

pytestmark = pytest.mark.django_db(transaction=True)


def in_a_pipeline() -> bool:
    return connection.vendor == "postgresql" and connection.connection.pgconn.pipeline_status != 0


def _fields(obj) -> dict:
    return {name: value for name, value in vars(obj).items() if not name.startswith("_")}


@pytest.fixture
def participants() -> list[Participant]:
    study = make_study(controls=4, clips_per_participant=6, training_clips=1)
    return [enrol(study, f"person-{n}", {"PROLIFIC_PID": f"person-{n}"}) for n in range(3)]


def test_a_compiled_query_reads_the_same_objects_and_annotations_as_the_orm_for_each_value(participants):
    annotated = CompiledQuery(lambda pk, key: Participant.objects.annotate(study_updated=F("study__updated"))
                              .filter(pk=pk, study__key=key), int, str)
    for participant in participants:
        expected = Participant.objects.annotate(study_updated=F("study__updated")).get(pk=participant.pk)
        [found] = annotated(participant.pk, participant.study.key)
        assert _fields(found) == _fields(expected)
        assert found.study_updated == participant.study.updated  # a date, converted as the ORM converts it
    assert annotated(participants[0].pk, "another-key") == []


def test_a_compiled_values_query_reads_the_same_dicts_in_the_same_order_as_the_orm(participants):
    clips = CompiledQuery(lambda pk: Assignment.objects.filter(participant_id=pk).order_by("-position")
                          .values("pk", "position", "shown_at", "stimulus__token"), int)
    Assignment.objects.filter(participant=participants[1], position=0).update(shown_at="2026-01-02T03:04:05Z")
    for participant in participants:
        expected = list(participant.assignments.order_by("-position")
                        .values("pk", "position", "shown_at", "stimulus__token"))
        assert clips(participant.pk) == expected and len(expected) > 1
    assert any(row["shown_at"] is not None for row in clips(participants[1].pk))


def test_a_value_that_the_orm_changes_on_its_way_into_the_sql_cannot_be_compiled(participants):
    pattern = CompiledQuery(lambda word: Participant.objects.filter(platform_id__contains=word), str)
    with pytest.raises(TypeError, match="value 1 of .* does not reach the SQL as it is given"):
        pattern("person")


def test_a_compiled_query_refuses_values_of_other_types_than_it_was_compiled_for(participants):
    by_id = CompiledQuery(lambda pk: Participant.objects.filter(pk=pk), int)
    with pytest.raises(TypeError, match=r"takes values of the types \['int'\]"):
        by_id(str(participants[0].pk))
    with pytest.raises(TypeError):
        by_id(participants[0].pk, 2)


def test_a_compiled_query_runs_on_the_connection_of_the_thread_that_calls_it(participants):
    by_id = CompiledQuery(lambda pk: Participant.objects.filter(pk=pk), int)
    by_id(participants[0].pk)  # compiled here, on this thread's connection
    seen: list[bool] = []

    def in_a_thread() -> None:
        def note(execute, sql, params, many, context):
            seen.append(True)
            return execute(sql, params, many, context)

        try:
            with connections["default"].execute_wrapper(note):
                assert by_id(participants[1].pk)[0].pk == participants[1].pk
        finally:
            connections["default"].close()

    thread = threading.Thread(target=in_a_thread)
    thread.start()
    thread.join()
    assert seen == [True]


def test_enrolment_under_the_lock_sends_only_the_loads_query_and_writes_that_return_nothing():
    """On PostgreSQL the lock, the loads and the new rows go out in one pipeline, so the
    server waits for the database twice while it holds the lock: the loads and the commit."""
    study = make_study(controls=4, clips_per_participant=6, training_clips=1)
    statements: list[tuple[str, bool]] = []

    def note(execute, sql, params, many, context):
        statements.append((sql, in_a_pipeline()))
        return execute(sql, params, many, context)

    with connection.execute_wrapper(note):
        enrol(study, "person-0", {})
    under_lock = statements[-4:]  # the lock, the loads and the two inserts
    assert [sql.split(None, 1)[0] for sql, _ in under_lock] == ["SELECT", "SELECT", "INSERT", "INSERT"], statements
    assert all(not pipelined for _, pipelined in statements[:-4])
    if connection.vendor == "postgresql":
        assert under_lock[0][0].endswith("FOR UPDATE")
        assert all(pipelined and "RETURNING" not in sql for sql, pipelined in under_lock)
    participant = Participant.objects.get(study=study, platform_id="person-0")
    assert participant.assignments.count() == 6 and participant.training


def test_a_row_written_in_a_pipeline_that_breaks_a_constraint_raises_at_the_commit_and_leaves_nothing():
    study = make_study(controls=2)
    enrol(study, "person-0", {})
    before = (Participant.objects.count(), Assignment.objects.count())
    with pytest.raises(IntegrityError):
        with pipeline(), transaction.atomic():
            lock_rows(Study.objects.filter(pk=study.pk))
            twin = Participant(pk=draw_id(Participant), study=study, platform_id="person-0")
            insert([twin])
    assert (Participant.objects.count(), Assignment.objects.count()) == before
    assert enrol(study, "person-1", {}).assignments.exists()  # the connection is usable again


def test_the_rendered_clips_are_read_again_only_when_what_a_plan_reads_of_them_changes():
    study = make_study(controls=3)
    clips = rendered_clips(study)
    assert rendered_clips(study) is clips  # unchanged: the same objects, not read again
    model = next(s.system for s in clips if s.system.role == System.Role.MODEL)
    System.objects.filter(pk=model.pk).update(role=System.Role.NATURAL)
    edited = rendered_clips(study)
    assert sorted(s.pk for s in edited) == sorted(s.pk for s in clips)  # in the new order of roles
    assert {s.system.role for s in edited if s.system_id == model.pk} == {System.Role.NATURAL}
    Stimulus.objects.filter(pk=clips[0].pk).update(status=Stimulus.Status.RUNNING)  # being rendered again
    assert sorted(s.pk for s in rendered_clips(study)) == sorted(s.pk for s in clips[1:])


def test_an_answer_is_read_and_written_in_one_pipeline_whose_writes_return_nothing():
    """On PostgreSQL the transaction's start goes out with the page's clips, and the
    rating (and any update of the participant's rows) with the commit: two waits for the
    database."""
    study = study_of("single", training_clips=0)
    client = Client()
    participant = through_instructions(client, study)
    statements: list[tuple[str, bool]] = []

    def note(execute, sql, params, many, context):
        statements.append((sql, in_a_pipeline()))
        return execute(sql, params, many, context)

    with connection.execute_wrapper(note):
        assert rate(client, study, participant).status_code == 200
    pipelined = [sql.split(None, 1)[0] for sql, in_pipeline in statements if in_pipeline]
    if connection.vendor == "postgresql":
        assert pipelined[:2] == ["SELECT", "INSERT"] and set(pipelined[2:]) <= {"UPDATE"}, statements
        assert "FOR UPDATE" in next(sql for sql, in_pipeline in statements if in_pipeline)
        assert not any("RETURNING" in sql for sql, in_pipeline in statements if in_pipeline)
    assert participant.assignments.filter(rating__isnull=False).count() == 1


def test_a_count_of_updated_rows_read_in_a_pipeline_is_the_number_of_rows_changed():
    study = make_study(controls=2)
    with pipeline(), transaction.atomic():
        lock_rows(Study.objects.filter(pk=study.pk))
        assert updated_count(Study.objects.filter(pk=study.pk), title="Renamed") == 1
        assert updated_count(Study.objects.filter(pk=study.pk, title="Not its title"), title="Again") == 0
    assert Study.objects.get(pk=study.pk).title == "Renamed"
