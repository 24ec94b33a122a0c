"""Bounds on the numbers a study stores, checked once for every way in.

A number field of the study's models carries its bound as a validator (``Within``),
which Django runs wherever a row is cleaned: the study pages' model forms, the admin,
``create_study``. Code that saves without a form (the services behind the systems page
and the command line) checks a value with ``check_field``. The bounds are what the
renderer, the participant's schedule and the database can actually do; the message
states the bound and the reason.
"""

from __future__ import annotations

import math
from numbers import Real

from django.core.exceptions import ValidationError
from django.db import models
from django.utils.deconstruct import deconstructible


def _shown(value: object) -> str:
    """A number as a message shows it: short, whatever its size (``:g`` fails past 1e308 on ints)."""
    text = repr(value)
    return text if len(text) <= 24 else f"{text[:12]}...({len(text)} characters)"


def _bound(number: float) -> str:
    """A bound as a researcher writes it: 1000000000, not 1e+09."""
    return str(int(number)) if float(number).is_integer() else f"{number:g}"


@deconstructible
class Within:
    """A validator: a finite number from ``low`` to ``high`` (both included); ``why``
    says where the bound comes from."""

    def __init__(self, low: float, high: float, why: str = "") -> None:
        self.low, self.high, self.why = low, high, why

    def message(self, value: object) -> str:
        reason = f" ({self.why})" if self.why else ""
        return f"must be a number from {_bound(self.low)} to {_bound(self.high)}{reason}, not {_shown(value)}"

    def __call__(self, value: object) -> None:
        if value is None:
            return
        if (isinstance(value, bool) or not isinstance(value, Real)  # an int of 400 digits overflows isfinite()
                or (isinstance(value, float) and not math.isfinite(value)) or not self.low <= value <= self.high):
            raise ValidationError(self.message(value), code="out_of_bounds")

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Within) and (self.low, self.high, self.why) == (other.low, other.high, other.why)


def _non_finite(value: object) -> str | None:
    """Where in a JSON value a NaN or an infinity is, or None."""
    if isinstance(value, float) and not math.isfinite(value):
        return repr(value)
    children = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
    for key, child in children:
        if (found := _non_finite(child)) is not None:
            return f"{key}: {found}"
    return None


def storable_json(value: object) -> None:
    """A validator of JSON fields: no NaN or infinity anywhere, which JSON parsers admit
    but no database's JSON column stores (SQLite answers with an IntegrityError)."""
    if (found := _non_finite(value)) is not None:
        raise ValidationError(f"JSON numbers must be finite, not {found}", code="not_finite")


def bound_of(model: type[models.Model], name: str) -> Within | None:
    """The ``Within`` validator of a model's field, if it has one."""
    return next((v for v in model._meta.get_field(name).validators if isinstance(v, Within)), None)


def check_field(model: type[models.Model], name: str, value: object) -> str | None:
    """Why ``value`` cannot be stored in the field ``name`` of ``model`` (its validators,
    the database's range included), or None."""
    try:
        model._meta.get_field(name).run_validators(value)
    except ValidationError as error:
        return f"{name.replace('_', ' ')} {' '.join(error.messages)}"
    return None


__all__ = ["Within", "bound_of", "check_field", "storable_json"]
