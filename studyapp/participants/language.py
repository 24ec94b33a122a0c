"""The language of a study's participant pages: the study's setting (``Study.language``),
never the browser's, and English wherever no study is known.

A participant view runs inside ``participant_language()``; ``speak(study)`` switches to the
study's language as soon as its row is read, so that the page, its messages and its
refusals (raised with their words in that language) all come in it, and the language the
thread had before comes back when the view returns. Only the app's own words are
translated: the researcher's texts (title, instructions, consent, question, scale labels,
questions) are shown as they were written.

A refusal made before the view runs (a middleware's: a NUL character, an oversized body)
is said in the study's language too where the view is a participant page, which
``in_study_language`` marks.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import Any

from django.conf import settings
from django.utils import translation

from studyapp.models import Study


def participant_language() -> AbstractContextManager:
    """The project's language (English) until ``speak`` names a study's; the thread's own afterwards."""
    return translation.override(settings.LANGUAGE_CODE)


def speak(study: Study) -> Study:
    """Speak ``study``'s language for the rest of the request (inside ``participant_language()``,
    or a ``translation.override`` of the caller's); returns the study."""
    translation.activate(study.language)
    return study


# The attribute marking a participant view; it survives decorators outside it (functools.wraps copies it).
_MARK = "in_study_language"


def in_study_language(view: Callable) -> Callable:
    """Mark ``view`` (taking the study's entry ``key``) as a participant page, said in its study's language."""
    setattr(view, _MARK, True)
    return view


def language_before_view(view: Callable, kwargs: dict[str, Any]) -> str:
    """The language of a refusal made before ``view`` runs with ``kwargs``: its study's for a
    participant page of a study that exists, else the project's."""
    key = kwargs.get("key") if getattr(view, _MARK, False) else None
    if not isinstance(key, str) or "\x00" in key:  # PostgreSQL cannot even compare text with NUL
        return settings.LANGUAGE_CODE
    return Study.objects.filter(key=key).values_list("language", flat=True).first() or settings.LANGUAGE_CODE


__all__ = ["in_study_language", "language_before_view", "participant_language", "speak"]
