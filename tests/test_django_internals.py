"""The private parts of Django that ``studyapp.server.db.django_internals`` drives behave as
the app relies on: a Django upgrade that changes one fails here, naming it, before the
compiled queries (``test_server_queries``) or the pipelined writes go wrong."""

from __future__ import annotations

import inspect

import django
import django.test.utils
import pytest
from django.contrib.auth.models import User
from django.db import DEFAULT_DB_ALIAS, connection
from django.db.models import F, QuerySet
from django.db.models.sql.compiler import SQLCompiler
from django.db.models.sql.query import Query

from studyapp.server.db import django_internals
from studyapp.server.db.django_internals import (
    CURSOR, NO_RESULTS, UpdateQuery, compile_select, insert_rows, run_compiled, select_sql, update_compiler,
)

pytestmark = pytest.mark.django_db


def _parameters(function) -> list[str]:
    return list(inspect.signature(function).parameters)


@pytest.fixture
def people() -> list[User]:
    return [User.objects.create(username=name, first_name=name.title()) for name in ("ada", "bob", "cy")]


def test_each_private_method_still_takes_the_arguments_it_is_called_with():
    assert _parameters(QuerySet._chain) == ["self"]
    assert _parameters(QuerySet._insert)[:3] == ["self", "objs", "fields"]
    assert "using" in _parameters(QuerySet._insert)
    assert _parameters(Query.chain) == ["self", "klass"]
    assert _parameters(Query.sql_with_params) == ["self"]
    assert _parameters(Query.get_compiler)[:2] == ["self", "using"]
    assert _parameters(UpdateQuery.add_update_values) == ["self", "values"]
    assert _parameters(SQLCompiler.as_sql)[0] == "self"
    assert _parameters(SQLCompiler.execute_sql)[:2] == ["self", "result_type"]
    assert issubclass(UpdateQuery, Query)
    assert {CURSOR, NO_RESULTS} == {"cursor", "no results"}


def test_a_missing_private_name_is_an_import_error_naming_the_django_version_and_the_name():
    with pytest.raises(ImportError) as refused:
        django_internals._private(QuerySet, "_no_such_method")
    assert f"Django {django.get_version()}" in str(refused.value)
    assert "django.db.models.query.QuerySet._no_such_method" in str(refused.value)
    with pytest.raises(ImportError, match=r"django\.db\.models\.sql\.constants\.NO_SUCH"):
        django_internals._private(django_internals._sql_constants, "NO_SUCH")


def test_a_compiled_select_runs_with_other_parameters_without_compiling_again(people):
    template = User.objects.filter(username="ada").annotate(shown=F("first_name"))
    compiler, sql, params = compile_select(template, DEFAULT_DB_ALIAS)
    assert list(params) == ["ada"] and "%s" in sql
    compiler.as_sql = lambda *args, **kwargs: pytest.fail("compiled again")
    [found] = run_compiled(template, compiler, DEFAULT_DB_ALIAS, sql, ["bob"])
    # An object, annotated as the ORM reads it.
    assert (type(found), found.pk, found.shown) == (User, people[1].pk, "Bob")
    assert run_compiled(template, compiler, DEFAULT_DB_ALIAS, sql, ["nobody"]) == []
    assert list(template) == [people[0]]  # the template itself is left as it was


def test_a_compiled_values_select_reads_dicts(people):
    template = User.objects.filter(username="ada").values("pk", "first_name")
    compiler, sql, _ = compile_select(template, DEFAULT_DB_ALIAS)
    assert run_compiled(template, compiler, DEFAULT_DB_ALIAS, sql, ["cy"]) == [{"pk": people[2].pk, "first_name": "Cy"}]


def test_a_selects_sql_runs_on_a_cursor_as_the_queryset_runs_it(people):
    sql, params = select_sql(User.objects.filter(username__in=["ada", "cy"]).order_by("pk").values_list("pk"))
    with connection.cursor() as cursor:
        cursor.execute(sql, params)
        assert cursor.fetchall() == [(people[0].pk,), (people[2].pk,)]


def test_an_update_compiler_writes_reading_nothing_or_the_cursor_with_its_count(people):
    everyone = User.objects.filter(username__in=["ada", "bob"])
    compiler = update_compiler(everyone, {"last_name": "Smith"})
    assert type(compiler.query) is UpdateQuery
    assert compiler.execute_sql(NO_RESULTS) == 0  # the count is not read: no cursor is kept to read it from
    assert sorted(User.objects.filter(last_name="Smith").values_list("username", flat=True)) == ["ada", "bob"]
    with update_compiler(User.objects.filter(username="cy"), {"last_name": "Jones"}).execute_sql(CURSOR) as cursor:
        assert cursor.rowcount == 1
    assert User.objects.get(username="cy").last_name == "Jones"


def test_inserted_rows_are_written_in_one_statement_and_marked_saved():
    first_id = 1000
    users = [User(pk=first_id + n, username=f"user-{n}", password="!") for n in range(3)]
    fields = list(User._meta.concrete_fields)
    with django.test.utils.CaptureQueriesContext(connection) as queries:
        insert_rows(User, users, fields, connection.alias)
    assert len(queries) == 1 and queries[0]["sql"].startswith("INSERT")
    assert sorted(User.objects.values_list("pk", flat=True)) == [first_id, first_id + 1, first_id + 2]
    assert all(not user._state.adding and user._state.db == connection.alias for user in users)
