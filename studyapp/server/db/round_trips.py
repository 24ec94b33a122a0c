"""Fewer waits for the database while a lock is held: PostgreSQL's pipeline mode.

A statement normally goes to the database and the server process waits for its answer
before sending the next one. Under a crowd each of those waits costs milliseconds more
than the database's own work: the thread must get a core and Python's interpreter lock
back before it can go on. Inside the study's lock (``participants.assignment.enrol``)
every such wait is a wait for every participant queued behind it, and every answer
(``designs.answers.record_answer``) made five of them, the transaction's start included.

In a ``pipeline`` (psycopg's pipeline mode) statements go out without waiting, and the
server process waits only where it reads an answer (a query's rows) and at the commit.
So a lock taken with ``lock_rows`` goes out with the query after it, and rows written
with ``insert`` or ``update`` go out with the commit. A count of changed rows is known only
once the database has answered: in a pipeline ``QuerySet.update`` returns -1, and
``updated_count`` waits for the answer instead. On SQLite, which runs in the server's own
process, there are no round trips to save: ``pipeline`` does nothing there and
``insert`` reads the new rows' ids back as ``bulk_create`` does.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

from django.db import connection
from django.db.models import Model, QuerySet

from studyapp.server.db.django_internals import CURSOR, NO_RESULTS, insert_rows, select_sql, update_compiler


def _pipelines() -> bool:
    return connection.vendor == "postgresql"


@contextlib.contextmanager
def pipeline() -> Iterator[None]:
    """Send statements without waiting for their answers until one is read (PostgreSQL).

    Enter it before ``transaction.atomic()``, so that the commit goes out with what
    precedes it: ``with pipeline(), transaction.atomic(): ...``. An error in a statement
    whose answer is not read is raised where the next answer is read, at the latest by
    the commit (an ``IntegrityError`` as usual), and the transaction is rolled back.
    """
    if not _pipelines():
        yield
        return
    connection.ensure_connection()
    with connection.connection.pipeline():
        yield


def lock_rows(queryset: QuerySet) -> None:
    """Lock the rows of ``queryset`` (``SELECT ... FOR UPDATE``) without reading them: in a
    ``pipeline`` the statements after it go out at once and run once the locks are held.
    Inside a transaction; SQLite has no row locks (its IMMEDIATE transaction already
    holds the database's write lock) and only runs the query."""
    sql, params = select_sql(queryset.select_for_update())
    with connection.cursor() as cursor:
        cursor.execute(sql, params)


def draw_id(model: type[Model]) -> int | None:
    """The next id of ``model``'s table, from its sequence (PostgreSQL), for a row that rows
    inserted with it will refer to; None on SQLite, whose ``insert`` reads the id back.

    Sequences ignore transactions: an id drawn for a row that is never written is a gap."""
    if not _pipelines():
        return None
    with connection.cursor() as cursor:
        cursor.execute("SELECT nextval(pg_get_serial_sequence(%s, %s))", [model._meta.db_table, model._meta.pk.column])
        return cursor.fetchone()[0]


def insert(objects: list[Model]) -> None:
    """INSERT ``objects`` (all of one model) in one statement.

    On PostgreSQL nothing is read back, so a ``pipeline`` need not wait for it: objects
    keep the ids they have (``draw_id``), and those without one get none. On SQLite the
    ids are read back into the objects.
    """
    if not objects:
        return
    model = type(objects[0])
    if not _pipelines():
        model._base_manager.bulk_create(objects)
        return
    with_ids = objects[0].pk is not None
    if any((obj.pk is not None) != with_ids for obj in objects):
        raise ValueError(f"insert(): some {model.__name__} objects have ids and some have none")
    fields = [field for field in model._meta.concrete_fields if with_ids or not field.primary_key]
    insert_rows(model, objects, fields, connection.alias)


def update(queryset: QuerySet, **values: object) -> None:
    """``queryset.update(**values)`` without reading how many rows changed, so that a
    ``pipeline`` need not wait for it."""
    update_compiler(queryset, values).execute_sql(NO_RESULTS)


def updated_count(queryset: QuerySet, **values: object) -> int:
    """``queryset.update(**values)``: how many rows changed, also in a ``pipeline`` (which
    then waits here for the database's answers so far)."""
    if not _pipelines():
        return queryset.update(**values)
    with pipeline():  # entered again: leaving it waits for the answers, this UPDATE's count among them
        cursor = update_compiler(queryset, values).execute_sql(CURSOR)
    with cursor:
        return cursor.rowcount
