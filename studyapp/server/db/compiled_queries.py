"""The queries that every participant page runs, compiled to SQL once per process.

Django builds a queryset and compiles it to SQL each time it runs. For the three queries
of a rating step that read rows (the participant, the page answered, the page shown
next) building and compiling took about a quarter of the step's CPU time on this
machine (benchmarks/bench_study.py), and a crowd of participants is held back by
exactly that time (enrolment's check of the rendered clips is compiled the same way).
Their SQL differs only in the values it compares, so ``CompiledQuery`` builds its
queryset once per process (which has one database) with stand-in values, keeps the
SQL, and runs it with the real values put where the stand-ins were. The rows are read
by the ORM as the queryset reads them: model objects (annotations as attributes) or, for
a ``values()`` query, dicts, converted as usual.

A compiled query takes its values as integers or strings that the ORM passes to the
database unchanged (``pk=``, ``participant_id=``, ``study__key=``; not ``__in`` lists,
patterns or dates), and its shape does not depend on them. ``CompiledQuery`` checks the
first: a value the ORM changed on its way into the SQL is an error when it compiles.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable

from django.db import DEFAULT_DB_ALIAS
from django.db.models import QuerySet

from studyapp.server.db.django_internals import compile_select, run_compiled

_stand_in_numbers = itertools.count(1)


def _stand_in(kind: type) -> int | str:
    """A value that no real query passes: a negative id, or a string that names itself."""
    number = next(_stand_in_numbers)
    if kind is int:
        return -(2**62) - number
    if kind is str:
        return f"compiled-query-stand-in-{number}"
    raise TypeError(f"a compiled query takes int or str values, not {kind.__name__}")


class CompiledQuery:
    """``build(*values)``'s queryset, compiled once with stand-ins for its values (of the
    types ``kinds``); calling it runs it with the values given."""

    def __init__(self, build: Callable[..., QuerySet], *kinds: type) -> None:
        self._build, self._kinds = build, kinds
        self._compiled: tuple | None = None  # queryset, compiler, SQL, params, slots

    def _compile(self) -> tuple:
        stand_ins = [_stand_in(kind) for kind in self._kinds]
        queryset = self._build(*stand_ins)
        compiler, sql, params = compile_select(queryset, DEFAULT_DB_ALIAS)
        slots = [[i for i, param in enumerate(params) if type(param) is type(value) and param == value]
                 for value in stand_ins]
        if missing := [n for n, positions in enumerate(slots) if not positions]:
            raise TypeError(f"value {missing[0] + 1} of {self._build.__qualname__} does not reach the SQL as "
                            f"it is given, so it cannot be compiled once")
        self._compiled = (queryset, compiler, sql, params, slots)
        return self._compiled

    def __call__(self, *values: int | str) -> list:
        """The query's rows with ``values`` (model objects, or dicts for a ``values()`` query)."""
        if len(values) != len(self._kinds) or any(type(v) is not k for v, k in zip(values, self._kinds)):
            raise TypeError(f"{self._build.__qualname__} takes values of the types "
                            f"{[kind.__name__ for kind in self._kinds]}, not {values!r}")
        template, compiler, sql, params, slots = self._compiled or self._compile()
        params = list(params)
        for value, positions in zip(values, slots):
            for position in positions:
                params[position] = value
        return run_compiled(template, compiler, DEFAULT_DB_ALIAS, sql, params)
