"""Every private part of Django that the app drives, looked up once, when it is imported.

``compiled_queries`` runs a queryset's SQL compiled once, and ``round_trips`` writes rows
without reading an answer the database would have to send. Neither is possible through
Django's public API, so both go through the seams below, and only these. Each private
name is looked up here at import time: a Django that lacks one fails at startup with an
``ImportError`` naming its version and the name, not halfway through a participant's
page. What each seam is relied on to do is pinned down in ``tests/test_django_internals.py``,
which a Django upgrade must pass first (pyproject.toml keeps Django to the tested series).
"""

from __future__ import annotations

import copy
import importlib
from collections.abc import Sequence

import django
from django.db import connections
from django.db.models import Field, Model, QuerySet

SUPPORTED_SERIES = "5.2"


def _private(owner: object, name: str) -> object:
    """``owner.name``, or an ImportError that names this Django and what it lacks."""
    try:
        return getattr(owner, name)
    except AttributeError:
        where = getattr(owner, "__qualname__", None) or owner.__name__
        module = getattr(owner, "__module__", None)
        full = f"{module}.{where}" if module and module != where else where
        raise ImportError(f"Django {django.get_version()} has no {full}.{name}, which the app's compiled queries "
                          f"and pipelined writes rely on (tested with Django {SUPPORTED_SERIES}; see "
                          f"studyapp/server/db/django_internals.py)") from None


_sql = importlib.import_module("django.db.models.sql")
_sql_constants = importlib.import_module("django.db.models.sql.constants")
_sql_compiler = importlib.import_module("django.db.models.sql.compiler")
_sql_query = importlib.import_module("django.db.models.sql.query")

UpdateQuery = _private(_sql, "UpdateQuery")
CURSOR = _private(_sql_constants, "CURSOR")
NO_RESULTS = _private(_sql_constants, "NO_RESULTS")
_SQLCompiler = _private(_sql_compiler, "SQLCompiler")
_Query = _private(_sql_query, "Query")

_queryset_chain = _private(QuerySet, "_chain")
_queryset_insert = _private(QuerySet, "_insert")
_query_chain = _private(_Query, "chain")
_query_sql_with_params = _private(_Query, "sql_with_params")
_add_update_values = _private(UpdateQuery, "add_update_values")
# Looked up for the check alone: a compiled query replaces them on its own copies.
_private(_Query, "get_compiler")
_private(_SQLCompiler, "as_sql")
_private(_SQLCompiler, "execute_sql")


def compile_select(queryset: QuerySet, using: str) -> tuple[object, str, tuple]:
    """The compiler of ``queryset`` on ``using``, its SQL and its parameters. Compiling also
    sets up what reading the rows needs (the compiler's select and klass_info)."""
    compiler = queryset.query.get_compiler(using=using)
    sql, params = compiler.as_sql()
    return compiler, sql, tuple(params)


def run_compiled(template: QuerySet, compiler: object, using: str, sql: str, params: Sequence) -> list:
    """The rows of ``template`` (as it would read them: model objects, or dicts for a
    ``values()`` query) when its SQL is ``sql`` with ``params``, compiled by ``compiler``
    and run on this thread's connection to ``using`` without compiling again."""
    run = copy.copy(compiler)  # a compiler holds the connection it was made with, which is another thread's
    run.connection = connections[using]
    run.as_sql = lambda *args, **kwargs: (sql, list(params))
    queryset = _queryset_chain(template)
    queryset.query.get_compiler = lambda *args, **kwargs: run
    return list(queryset)


def select_sql(queryset: QuerySet) -> tuple[str, tuple]:
    """The SQL and parameters ``queryset`` runs, to send without reading its rows."""
    return _query_sql_with_params(queryset.query)


def update_compiler(queryset: QuerySet, values: dict) -> object:
    """The compiler of ``queryset.update(**values)``, as ``QuerySet.update`` makes it; its
    ``execute_sql(NO_RESULTS)`` reads no answer, ``execute_sql(CURSOR)`` the cursor."""
    query = _query_chain(queryset.query, UpdateQuery)
    _add_update_values(query, values)
    return query.get_compiler(queryset.db)


def insert_rows(model: type[Model], objects: list[Model], fields: list[Field], using: str) -> None:
    """INSERT ``objects`` with the values of ``fields`` in one statement that returns nothing,
    and mark them saved as ``bulk_create`` leaves them."""
    _queryset_insert(model._base_manager.using(using), objects, fields=fields, using=using)
    for obj in objects:
        obj._state.adding, obj._state.db = False, using
